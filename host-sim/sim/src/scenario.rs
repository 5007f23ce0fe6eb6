//! Operator/load scenarios: what the joint is asked to do and what pushes on it, per control tick.
//!
//! - `sweep` (trunk paper §3.2): the core in Velocity mode follows trapezoidal back-and-forth
//!   strokes at 5, 10, 20, …, 90 deg/s; each stroke starts from the measured angle toward the
//!   farther end of the range, so tracking errors never accumulate; the stroke length is what
//!   the scenario's time allows (at most the range minus a 2° margin). τ_ext = 0.
//! - `poses` (§3.3): the core in Position mode visits the range in 10° steps; each pose moves
//!   with a minimum-jerk ramp, then holds. τ_ext = 0.
//! - `free`: the joint is held by hand at a start angle and released: τ_ext = 0 after release
//!   (the elastic-joint free oscillation), core in Assist mode. As the first scenario the
//!   simulation starts at rest at the start angle and releases at once; later in a list the
//!   operator first holds the joint there for 1 s.
//! - `hand` (§3.4/§4): an operator impedance `K_h·(q_ref − q) + B_h·(q̇_ref − q̇)` pulls toward a
//!   smooth random reference (minimum-jerk segments of 0.8–2.5 s between random targets in the
//!   range), core in Assist mode.

use joint_core::control::Mode;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::plant::Operator;

const DEG: f64 = std::f64::consts::PI / 180.0;
/// 1/s: position correction of the sweep's velocity command.
const SWEEP_POS_GAIN: f64 = 2.0;

/// The scenario names `--scenario` accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScenarioKind {
    Sweep,
    Poses,
    Free,
    Hand,
}

impl ScenarioKind {
    pub fn parse_list(s: &str) -> Result<Vec<ScenarioKind>, String> {
        s.split(',')
            .map(|p| match p.trim() {
                "sweep" => Ok(ScenarioKind::Sweep),
                "poses" => Ok(ScenarioKind::Poses),
                "free" => Ok(ScenarioKind::Free),
                "hand" => Ok(ScenarioKind::Hand),
                other => Err(format!("unknown scenario `{other}` (known: sweep, poses, free, hand)")),
            })
            .collect()
    }
}

/// What one control tick asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    pub mode: Mode,
    pub operator: Operator,
}

/// Settings shared by all scenarios.
#[derive(Clone, Debug, PartialEq)]
pub struct ScenarioCfg {
    /// joint range, rad
    pub lo: f64,
    pub hi: f64,
    /// operator impedance, N·m/rad and N·m·s/rad
    pub k_h: f64,
    pub b_h: f64,
    /// start angle of `free`, rad
    pub free_start: f64,
    /// sweep acceleration, rad/s²
    pub sweep_accel: f64,
}

/// Minimum-jerk blend 0→1 and its derivative for s = t/T.
fn min_jerk(s: f64) -> (f64, f64) {
    let s = s.clamp(0.0, 1.0);
    let p = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
    let dp = 30.0 * s * s * (1.0 - s) * (1.0 - s);
    (p, dp)
}

/// A smooth random path: minimum-jerk segments between random targets.
#[derive(Clone, Debug)]
pub struct RandomPath {
    lo: f64,
    hi: f64,
    seg_min: f64,
    seg_max: f64,
    from: f64,
    to: f64,
    t0: f64,
    len: f64,
}

impl RandomPath {
    pub fn new(start: f64, lo: f64, hi: f64, seg_min: f64, seg_max: f64, rng: &mut ChaCha8Rng) -> Self {
        let mut p = RandomPath { lo, hi, seg_min, seg_max, from: start, to: start, t0: 0.0, len: 0.0 };
        p.next_segment(0.0, rng);
        p
    }

    fn next_segment(&mut self, t: f64, rng: &mut ChaCha8Rng) {
        self.from = self.to;
        self.to = rng.random_range(self.lo..=self.hi);
        self.t0 = t;
        self.len = rng.random_range(self.seg_min..=self.seg_max);
    }

    /// Reference angle and velocity at time `t` (monotone calls).
    pub fn at(&mut self, t: f64, rng: &mut ChaCha8Rng) -> (f64, f64) {
        while t >= self.t0 + self.len {
            let end = self.t0 + self.len;
            self.next_segment(end, rng);
        }
        let (p, dp) = min_jerk((t - self.t0) / self.len);
        (self.from + (self.to - self.from) * p, (self.to - self.from) * dp / self.len)
    }
}

/// One running scenario segment.
pub enum Scenario {
    Sweep(Sweep),
    Poses(Poses),
    Free { hold: f64, start: f64, k: f64, b: f64 },
    Hand { path: RandomPath, k: f64, b: f64 },
}

pub struct Sweep {
    speeds: Vec<f64>,
    stroke_time: f64,
    accel: f64,
    lo: f64,
    hi: f64,
    idx: usize,
    // current stroke
    t0: f64,
    dir: f64,
    v: f64,
    t_acc: f64,
    t_flat: f64,
    q0: f64,
    active: bool,
}

impl Sweep {
    fn plan(&mut self, t: f64, q: f64) {
        let base = self.speeds.get(self.idx / 2 % self.speeds.len()).copied().unwrap_or(5.0 * DEG);
        self.idx += 1;
        let (to_hi, to_lo) = (self.hi - q, q - self.lo);
        self.dir = if to_hi >= to_lo { 1.0 } else { -1.0 };
        let avail = to_hi.max(to_lo).max(0.0);
        let a = self.accel;
        // Distance the time budget allows at this speed, at least 0.2 s of constant speed.
        let want = (base * (self.stroke_time - base / a)).max(base * base / a + 0.2 * base);
        let l = want.min(avail);
        let (v, t_acc, t_flat) = if l >= base * base / a {
            (base, base / a, (l - base * base / a) / base)
        } else {
            let v = (l * a).sqrt();
            (v, v / a, 0.0)
        };
        self.t0 = t;
        self.q0 = q;
        self.v = v;
        self.t_acc = t_acc;
        self.t_flat = t_flat;
        self.active = true;
    }

    fn velocity(&mut self, t: f64, q: f64) -> f64 {
        if !self.active || t - self.t0 >= 2.0 * self.t_acc + self.t_flat {
            self.plan(t, q);
        }
        let tau = t - self.t0;
        let (ta, tf, v) = (self.t_acc, self.t_flat, self.v);
        // Planned velocity and distance of the trapezoid at stroke time tau.
        let (vel, dist) = if tau < ta {
            (v * tau / ta, 0.5 * v * tau * tau / ta)
        } else if tau < ta + tf {
            (v, 0.5 * v * ta + v * (tau - ta))
        } else {
            let r = (2.0 * ta + tf - tau).max(0.0);
            (v * r / ta, v * (ta + tf) - 0.5 * v * r * r / ta)
        };
        // A gentle position correction keeps the stroke inside the range although the velocity
        // loop lags; at constant speed it is near zero, so the friction data stay clean.
        let q_plan = self.q0 + self.dir * dist;
        self.dir * vel + SWEEP_POS_GAIN * (q_plan - q)
    }
}

pub struct Poses {
    targets: Vec<f64>,
    pose_time: f64,
    move_time: f64,
    from: f64,
    current: usize,
}

impl Scenario {
    /// Starts a scenario of `duration` s at the measured angle `q`; `first` = nothing ran before.
    pub fn start(
        kind: ScenarioKind,
        duration: f64,
        cfg: &ScenarioCfg,
        q: f64,
        first: bool,
        rng: &mut ChaCha8Rng,
    ) -> Scenario {
        let margin = (2.0 * DEG).min((cfg.hi - cfg.lo) / 10.0);
        let (lo, hi) = (cfg.lo + margin, cfg.hi - margin);
        match kind {
            ScenarioKind::Sweep => {
                let speeds: Vec<f64> =
                    [5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0].iter().map(|v| v * DEG).collect();
                let stroke_time = duration / (2.0 * speeds.len() as f64);
                Scenario::Sweep(Sweep {
                    speeds,
                    stroke_time,
                    accel: cfg.sweep_accel,
                    lo,
                    hi,
                    idx: 0,
                    t0: 0.0,
                    dir: 1.0,
                    v: 0.0,
                    t_acc: 1.0,
                    t_flat: 0.0,
                    q0: q,
                    active: false,
                })
            }
            ScenarioKind::Poses => {
                let mut targets = Vec::new();
                let mut x = cfg.lo;
                while x <= cfg.hi + 1e-9 {
                    targets.push(x.clamp(lo, hi));
                    x += 10.0 * DEG;
                }
                let pose_time = duration / targets.len().max(1) as f64;
                Scenario::Poses(Poses {
                    targets,
                    pose_time,
                    move_time: (0.4 * pose_time).min(1.0),
                    from: q,
                    current: 0,
                })
            }
            ScenarioKind::Free => Scenario::Free {
                hold: if first { 0.0 } else { 1.0f64.min(0.3 * duration) },
                start: cfg.free_start,
                k: cfg.k_h,
                b: cfg.b_h,
            },
            ScenarioKind::Hand => {
                Scenario::Hand { path: RandomPath::new(q, lo, hi, 0.8, 2.5, rng), k: cfg.k_h, b: cfg.b_h }
            }
        }
    }

    /// Where the joint should be when this scenario starts as the first one.
    pub fn initial_angle(kind: ScenarioKind, cfg: &ScenarioCfg) -> f64 {
        match kind {
            ScenarioKind::Free => cfg.free_start,
            _ => 0.5 * (cfg.lo + cfg.hi),
        }
    }

    /// The command at scenario-local time `t`, given the measured angle.
    pub fn command(&mut self, t: f64, q_meas: f64, rng: &mut ChaCha8Rng) -> Command {
        let none = Operator::default();
        match self {
            Scenario::Sweep(s) => Command { mode: Mode::Velocity(s.velocity(t, q_meas) as f32), operator: none },
            Scenario::Poses(p) => {
                let idx = ((t / p.pose_time) as usize).min(p.targets.len().saturating_sub(1));
                if idx != p.current {
                    p.from = p.targets.get(p.current).copied().unwrap_or(q_meas);
                    p.current = idx;
                }
                let target = p.targets.get(idx).copied().unwrap_or(q_meas);
                let local = t - idx as f64 * p.pose_time;
                let (s, _) = min_jerk(local / p.move_time);
                Command { mode: Mode::Position((p.from + (target - p.from) * s) as f32), operator: none }
            }
            Scenario::Free { hold, start, k, b } => {
                let operator = if t < *hold { Operator { k: *k, b: *b, q_ref: *start, qd_ref: 0.0 } } else { none };
                Command { mode: Mode::Assist, operator }
            }
            Scenario::Hand { path, k, b } => {
                let (q_ref, qd_ref) = path.at(t, rng);
                Command { mode: Mode::Assist, operator: Operator { k: *k, b: *b, q_ref, qd_ref } }
            }
        }
    }
}
