//! The free (or known-input) response of a joint: `J·q̈ = u − D(q, q̇)` integrated from a start
//! state, with the friction law the model file states (spec §2):
//!
//! - **pure sign** (a Coulomb term and no `v_band`): stick-slip. While the joint slides the sign
//!   is the direction of motion; a velocity zero inside a sub-step is located (bisection) and
//!   there the joint sticks as long as the torque that is not friction stays within the static
//!   level (Coulomb plus the full Stribeck excess, per direction). A joint released where the
//!   spring or weight torque is below `c` does not move at all.
//! - **a band** `clamp(q̇/v_band, −1, 1)`: where the band is stiff for the sample interval
//!   (the friction's slope `c/v_band` against `J`) the entry into the band is located and the
//!   motion inside it is the exact creep of the linearised law, otherwise plain RK4.
//! - **pre-sliding** (a Dahl state instead of the sign): `dF/dq = σ(1 − F/c·sign(dq))`, taken
//!   over each sub-step as the exact exponential in the angle travelled since the sub-step's
//!   start, so `|F| ≤ c` whatever the step.
//!
//! The shapes (dead zone, cable spring) are this crate's own ([`crate::diagnose::shapes`]).

use crate::diagnose::shapes;

/// A cable or harness torque (added to D, i.e. restoring when positive above its engagement).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cable {
    /// taut above `engage`: `k·spring(q − engage)` with a quadratic blend of `width`
    Above { k: f64, engage: f64, width: f64 },
    /// taut below `engage`: the mirror image, pushing back up
    Below { k: f64, engage: f64, width: f64 },
    /// a progressive element `k1·x + k3·x³`, `x = q − qs`
    Cubic { k1: f64, k3: f64, qs: f64 },
    /// padding pressed over a stretch of angle: `a·exp(−½((q − qb)/w)²)`
    Bump { a: f64, qb: f64, w: f64 },
}

impl Cable {
    pub fn torque(&self, q: f64) -> f64 {
        match *self {
            Cable::Above { k, engage, width } => shapes::engaged_spring(k, engage, width, q),
            Cable::Below { k, engage, width } => -shapes::engaged_spring(k, -engage, width, -q),
            Cable::Cubic { k1, k3, qs } => {
                let x = q - qs;
                k1 * x + k3 * x * x * x
            }
            Cable::Bump { a, qb, w } => {
                let z = (q - qb) / w;
                a * (-0.5 * z * z).exp()
            }
        }
    }

    fn stiffness(&self, span: f64) -> f64 {
        match *self {
            Cable::Above { k, .. } | Cable::Below { k, .. } => k.abs(),
            Cable::Cubic { k1, k3, .. } => k1.abs() + 3.0 * k3.abs() * span * span,
            Cable::Bump { a, w, .. } => a.abs() / (w * w).max(1e-12) * w,
        }
    }
}

/// Everything the right-hand side needs, resolved from a fit's coefficients.
#[derive(Clone, Debug, Default)]
pub struct Law {
    pub j: f64,
    /// `a·q̇|q̇| + b·q̇`
    pub a: f64,
    pub b: f64,
    /// Coulomb level and its direction offset: `c + delta` moving forward, `c − delta` back
    pub c: f64,
    pub delta: f64,
    /// Stribeck excesses `level·exp(−(|q̇|/speed)^exponent)` on top of `c`
    pub strib: Vec<(f64, f64, f64)>,
    /// the sign band, rad/s (0: the pure sign, with stick-slip)
    pub band: f64,
    /// pre-sliding stiffness σ: a Dahl state of level `c` replaces `c·sign(q̇)`
    pub dahl: Option<f64>,
    /// `(s, α, β)`: `α·sin(s·q) + β·cos(s·q)`
    pub weight: Option<(f64, f64, f64)>,
    /// `k·q + konst`; with a backlash `(width, centre)` the spring is `k·(pivot + dz(q − m, w))`:
    /// it transmits nothing inside the dead zone, and `konst` (`c0 − k·q0` in a model file) keeps
    /// the file's meaning when `pivot` is the file's spring rest angle `q0`
    pub k: f64,
    pub konst: f64,
    pub backlash: Option<(f64, f64)>,
    pub pivot: f64,
    /// `(period, α, β)`: `α·sin(2πq/P) + β·cos(2πq/P)`
    pub ripples: Vec<(f64, f64, f64)>,
    pub cables: Vec<Cable>,
    /// the model file's gravity table over the joint's own angle, added to the weight (the
    /// core's rule without fusion): grid and torque, interpolated linearly, clamped to the grid
    pub table: Option<Table>,
    /// angles travelled (bounds a progressive element's stiffness)
    pub span: f64,
}

/// A gravity table over the joint's own angle: its grid (one axis) and torques, as the model file
/// states them (shared, never fitted).
pub type Table = std::sync::Arc<(Vec<Vec<f64>>, Vec<f64>)>;

impl Law {
    /// The torque that depends on the angle alone.
    #[inline]
    pub fn position(&self, q: f64) -> f64 {
        let mut d = self.konst;
        if let Some((s, al, be)) = self.weight {
            let (sn, cs) = (s * q).sin_cos();
            d += al * sn + be * cs;
        }
        d += match self.backlash {
            Some((w, m)) => self.k * (self.pivot + shapes::dead_zone(q - m, w)),
            None => self.k * q,
        };
        for &(p, al, be) in &self.ripples {
            let (sn, cs) = (std::f64::consts::TAU * q / p).sin_cos();
            d += al * sn + be * cs;
        }
        for c in &self.cables {
            d += c.torque(q);
        }
        if let Some(t) = &self.table {
            d += crate::identify::gravity_table::interpolate(&t.0, &t.1, &[q]);
        }
        d
    }

    /// The whole of `D(q, q̇)` at a state, the sign-like friction taken at `v` (0 at rest, as
    /// the sign's expected value near it; a Dahl state as the sign it tends to).
    pub fn torque_at(&self, q: f64, v: f64) -> f64 {
        let sign_like = if self.c == 0.0 && self.delta == 0.0 && self.strib.is_empty() {
            0.0
        } else if self.band > 0.0 {
            self.banded(v)
        } else if v != 0.0 {
            self.sliding(v, v.signum())
        } else {
            0.0
        };
        self.position(q) + self.smooth(v) + sign_like
    }

    #[inline]
    fn smooth(&self, v: f64) -> f64 {
        self.a * v * v.abs() + self.b * v
    }

    #[inline]
    fn excess(&self, v: f64) -> f64 {
        self.strib.iter().map(|&(l, vs, e)| l * (-(v.abs() / vs).powf(e)).exp()).sum()
    }

    /// The sign-like friction while sliding in direction `dir` (±1).
    #[inline]
    fn sliding(&self, v: f64, dir: f64) -> f64 {
        dir * (self.c + self.excess(v)) + self.delta
    }

    /// The sign-like friction with the band.
    #[inline]
    fn banded(&self, v: f64) -> f64 {
        let s = (v / self.band).clamp(-1.0, 1.0);
        s * (self.c + self.excess(v)) + self.delta * s.abs()
    }

    /// The levels the non-friction torque must exceed to start the joint (forward, backward).
    fn static_levels(&self) -> (f64, f64) {
        let ex = self.excess(0.0);
        (self.c + self.delta + ex, self.c - self.delta + ex)
    }

    fn has_sign(&self) -> bool {
        self.dahl.is_none() && (self.c != 0.0 || self.delta != 0.0 || !self.strib.is_empty())
    }

    /// The natural frequency of the stiffness terms, 1/s, and the highest spatial frequency of
    /// a term periodic in the angle, 1/rad (a torque that varies in time at κ·|q̇|).
    fn rates(&self) -> (f64, f64) {
        let mut stiff = self.k.abs();
        let mut kappa: f64 = 0.0;
        if let Some((s, al, be)) = self.weight {
            stiff += al.hypot(be) * s.abs();
            kappa = kappa.max(s.abs());
        }
        for &(p, al, be) in &self.ripples {
            let w = std::f64::consts::TAU / p.abs().max(1e-9);
            stiff += al.hypot(be) * w;
            kappa = kappa.max(w);
        }
        stiff += self.cables.iter().map(|c| c.stiffness(self.span)).sum::<f64>();
        ((stiff / self.j.max(1e-12)).sqrt(), kappa)
    }

    /// The viscous decay rate at speed `v`, 1/s.
    fn damping(&self, v: f64) -> f64 {
        (self.b.abs() + 2.0 * self.a.abs() * v.abs()) / self.j.max(1e-12)
    }

    /// The slope of the banded friction against `J`, 1/s: above ~1/h the band is stiff.
    fn band_rate(&self) -> f64 {
        (self.c.abs() + self.delta.abs() + self.excess(0.0)) / (self.band * self.j.max(1e-12))
            + self.b.abs() / self.j.max(1e-12)
    }
}

/// The known input over one sample interval: a cubic through its ends with the slopes of the
/// neighbouring samples (Catmull–Rom on uneven stamps), limited so it never overshoots the
/// samples (Fritsch–Carlson): a logged input is the samples of a smooth torque, and a line
/// between them is off by its curvature, ~0.1 % of a step's size per sample at 50 Hz.
#[derive(Clone, Copy)]
struct Input {
    t0: f64,
    dt: f64,
    u0: f64,
    u1: f64,
    m0: f64,
    m1: f64,
    /// the curve read this much earlier (s; negative: later), held at the interval's ends
    /// ([`edge_spread`])
    shift: f64,
}

impl Input {
    const ZERO: Input = Input { t0: 0.0, dt: 1.0, u0: 0.0, u1: 0.0, m0: 0.0, m1: 0.0, shift: 0.0 };

    fn line(t: &[f64], u: &[f64], i: usize) -> Input {
        let (t0, dt) = (t[i - 1], t[i] - t[i - 1]);
        let m = (u[i] - u[i - 1]) / dt;
        Input { t0, dt, u0: u[i - 1], u1: u[i], m0: m, m1: m, shift: 0.0 }
    }

    fn between(t: &[f64], u: &[f64], i: usize) -> Input {
        let (t0, t1) = (t[i - 1], t[i]);
        let (u0, u1) = (u[i - 1], u[i]);
        let dt = t1 - t0;
        let secant = (u1 - u0) / dt;
        let slope = |a: usize, b: usize| (u[b] - u[a]) / (t[b] - t[a]);
        let mut m0 = if i >= 2 { slope(i - 2, i) } else { secant };
        let mut m1 = if i + 1 < t.len().min(u.len()) { slope(i - 1, i + 1) } else { secant };
        // no overshoot: a slope against the secant's direction is flattened, and the pair is
        // kept inside the monotone region
        if secant == 0.0 {
            m0 = 0.0;
            m1 = 0.0;
        } else {
            if m0 * secant < 0.0 {
                m0 = 0.0;
            }
            if m1 * secant < 0.0 {
                m1 = 0.0;
            }
            let (a, b) = (m0 / secant, m1 / secant);
            let r = a * a + b * b;
            if r > 9.0 {
                let s = 3.0 / r.sqrt();
                m0 *= s;
                m1 *= s;
            }
        }
        Input { t0, dt, u0, u1, m0, m1, shift: 0.0 }
    }

    #[inline]
    fn at(&self, t: f64) -> f64 {
        let s = ((t + self.shift - self.t0) / self.dt).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        (2.0 * s3 - 3.0 * s2 + 1.0) * self.u0
            + (s3 - 2.0 * s2 + s) * self.dt * self.m0
            + (-2.0 * s3 + 3.0 * s2) * self.u1
            + (s3 - s2) * self.dt * self.m1
    }
}

/// Integrator state: angle, velocity, and the Dahl friction state.
#[derive(Clone, Copy, Debug)]
struct Y {
    q: f64,
    v: f64,
    f: f64,
}

/// The simulated angle at samples `0..n` of `t` from `(q0, v0)`; `u` the known input (held
/// linear between samples). `None` if the integration diverges.
pub fn run(law: &Law, t: &[f64], u: Option<&[f64]>, start: (f64, f64), n: usize) -> Option<Vec<f64>> {
    simulate(law, t, u, start, n, Plan::Choose(&mut Vec::new()), Reading::Cubic)
}

/// How much the response depends on how the logged input is read between its samples: the
/// simulated angle with a line between the samples less the one with the cubic [`run`] uses.
/// Where the input changes within a few samples (a step's edge at a low rate) the two differ
/// by about what no model can know; the diagnosis counts it into the noise floor.
pub fn input_spread(law: &Law, t: &[f64], u: &[f64], start: (f64, f64), n: usize) -> Option<Vec<f64>> {
    let cubic = simulate(law, t, Some(u), start, n, Plan::Choose(&mut Vec::new()), Reading::Cubic)?;
    let line = simulate(law, t, Some(u), start, n, Plan::Choose(&mut Vec::new()), Reading::Line)?;
    Some(line.iter().zip(&cubic).map(|(a, b)| a - b).collect())
}

/// How much the response depends on the logged input's white noise `sd` ([`input_noise`]): the
/// simulated angle with a noise of that size added to the input, less the one without. A
/// sensor's noise on the logged input is a torque the joint never felt, and the response to it
/// is residual no model can remove; the diagnosis counts its mean square into the noise floor.
/// The noise is a fixed ±`sd` sequence (a white sequence of that variance), so the figure
/// repeats from run to run.
pub fn noise_spread(law: &Law, t: &[f64], u: &[f64], start: (f64, f64), n: usize, sd: f64) -> Option<Vec<f64>> {
    let n = n.min(t.len()).min(u.len());
    if !(sd > 0.0) {
        return Some(vec![0.0; n]);
    }
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    // one bit per sample
    let noisy: Vec<f64> = u[..n].iter().map(|x| if xorshift(&mut state) & 1 == 1 { x + sd } else { x - sd }).collect();
    let base = simulate(law, t, Some(u), start, n, Plan::Choose(&mut Vec::new()), Reading::Cubic)?;
    let with = simulate(law, t, Some(&noisy), start, n, Plan::Choose(&mut Vec::new()), Reading::Cubic)?;
    Some(with.iter().zip(&base).map(|(a, b)| (a - b) * (a - b)).collect())
}

/// The next value of a xorshift64 generator (Marsaglia's 13/7/17 triple) from `state`.
fn xorshift(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// A white sequence of known size for tests (a fixed Gaussian draw from a Box–Muller over
/// [`xorshift`]).
#[cfg(test)]
pub(super) fn white(n: usize, sd: f64, seed: u64) -> Vec<f64> {
    let mut s = seed;
    let mut uniform = || ((xorshift(&mut s) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    (0..n)
        .map(|_| {
            let (a, b) = (uniform(), uniform());
            sd * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        })
        .collect()
}

/// How much the response depends on when, within its sample interval, the input changed
/// where it changed in one: a step whose edge is shorter than a sample is logged as a jump
/// between two samples, and the log cannot tell whether the edge came just after the first
/// or just before the second (an edge uniform over the interval: T²/12 of timing variance),
/// which moves the whole response after it. What no model can know goes into the noise floor
/// (issue 13: on the null bench, step inputs at 50–80 Hz left the file's own model up to
/// 1.9× the floor and were named `cable_spring`, `delay`, `unexplained`).
///
/// Interval `i` is an edge by the share `f` of its edge's change that falls within it (the
/// edge: the run of same-signed changes around it): an input the samples resolve spreads that
/// change over several intervals, a jump between flat stretches puts all of it in one (`f` =
/// 1). Past a third, `w = (f − 1/3)/(2/3)` clamped to [0, 1] is the part whose time the samples
/// do not place: its curve may have come up to `w·T/2` earlier or later (0.55 for a ramp of 1.1
/// samples split 0.3/0.7, 0.25 for one split evenly over two intervals, 0.04 at the middle of
/// a quintic edge over five samples, 0 for any input smooth at this rate, so a delay of a
/// smooth input is not hidden). Two pairs of readings bound the response per sample: all
/// edges early against all late (`Δc`), rising edges early and falling ones late against the
/// reverse (`Δd`: a pulse's width); for edges `k` of sensitivities `a_k`, `(Δc² + Δd²)/2` is
/// `Σ a_k²·T²` exactly for one or two edges. Returns that over 12 (rad²) per sample.
pub fn edge_spread(law: &Law, t: &[f64], u: &[f64], start: (f64, f64), n: usize, noise: f64) -> Option<Vec<f64>> {
    let n = n.min(t.len()).min(u.len());
    let (delta, half) = edge_shifts(t, u, n, noise);
    if half.iter().all(|h| *h == 0.0) {
        return Some(vec![0.0; n]);
    }
    let rising = |i: usize| delta[i] > 0.0;
    let run = |sign: &dyn Fn(usize) -> f64| -> Option<Vec<f64>> {
        let by: Vec<f64> = half.iter().enumerate().map(|(i, h)| h * sign(i)).collect();
        simulate(law, t, Some(u), start, n, Plan::Choose(&mut Vec::new()), Reading::Shifted(&by))
    };
    let early = run(&|_| 1.0)?;
    let late = run(&|_| -1.0)?;
    let wide = run(&|i| if rising(i) { 1.0 } else { -1.0 })?;
    let narrow = run(&|i| if rising(i) { -1.0 } else { 1.0 })?;
    Some(
        (0..n)
            .map(|i| {
                let c = early.get(i).zip(late.get(i)).map_or(0.0, |(a, b)| a - b);
                let d = wide.get(i).zip(narrow.get(i)).map_or(0.0, |(a, b)| a - b);
                (c * c + d * d) / 24.0
            })
            .collect(),
    )
}

/// The longest time (s) by which an edge of the logged input may have come earlier or later
/// than the cubic between its samples puts it: the largest `w·T/2` of [`edge_spread`] over the
/// first `n` samples (0 for an input the samples resolve).
pub fn edge_slack(t: &[f64], u: &[f64], n: usize, noise: f64) -> f64 {
    let n = n.min(t.len()).min(u.len());
    edge_shifts(t, u, n, noise).1.into_iter().fold(0.0, f64::max)
}

/// The white noise on the logged input (sd): from its second and fourth differences, robustly
/// (`1.4826·median|Δᵏu|` over the differences' own noise gain, √6 and √70), the smaller of
/// the two. A step's edges are a minority of the differences and leave the median alone; a
/// smooth input sampled coarsely puts its curvature into the second differences, much less
/// into the fourth.
pub fn input_noise(u: &[f64]) -> f64 {
    let robust = |d: Vec<f64>, gain: f64| -> f64 {
        let mut a: Vec<f64> = d.into_iter().map(f64::abs).collect();
        if a.is_empty() {
            return f64::INFINITY;
        }
        let mid = a.len() / 2;
        let (_, m, _) = a.select_nth_unstable_by(mid, f64::total_cmp);
        1.4826 * *m / gain
    };
    let d2: Vec<f64> = u.windows(3).map(|w| w[2] - 2.0 * w[1] + w[0]).collect();
    let d4: Vec<f64> = u.windows(5).map(|w| w[4] - 4.0 * w[3] + 6.0 * w[2] - 4.0 * w[1] + w[0]).collect();
    let s = robust(d2, 6f64.sqrt()).min(robust(d4, 70f64.sqrt()));
    if s.is_finite() {
        s
    } else {
        0.0
    }
}

/// Per interval `i` (samples i − 1 → i): the input's change, and the largest shift (s) of
/// when it came that the samples leave open ([`edge_spread`]'s `w·T/2`). A change within
/// four standard deviations of the input's own white noise `noise` ([`input_noise`]) is no edge: a noisy
/// input's every sample would otherwise be a jump the samples do not place, and the floor
/// would carry a shift of half a sample for each (unseen seed 9053, case 72: a torque logged
/// with 2.7 mN·m of white noise put the floor at 14× the angle noise, and an asymmetric
/// friction at SNR 3.4 was `none` at 0.33× that floor).
fn edge_shifts(t: &[f64], u: &[f64], n: usize, noise: f64) -> (Vec<f64>, Vec<f64>) {
    let quiet = 4.0 * std::f64::consts::SQRT_2 * noise;
    // the change over interval i (samples i − 1 → i), and the monotone run of changes it is in
    let delta: Vec<f64> = (0..n)
        .map(|i| match (t.get(i.wrapping_sub(1)), t.get(i), u.get(i.wrapping_sub(1)), u.get(i)) {
            (Some(&t0), Some(&t1), Some(&u0), Some(&u1)) if t1 > t0 && (u1 - u0).abs() > quiet => u1 - u0,
            _ => 0.0,
        })
        .collect();
    let mut run_sum = vec![0.0; n];
    let mut i = 1;
    while i < n {
        let sign = delta[i].signum();
        let mut j = i;
        let mut sum = 0.0;
        while j < n && delta[j] != 0.0 && delta[j].signum() == sign {
            sum += delta[j].abs();
            j += 1;
        }
        let j = j.max(i + 1);
        for r in &mut run_sum[i..j] {
            *r = sum;
        }
        i = j;
    }
    // per interval: the largest shift (s); its direction is the change's sign
    let half: Vec<f64> = (0..n)
        .map(|i| {
            if i == 0 || delta[i] == 0.0 || !(run_sum[i] > 0.0) {
                return 0.0;
            }
            let w = (1.5 * delta[i].abs() / run_sum[i] - 0.5).clamp(0.0, 1.0);
            w * 0.5 * (t[i] - t[i - 1])
        })
        .collect();
    (delta, half)
}

/// The sub-steps of each sample interval (and whether its band is treated as stiff), fixed
/// for all the evaluations of one fit: a count that followed the fitted values would make the
/// simulated angle jump by its integration error between two nearby values, and a
/// finite-difference Jacobian would read that jump as a slope.
pub fn plan(law: &Law, t: &[f64], u: Option<&[f64]>, start: (f64, f64), n: usize) -> Option<Vec<u8>> {
    let mut p = Vec::with_capacity(n);
    simulate(law, t, u, start, n, Plan::Choose(&mut p), Reading::Cubic)?;
    Some(p)
}

/// [`run`] with the sub-steps of `plan` (from [`plan`], at least `n − 1` entries).
pub fn run_planned(
    law: &Law,
    t: &[f64],
    u: Option<&[f64]>,
    start: (f64, f64),
    n: usize,
    plan: &[u8],
) -> Option<Vec<f64>> {
    simulate(law, t, u, start, n, Plan::Follow(plan), Reading::Cubic)
}

/// Whether sub-steps are chosen (and recorded) or followed.
enum Plan<'p> {
    Choose(&'p mut Vec<u8>),
    Follow(&'p [u8]),
}

/// The flag of a planned entry that marks a stiff band.
const STIFF: u8 = 0x80;

/// How the logged input is read between its samples.
#[derive(Clone, Copy)]
enum Reading<'a> {
    /// [`Input::between`]: what every fit uses
    Cubic,
    /// a line between the samples
    Line,
    /// the cubic, read earlier by the interval's entry here (s; negative: later)
    Shifted(&'a [f64]),
}

fn simulate(
    law: &Law,
    t: &[f64],
    u: Option<&[f64]>,
    start: (f64, f64),
    n: usize,
    mut plan: Plan,
    reading: Reading,
) -> Option<Vec<f64>> {
    let n = n.min(t.len());
    let mut out = Vec::with_capacity(n);
    let mut y = Y { q: start.0, v: start.1, f: 0.0 };
    if n == 0 {
        return Some(out);
    }
    out.push(y.q);
    let pure = law.has_sign() && law.band <= 0.0;
    let banded = law.has_sign() && law.band > 0.0;
    for i in 1..n {
        let (t0, t1) = (t[i - 1], t[i]);
        let dt = t1 - t0;
        if !(dt > 0.0) {
            out.push(y.q);
            continue;
        }
        let inp = match (u, reading) {
            (Some(u), Reading::Line) => Input::line(t, u, i),
            (Some(u), Reading::Cubic) => Input::between(t, u, i),
            (Some(u), Reading::Shifted(by)) => {
                Input { shift: by.get(i).copied().unwrap_or(0.0), ..Input::between(t, u, i) }
            }
            (None, _) => Input::ZERO,
        };
        let (sub, stiff_band) = match &mut plan {
            Plan::Follow(p) => {
                let e = p.get(i - 1).copied().unwrap_or(1);
                (usize::from((e & !STIFF).max(1)), e & STIFF != 0)
            }
            Plan::Choose(rec) => {
                let (sub, stiff) = choose_sub(law, &inp, t0, dt, y, banded);
                rec.push(sub as u8 | if stiff { STIFF } else { 0 });
                (sub, stiff)
            }
        };
        let h = dt / sub as f64;
        for k in 0..sub {
            let ts = t0 + k as f64 * h;
            y = if pure {
                step_stick_slip(law, &inp, ts, h, y)
            } else if stiff_band {
                step_stiff_band(law, &inp, ts, h, y)
            } else if law.dahl.is_some() {
                step_dahl(law, &inp, ts, h, y)
            } else {
                rk4(law, &inp, ts, h, y, Mode::Smooth)
            };
        }
        if !(y.q.is_finite() && y.v.is_finite()) || y.q.abs() > 1e6 {
            return None;
        }
        out.push(y.q);
    }
    Some(out)
}

/// Sub-steps for one sample interval from state `y`: enough that the fastest mode advances
/// ≤ 0.05 rad per step (with a factor 1.5 of room for what a fit does to the values it was
/// planned at), a periodic term at the speed the joint may reach ≤ 1 rad of its phase (a
/// small torque: its error stays far below the motion's), a Dahl state's
/// pre-sliding stiffness ≤ 0.5, and at least four where the speed may cross the band's edge (a
/// kink that costs RK4 its order; the pure sign's zero crossings are located instead); whether
/// the band is stiff.
fn choose_sub(law: &Law, inp: &Input, t0: f64, dt: f64, y: Y, banded: bool) -> (usize, bool) {
    let acc = accel(law, inp, t0, y, Mode::Smooth).abs();
    let v_bound = y.v.abs() + acc * dt;
    let (omega, kappa) = law.rates();
    let mut sub = (1.5 * dt * omega.max(law.damping(v_bound)) / 0.05).ceil().max((dt * kappa * v_bound).ceil());
    if let Some(sigma) = law.dahl {
        sub = sub.max((dt * (sigma.abs() / law.j.max(1e-12)).sqrt() / 0.5).ceil());
    }
    if banded && (y.v.abs() - law.band).abs() <= acc * dt + 1e-12 {
        sub = sub.max(4.0);
    }
    let sub = sub.clamp(1.0, 64.0) as usize;
    (sub, banded && law.band_rate() * dt / sub as f64 > 0.5)
}

/// Which friction the right-hand side uses.
#[derive(Clone, Copy, PartialEq)]
enum Mode {
    /// the banded law (or no sign term), smooth enough for RK4
    Smooth,
    /// sliding in a fixed direction
    Slide(f64),
    /// the Dahl state as the exponential in the travel from `q_s` with state `f_s` there
    Dahl { q_s: f64, f_s: f64 },
}

#[inline]
fn dahl_force(law: &Law, q: f64, q_s: f64, f_s: f64) -> f64 {
    let (Some(sigma), c) = (law.dahl, law.c.abs()) else { return 0.0 };
    if c <= 0.0 {
        return 0.0;
    }
    let dq = q - q_s;
    if dq == 0.0 {
        return f_s;
    }
    let target = c * dq.signum();
    target + (f_s - target) * (-sigma * dq.abs() / c).exp()
}

#[inline]
fn accel(law: &Law, inp: &Input, t: f64, y: Y, mode: Mode) -> f64 {
    let sign_like = match mode {
        Mode::Smooth if law.has_sign() => {
            if law.band > 0.0 {
                law.banded(y.v)
            } else {
                law.sliding(y.v, y.v.signum()) * (y.v != 0.0) as u8 as f64
            }
        }
        Mode::Smooth => 0.0,
        Mode::Slide(dir) => law.sliding(y.v, dir),
        Mode::Dahl { q_s, f_s } => dahl_force(law, y.q, q_s, f_s),
    };
    (inp.at(t) - law.smooth(y.v) - sign_like - law.position(y.q)) / law.j
}

#[inline]
fn rk4(law: &Law, inp: &Input, t: f64, h: f64, y: Y, mode: Mode) -> Y {
    let f = |t: f64, q: f64, v: f64| accel(law, inp, t, Y { q, v, f: 0.0 }, mode);
    let b1 = f(t, y.q, y.v);
    let a1 = y.v;
    let (a2, b2) = (y.v + 0.5 * h * b1, f(t + 0.5 * h, y.q + 0.5 * h * a1, y.v + 0.5 * h * b1));
    let (a3, b3) = (y.v + 0.5 * h * b2, f(t + 0.5 * h, y.q + 0.5 * h * a2, y.v + 0.5 * h * b2));
    let (a4, b4) = (y.v + h * b3, f(t + h, y.q + h * a3, y.v + h * b3));
    Y { q: y.q + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4), v: y.v + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4), f: y.f }
}

fn step_dahl(law: &Law, inp: &Input, t: f64, h: f64, y: Y) -> Y {
    let mode = Mode::Dahl { q_s: y.q, f_s: y.f };
    let mut next = rk4(law, inp, t, h, y, mode);
    next.f = dahl_force(law, next.q, y.q, y.f);
    next
}

/// The first time in `(0, h]` at which `g` (positive at 0, ≤ 0 at `h`) reaches 0, by
/// bisection: a located event keeps the simulation smooth in the fitted parameters.
fn locate(h: f64, mut g: impl FnMut(f64) -> f64) -> f64 {
    let (mut lo, mut hi) = (0.0, h);
    // v is ≈ 0 at the event, so the angle there depends on its time only to second order
    for _ in 0..24 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// One sub-step with the pure sign: slide, stop at a velocity zero, stick while the static
/// level holds the joint.
fn step_stick_slip(law: &Law, inp: &Input, t: f64, h: f64, mut y: Y) -> Y {
    let mut done = 0.0;
    for _ in 0..6 {
        let left = h - done;
        if left <= 0.0 {
            break;
        }
        let now = t + done;
        let dir = if y.v != 0.0 {
            y.v.signum()
        } else {
            let tn = inp.at(now) - law.position(y.q);
            let (fwd, back) = law.static_levels();
            if tn <= fwd && tn >= -back {
                // stuck: stays for the rest of the sub-step
                return Y { v: 0.0, ..y };
            }
            tn.signum()
        };
        let next = rk4(law, inp, now, left, y, Mode::Slide(dir));
        if next.v * dir > 0.0 {
            return next;
        }
        let s = locate(left, |s| rk4(law, inp, now, s, y, Mode::Slide(dir)).v * dir);
        let at = rk4(law, inp, now, s, y, Mode::Slide(dir));
        y = Y { q: at.q, v: 0.0, f: y.f };
        done += s;
    }
    y
}

/// One sub-step where the band is stiff for the step: slide with the full sign, locate the
/// entry into the band, and inside it follow the exact creep of the linearised law
/// `J·q̇' = g − μ·q̇` (g the non-friction torque at the entry, μ the band's slope on that side),
/// leaving it again where the creep would exceed the band.
fn step_stiff_band(law: &Law, inp: &Input, t: f64, h: f64, mut y: Y) -> Y {
    let vb = law.band;
    let mut done = 0.0;
    for _ in 0..6 {
        let left = h - done;
        if left <= 0.0 {
            break;
        }
        let now = t + done;
        if y.v.abs() >= vb {
            let dir = y.v.signum();
            let next = rk4(law, inp, now, left, y, Mode::Slide(dir));
            if next.v * dir >= vb {
                return next;
            }
            let s = locate(left, |s| rk4(law, inp, now, s, y, Mode::Slide(dir)).v * dir - vb);
            let at = rk4(law, inp, now, s, y, Mode::Slide(dir));
            // just inside the band, so the creep below takes over
            y = Y { q: at.q, v: dir * vb * (1.0 - 1e-9), f: y.f };
            done += s;
            continue;
        }
        let g = inp.at(now + 0.5 * left) - law.position(y.q);
        let ex = law.excess(0.5 * vb);
        let side = if g != 0.0 { g.signum() } else { y.v.signum() };
        let mu = (law.c + ex + side * law.delta).max(0.0) / vb + law.b + law.a.abs() * vb;
        let lam = mu / law.j;
        let v_inf = g / mu.max(1e-300);
        let dv = y.v - v_inf;
        let creep = |s: f64| {
            let e = (-lam * s).exp();
            Y { q: y.q + v_inf * s + dv * (1.0 - e) / lam, v: v_inf + dv * e, f: y.f }
        };
        if v_inf.abs() > vb {
            // the creep leaves the band where v reaches ±vb
            let target = v_inf.signum() * vb;
            let ratio = dv / (target - v_inf);
            if ratio >= 1.0 {
                let s = ratio.ln() / lam;
                if s < left {
                    let at = creep(s);
                    y = Y { q: at.q, v: target, f: y.f };
                    done += s;
                    continue;
                }
            }
        }
        return creep(left);
    }
    y
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn elastic(c: f64, band: f64) -> Law {
        Law { j: 0.0085, b: 0.0416, c, band, k: 7.3035, span: 0.6, ..Law::default() }
    }

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 * dt).collect()
    }

    /// The input's noise is read from the input alone: within 15 % on a pulse train and on a
    /// sine of 50 samples per period (whose curvature the fourth differences leave out), 0 on a
    /// clean step. (At 18 samples per period a 2 N·m sine's fourth differences are as large as
    /// the noise's, and the reading comes out 1.3× high.)
    #[test]
    fn the_input_noise_is_read_past_edges_and_curvature() {
        let n = 2000;
        let e = white(n, 0.003, 7);
        let pulses: Vec<f64> = (0..n).map(|i| if (i / 100) % 2 == 1 { 1.5 } else { 0.0 } + e[i]).collect();
        let sine: Vec<f64> = (0..n).map(|i| 2.0 * (i as f64 * 0.125).sin() + e[i]).collect();
        for (what, u) in [("pulses", &pulses), ("sine", &sine)] {
            let r = input_noise(u) / 0.003;
            assert!((r - 1.0).abs() < 0.15, "{what}: read {r:.3}× the noise");
        }
        let step: Vec<f64> = (0..n).map(|i| if i < 500 { 0.0 } else { 1.0 }).collect();
        assert_eq!(input_noise(&step), 0.0);
    }

    /// A noisy input's sample-to-sample jumps are not edges the samples leave unplaced: the slack
    /// of a pulse train at 50 Hz is the one of its clean edges (a jump between two samples: half
    /// a sample), and the same train resolved over five samples per edge leaves (almost) none
    /// with or without its noise. Without the noise rule every noise jump counted as an edge.
    #[test]
    fn a_noisy_input_has_the_slack_of_its_edges_only() {
        let (n, dt) = (400, 0.02);
        let t = times(n, dt);
        let e = white(n, 0.003, 11);
        let ramp = |i: usize| {
            let k = i % 100;
            (k.min(100 - k) as f64 / 5.0).min(1.0)
        };
        let smooth: Vec<f64> = (0..n).map(ramp).collect();
        let smooth_noisy: Vec<f64> = (0..n).map(|i| ramp(i) + e[i]).collect();
        let slack = |u: &[f64]| edge_slack(&t, u, n, input_noise(u));
        assert!(slack(&smooth) < 0.1 * dt, "{}", slack(&smooth));
        assert!(slack(&smooth_noisy) < 0.25 * dt, "{}", slack(&smooth_noisy));
        // the noise alone (flat input): no edge anywhere
        assert_eq!(slack(&e), 0.0);
        // the noise's own response is counted instead, and it grows as the noise's square
        let law = elastic(0.0, 0.0);
        let flat = vec![0.0; n];
        let ms = |sd: f64| noise_spread(&law, &t, &flat, (0.0, 0.0), n, sd).unwrap().iter().sum::<f64>() / n as f64;
        let (a, b) = (ms(0.001), ms(0.002));
        assert!(a > 0.0 && (b / a - 4.0).abs() < 1e-6, "{a} {b}");
    }

    /// A joint released where the spring's torque is below the Coulomb level stays where it is,
    /// and a swinging one stops for good at the first reversal whose spring torque is below it.
    #[test]
    fn pure_sign_sticks_while_the_spring_torque_is_below_c() {
        let law = elastic(0.05, 0.0);
        let t = times(2000, 1e-3);
        // K·x = 7.3·0.005 = 0.037 < c = 0.05: never moves
        let q = run(&law, &t, None, (0.005, 0.0), t.len()).unwrap();
        assert!(q.iter().all(|&x| x == 0.005), "moved: {:?}", &q[..5]);
        // released from 0.2 rad: swings, then stops at an angle |x| ≤ c/K and stays exactly there
        let q = run(&law, &t, None, (0.2, 0.0), t.len()).unwrap();
        let end = q[q.len() - 1];
        assert!(end.abs() <= 0.05 / 7.3035 + 1e-9, "stopped at {end}");
        let stop = q.iter().rposition(|&x| x != end).unwrap();
        assert!(stop < 1500, "still moving at sample {stop}");
        assert!(q.iter().map(|x| x.abs()).fold(0.0, f64::max) > 0.19);
        // the same joint with a band creeps on towards the spring's rest angle instead
        let qb = run(&elastic(0.05, 0.01), &t, None, (0.2, 0.0), t.len()).unwrap();
        assert!(qb[qb.len() - 1].abs() < end.abs() * 0.9, "{} vs {end}", qb[qb.len() - 1]);
    }

    /// Stick-slip is a located event, not a step artefact: the same response at 50 Hz and at
    /// 1 kHz sampling agrees at the common instants, and against 4× finer sub-steps.
    #[test]
    fn stick_slip_does_not_depend_on_the_sampling() {
        let law = Law { strib: vec![(0.02, 0.05, 1.0)], ..elastic(0.03, 0.0) };
        let fine = times(3001, 1e-3);
        let coarse = times(151, 0.02);
        let qf = run(&law, &fine, None, (0.25, 0.0), fine.len()).unwrap();
        let qc = run(&law, &coarse, None, (0.25, 0.0), coarse.len()).unwrap();
        let worst = (0..coarse.len()).map(|k| (qc[k] - qf[20 * k]).abs()).fold(0.0, f64::max);
        eprintln!("stick-slip 50 Hz vs 1 kHz: worst {worst:.2e} rad, end {:.5} {:.5}", qf[3000], qc[150]);
        assert!(worst < 2e-5, "worst {worst:e}");
    }

    /// A stiff band (a heavy pendulum with a 2 mrad/s band) is integrated stably at 50 Hz and
    /// agrees with a 1 kHz run of the same law.
    #[test]
    fn a_stiff_band_creeps_stably() {
        let law =
            Law { j: 0.2, b: 0.5, c: 3.0, band: 0.002, weight: Some((1.0, 20.0, 0.0)), span: 1.0, ..Law::default() };
        assert!(law.band_rate() * 0.02 > 100.0);
        let fine = times(4001, 1e-3);
        let coarse = times(201, 0.02);
        let qf = run(&law, &fine, None, (0.8, 0.0), fine.len()).unwrap();
        let qc = run(&law, &coarse, None, (0.8, 0.0), coarse.len()).unwrap();
        let worst = (0..coarse.len()).map(|k| (qc[k] - qf[20 * k]).abs()).fold(0.0, f64::max);
        eprintln!("stiff band 50 Hz vs 1 kHz: worst {worst:.2e} rad, end {:.5} {:.5}", qf[4000], qc[200]);
        assert!(worst < 1e-3, "worst {worst:e}");
        assert!(qf.iter().all(|q| q.abs() <= 0.8 + 1e-9));
    }

    /// The Dahl state stays within ±c and, with a stiff σ, the response approaches the pure
    /// sign's.
    #[test]
    fn presliding_tends_to_the_sign_law() {
        let t = times(2001, 1e-3);
        let sign = run(&elastic(0.03, 0.0), &t, None, (0.2, 0.0), t.len()).unwrap();
        let dahl = run(&Law { dahl: Some(0.03 / 1e-5), ..elastic(0.03, 0.0) }, &t, None, (0.2, 0.0), t.len()).unwrap();
        let soft = run(&Law { dahl: Some(0.03 / 3e-3), ..elastic(0.03, 0.0) }, &t, None, (0.2, 0.0), t.len()).unwrap();
        let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        eprintln!("dahl vs sign: stiff {:.2e} soft {:.2e}", d(&sign, &dahl), d(&sign, &soft));
        assert!(d(&sign, &dahl) < 2e-3, "{}", d(&sign, &dahl));
        assert!(d(&sign, &soft) > 3.0 * d(&sign, &dahl));
    }
}
