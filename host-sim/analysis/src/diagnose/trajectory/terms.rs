//! What a trajectory-mode fit varies: the start `(q0, q̇0)`, the model's own terms (J fixed: a
//! free response sees D/J only) and each effect's values, laid out as one vector
//! `θ = [q0, q̇0 | the model's terms | effect 1 | effect 2 …]`, with the physical bounds of each
//! and the force law ([`Law`]) they make.
//!
//! Effects own their shapes here (never the simulator's plant):
//! - `stribeck`: `level·exp(−(|q̇|/speed)^δ)·sign(q̇)` on top of `c`, δ in 0.5–2;
//! - `asymmetric_friction`: `delta·|sign(q̇)|` (`c ± delta` per direction);
//! - `position_ripple`: one harmonic `α·sin(2πq/P) + β·cos(2πq/P)`, or two;
//! - `cable_spring`: one-sided (taut above or below an angle, with a blend width) or progressive
//!   `k1·x + k3·x³`, or padding pressed over a stretch of angle `A·exp(−½((q − q_b)/w)²)`;
//! - `backlash`: a dead zone of width `w` centred at `m` in the spring (either side of its rest);
//! - `dry_friction`: `c·sign(q̇)` when the model has none, with the pure sign or (where the
//!   file states no band) a sign band `clamp(q̇/v_band, −1, 1)` searched with it;
//! - `presliding_hysteresis`: a Dahl state of the model's level `c` and pre-sliding distance
//!   `x = c/σ` instead of `c·sign(q̇)`;
//! - `delay`: the joint felt the logged input `u` shifted by `δ` either way (only with a logged
//!   `u`; positive as torque mode's: the logged state lags the input).

use joint_core::params::ParamId;
use joint_formats::model_file::ModelFile;
use joint_formats::vocab::Effect as Vocab;

use super::sim::{Cable, Law, Table};
use crate::diagnose::candidates::{base_from_model, Col};

/// One effect a fit can carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Kind {
    Stribeck,
    Asymmetric,
    Ripple,
    Ripple2,
    CableAbove,
    CableBelow,
    CableCubic,
    CableBump,
    Backlash,
    Dry,
    /// dry friction with its own sign band (the file states none)
    DryBand,
    Presliding,
    Delay,
}

impl Kind {
    pub const ALL: [Kind; 13] = [
        Kind::Stribeck,
        Kind::Asymmetric,
        Kind::Ripple,
        Kind::Ripple2,
        Kind::CableAbove,
        Kind::CableBelow,
        Kind::CableCubic,
        Kind::CableBump,
        Kind::Backlash,
        Kind::Dry,
        Kind::DryBand,
        Kind::Presliding,
        Kind::Delay,
    ];

    /// The vocabulary entry (variants of one effect share it).
    pub fn effect(self) -> Vocab {
        match self {
            Kind::Stribeck => Vocab::Stribeck,
            Kind::Asymmetric => Vocab::AsymmetricFriction,
            Kind::Ripple | Kind::Ripple2 => Vocab::PositionRipple,
            Kind::CableAbove | Kind::CableBelow | Kind::CableCubic | Kind::CableBump => Vocab::CableSpring,
            Kind::Backlash => Vocab::Backlash,
            Kind::Dry | Kind::DryBand => Vocab::DryFriction,
            Kind::Presliding => Vocab::PreslidingHysteresis,
            Kind::Delay => Vocab::Delay,
        }
    }

    /// The spec §3 name.
    pub fn name(self) -> &'static str {
        self.effect().name()
    }

    /// The kinds that fit vocabulary term `v` in trajectory mode, or why a free response cannot
    /// show it. The match names every entry, so a term added to the vocabulary does not compile
    /// here until trajectory mode fits it or says why not (the report's "not applicable" list
    /// comes from here); a test checks [`Kind::ALL`] against it.
    pub fn of(v: Vocab) -> Result<&'static [Kind], &'static str> {
        match v {
            Vocab::Stribeck => Ok(&[Kind::Stribeck]),
            Vocab::AsymmetricFriction => Ok(&[Kind::Asymmetric]),
            Vocab::LoadDependentFriction => Err("trajectory mode has no measured transmitted torque"),
            Vocab::ThermalDrift => Err(
                "a free response of seconds has no temperature course: a slow change of friction is a damping value",
            ),
            Vocab::PositionRipple => Ok(&[Kind::Ripple, Kind::Ripple2]),
            Vocab::CableSpring => Ok(&[Kind::CableAbove, Kind::CableBelow, Kind::CableCubic, Kind::CableBump]),
            Vocab::Backlash => Ok(&[Kind::Backlash]),
            Vocab::Delay => Ok(&[Kind::Delay]),
            Vocab::DryFriction => Ok(&[Kind::Dry, Kind::DryBand]),
            Vocab::PreslidingHysteresis => Ok(&[Kind::Presliding]),
            // verdicts, and the start state every trajectory fit frees anyway
            Vocab::Parameters | Vocab::InitialState | Vocab::None | Vocab::Unexplained => Ok(&[]),
        }
    }

    /// How many values the effect adds to the model (what parsimony counts).
    pub fn size(self, lay: &Layout) -> usize {
        match self {
            Kind::Asymmetric | Kind::Dry | Kind::Presliding | Kind::Delay => 1,
            Kind::Backlash | Kind::DryBand => 2,
            Kind::CableCubic if lay.has(Col::Q) => 2,
            Kind::CableBump
            | Kind::Stribeck
            | Kind::Ripple
            | Kind::CableAbove
            | Kind::CableBelow
            | Kind::CableCubic => 3,
            Kind::Ripple2 => 6,
        }
    }
}

/// A model term trajectory mode fits: J only with a known input (a free response scales with
/// D/J), and never a load-dependent friction, which a log without a measured load cannot move
/// (the joint's term is 0 there).
pub fn kept(c: Col, driven: bool) -> bool {
    (driven || c != Col::Qdd) && c != Col::LoadSgn
}

/// The model's terms as the fits see them, and what bounds the effects' shapes.
#[derive(Clone, Debug)]
pub struct Layout {
    pub cols: Vec<Col>,
    /// the terms' values in the file: one per column, then the weight's `s` when it is free
    pub beta0: Vec<f64>,
    /// the file's weight `s` when the model has a weight: the fits free it (after the columns),
    /// since the restoring torque's shape is what a swing measures most closely
    pub weight_s: Option<f64>,
    pub j: f64,
    /// the file's sign band (0: no `v_band`, the pure sign)
    pub band: f64,
    /// the file's own pre-sliding stiffness, when it has `[presliding]`
    pub file_sigma: Option<f64>,
    /// angles travelled in the training part: lowest, highest
    pub qmin: f64,
    pub qmax: f64,
    /// the spring's rest angle (or the equilibrium of the weight), a backlash's start centre
    pub q_rest: f64,
    /// the file's spring rest angle `q0` (0 without a spring): a dead zone's torque is taken
    /// relative to it (see [`Law::position`])
    pub spring_q0: f64,
    /// a typical speed of the motion (95th percentile of |q̇|), rad/s
    pub v_typ: f64,
    /// a torque scale: the restoring torque over half the angles travelled, N·m
    pub torque: f64,
    /// the longest ripple period searched, rad
    pub ripple_max: f64,
    /// the file's gravity table when the simulation can add it ([`table_of`]): fixed, never fitted
    pub table: Option<Table>,
    /// how far (s) the logged input's edges may lie from where its samples put them
    /// ([`super::sim::edge_slack`]; 0 without an input or with one the samples resolve): a delay
    /// within it is no verdict
    pub input_slack: f64,
}

/// The model's gravity table as the simulation adds it: one axis over the joint's own angle, and
/// no fusion (σ_model unset or 0, not the residual of a gravity series), which is the table added
/// to the weight. `Err` names a table trajectory mode cannot simulate (it reads the other joints'
/// angles, or the joint fuses it with its model), `Ok(None)` a model without one.
pub fn table_of(model: &ModelFile) -> Result<Option<Table>, String> {
    let Some(t) = &model.table else { return Ok(None) };
    let fused = model.explicit(ParamId::TableSigmaModel).is_some_and(|s| s > 0.0)
        || model.series.as_ref().is_some_and(|s| s.table_residual);
    match t.axes.as_slice() {
        [a] if a == "q" && !fused => Ok(Some(Table::new((t.grid.clone(), t.torque.clone())))),
        _ if fused => Err("its gravity table is fused with the model (sigma_model)".into()),
        _ => Err(format!("its gravity table reads {:?}, not the joint's own angle alone", t.axes)),
    }
}

impl Layout {
    /// `driven`: the log has a known input, so J is a term the fits can see (a free response
    /// scales with D/J only, and J stays fixed).
    pub fn new(model: &ModelFile, qmin: f64, qmax: f64, v_typ: f64, driven: bool) -> Layout {
        let base = base_from_model(model);
        let (cols, mut beta0): (Vec<Col>, Vec<f64>) =
            base.cols.iter().zip(&base.beta0).filter(|(c, _)| kept(**c, driven)).map(|(c, b)| (*c, *b)).unzip();
        let v = |id| model.value(id);
        let weight_s = free_weight_s(&cols);
        beta0.extend(weight_s);
        let span = (qmax - qmin).max(1e-3);
        let k = if model.explicit(ParamId::SpringK).is_some() { v(ParamId::SpringK) } else { 0.0 };
        let w = if model.explicit(ParamId::WeightAmplitude).is_some() {
            v(ParamId::WeightAmplitude) * v(ParamId::WeightS).abs()
        } else {
            0.0
        };
        let q_rest = if k > 0.0 {
            v(ParamId::SpringQ0) - v(ParamId::OffsetC0) / k
        } else if w > 0.0 {
            -v(ParamId::WeightPhi) / v(ParamId::WeightS)
        } else {
            0.5 * (qmin + qmax)
        };
        let torque = ((k + w) * 0.5 * span).max(1e-6);
        Layout {
            cols,
            beta0,
            weight_s,
            j: v(ParamId::InertiaJ),
            band: model.explicit(ParamId::FrictionVBand).unwrap_or(0.0),
            file_sigma: model.explicit(ParamId::PreslidingSigma).filter(|s| *s > 0.0),
            qmin,
            qmax,
            q_rest,
            spring_q0: if k > 0.0 { v(ParamId::SpringQ0) } else { 0.0 },
            v_typ: v_typ.max(1e-3),
            torque,
            // short periods (gear mesh, cogging, wave generator: ≤ 0.3 rad) with at least three
            // periods inside the angles travelled
            ripple_max: (span / 3.0).min(0.3),
            table: table_of(model).ok().flatten(),
            input_slack: 0.0,
        }
    }

    pub fn has(&self, c: Col) -> bool {
        self.cols.contains(&c)
    }

    /// How many values the model's terms take in θ: one per column, and the weight's `s`.
    pub fn nb(&self) -> usize {
        self.cols.len() + usize::from(self.weight_s.is_some())
    }

    pub fn span(&self) -> f64 {
        (self.qmax - self.qmin).max(1e-3)
    }

    /// The Coulomb level of the model's terms at `base` (0 without a sign term).
    pub fn coulomb(&self, base: &[f64]) -> f64 {
        self.cols.iter().zip(base).filter(|(c, _)| **c == Col::Sgn).map(|(_, b)| *b).sum()
    }

    /// Whether effect `k` applies to this model and log (`Err`: why not).
    pub fn applies(&self, k: Kind, has_u: bool) -> Result<(), &'static str> {
        match k {
            Kind::Backlash if !self.has(Col::Q) => Err("the model has no [spring] whose dead zone could be fitted"),
            Kind::Dry | Kind::DryBand if self.has(Col::Sgn) => {
                Err("the model has a Coulomb term, so a missing Coulomb torque is `parameters`")
            }
            Kind::DryBand if self.band > 0.0 => Err("the file states the sign band its friction has"),
            Kind::Asymmetric if !self.has(Col::Sgn) => {
                Err("the model has no Coulomb term whose level could differ by direction")
            }
            Kind::Presliding if !self.has(Col::Sgn) => {
                Err("the model has no Coulomb term to build up after a reversal")
            }
            Kind::Presliding if self.file_sigma.is_some() => Err("the model already has [presliding]"),
            Kind::Delay if !has_u => {
                Err("a free response has no logged input to lag: a time shift is an initial state")
            }
            Kind::Ripple2 if self.ripple_max < 0.02 => Err("the angles travelled hold too few periods"),
            _ => Ok(()),
        }
    }

    /// Lower and upper bounds of the start and the model's terms.
    pub fn base_bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let mut lo = vec![f64::NEG_INFINITY; 2];
        let mut hi = vec![f64::INFINITY; 2];
        for c in &self.cols {
            // friction cannot feed energy in, a spring cannot push away from its rest
            let nonneg = matches!(c, Col::QdAbsQd | Col::Qd | Col::Sgn | Col::Q | Col::Stribeck(_) | Col::Cable { .. });
            // an inertia is positive (and a tenth of the file's is a wrong model, not a fit)
            lo.push(if *c == Col::Qdd {
                0.1 * self.j
            } else if nonneg {
                0.0
            } else {
                f64::NEG_INFINITY
            });
            hi.push(f64::INFINITY);
        }
        // the weight's `s` within a factor of two of the file's (a unit error is the
        // preparation's to refuse, not a fit's to absorb)
        if let Some(s) = self.weight_s {
            lo.push((0.5 * s).min(2.0 * s));
            hi.push((0.5 * s).max(2.0 * s));
        }
        (lo, hi)
    }

    /// Bounds of effect `k`'s values.
    pub fn effect_bounds(&self, k: Kind) -> (Vec<f64>, Vec<f64>) {
        let inf = f64::INFINITY;
        let span = self.span();
        let per = (0.008f64.ln(), (1.5 * self.ripple_max).max(0.01).ln());
        let width = ((1e-3f64).ln(), (0.5 * span).max(2e-3).ln());
        // A ripple's sine and cosine parts within 20 torque scales: a ripple that holds the joint
        // in its wells is a fraction of the torque scale (seed 7 case 0: 4.9 N·m on a 37 N·m
        // pendulum), while the few LM steps of the grid's prefilter ran a period that fits
        // nothing to thousands of N·m on a 1.2 N·m pendulum (the Jensen swing 02), a simulation
        // that needed its finest sub-steps (40 s instead of 7 for a fit no better).
        let amp = if self.torque > 0.0 { 20.0 * self.torque } else { inf };
        let (lo, hi): (Vec<f64>, Vec<f64>) = match k {
            Kind::Stribeck => (vec![0.0, (1e-3f64).ln(), 0.5], vec![inf, (20.0 * self.v_typ).ln(), 2.0]),
            Kind::Asymmetric => (vec![-inf], vec![inf]),
            Kind::Ripple => (vec![-amp, -amp, per.0], vec![amp, amp, per.1]),
            Kind::Ripple2 => (vec![-amp, -amp, per.0, -amp, -amp, per.0], vec![amp, amp, per.1, amp, amp, per.1]),
            Kind::CableAbove | Kind::CableBelow => {
                (vec![0.0, self.qmin - 0.1 * span, width.0], vec![inf, self.qmax + 0.1 * span, width.1])
            }
            Kind::CableCubic if self.has(Col::Q) => (vec![0.0, self.qmin], vec![inf, self.qmax]),
            Kind::CableCubic => (vec![0.0, 0.0, self.qmin], vec![inf, inf, self.qmax]),
            Kind::CableBump => (vec![-inf, self.qmin, (0.01 * span).ln()], vec![inf, self.qmax, (0.5 * span).ln()]),
            Kind::Backlash => {
                (vec![(1e-4f64).ln(), self.q_rest - 0.5 * span], vec![(0.5 * span).ln(), self.q_rest + 0.5 * span])
            }
            Kind::Dry => (vec![0.0], vec![inf]),
            Kind::DryBand => (vec![0.0, (1e-3 * self.v_typ).ln()], vec![inf, (0.5 * self.v_typ).ln()]),
            Kind::Presliding => (vec![(1e-5f64).ln()], vec![(0.05f64).ln()]),
            Kind::Delay => (vec![-0.2], vec![0.2]),
        };
        (lo, hi)
    }

    /// Whether effect `k` is a friction level whose starts form a grid that is scanned (each
    /// simulated once over the whole training part, the best three descended) rather than
    /// descended from each: with the pure sign, a free decay stops where the level lets the
    /// spring or weight no longer break it away, after a number of half-swings that steps with
    /// the level, so the angle it rests at runs back and forth between ±c/K as the level grows
    /// and the training residual (a rest often takes most of the log) has a minimum on every
    /// step. Seed 7 case 72, a released pendulum without its Coulomb term (c = 0.37 N·m, about
    /// five half-swings): the file's model with c = 0.25, 0.30, 0.37 held out 0.0130, 0.0155,
    /// 0.0110 rad, and the fit from one start stopped at c = 0.19 or 0.06. A step is c/n wide
    /// for n half-swings, so a ratio of 1.25 between levels puts a start on each of a dozen.
    pub fn level_grid(&self, k: Kind) -> bool {
        matches!(k, Kind::Dry | Kind::DryBand | Kind::Asymmetric)
    }

    /// Starts of effect `k`'s values (several where its shape makes the fit multimodal).
    pub fn effect_starts(&self, k: Kind, c_ref: f64) -> Vec<Vec<f64>> {
        let span = self.span();
        let tq = self.torque;
        let lvl = if c_ref > 0.0 { 0.3 * c_ref } else { 0.05 * tq };
        // the Coulomb levels a dry friction's scan starts from (see [`Layout::level_grid`])
        let levels = || (0..28).map(move |i| 0.002 * tq * 1.25f64.powi(i));
        match k {
            Kind::Stribeck => {
                // the speed is where the fit is multimodal (a high narrow curve and a low wide
                // one take the same energy per reversal): a decade and a half of starts
                let mut v = Vec::new();
                for f in [0.01, 0.03, 0.1, 0.3] {
                    for d in [1.0, 2.0] {
                        v.push(vec![lvl, (f * self.v_typ).ln(), d]);
                    }
                }
                v
            }
            // a level grid (see [`Layout::level_grid`]); the former single start first
            Kind::Asymmetric => {
                let c = c_ref.max(0.01 * tq);
                std::iter::once(0.1)
                    .chain([-0.1, 0.05, -0.05, 0.2, -0.2, 0.3, -0.3, 0.45, -0.45, 0.6, -0.6, 0.8, -0.8])
                    .map(|f| vec![f * c])
                    .collect()
            }
            // The period is where the fit is multimodal (a start more than ~10 % off locks onto
            // another period): starts every 15 % from 0.01 rad to `ripple_max`.
            Kind::Ripple => (0..40)
                .map(|i| 0.01 * 1.15f64.powi(i))
                .take_while(|p| *p <= self.ripple_max)
                .map(|p| vec![0.02 * tq, 0.02 * tq, p.ln()])
                .collect(),
            Kind::Ripple2 => Vec::new(), // started from the best single harmonic (see fits)
            Kind::CableAbove => [0.5, 0.75, 0.9]
                .iter()
                .map(|f| vec![0.1 * tq / (0.2 * span), self.qmin + f * span, (0.05 * span).ln()])
                .collect(),
            Kind::CableBelow => [0.5, 0.25, 0.1]
                .iter()
                .map(|f| vec![0.1 * tq / (0.2 * span), self.qmin + f * span, (0.05 * span).ln()])
                .collect(),
            Kind::CableCubic => {
                let k3 = 0.1 * tq / (0.5 * span).powi(3);
                let mid = 0.5 * (self.qmin + self.qmax);
                if self.has(Col::Q) {
                    vec![vec![k3, mid]]
                } else {
                    vec![vec![0.0, k3, mid], vec![0.1 * tq / span, k3, mid]]
                }
            }
            Kind::CableBump => [0.25, 0.5, 0.75]
                .iter()
                .flat_map(|f| [1.0, -1.0].map(|sg| vec![sg * 0.05 * tq, self.qmin + f * span, (0.1 * span).ln()]))
                .collect(),
            // The dead zone holds the spring's unloaded angle: centred on it, or ending there on
            // either side; its width on a grid (a zone much narrower than the start sees no
            // gradient from the crossings it misses, and the fit ran the centre off the motion
            // with a width of 0.3 mrad, seed 7 cases 3 and 36).
            Kind::Backlash => [0.005, 0.01, 0.02, 0.04, 0.08]
                .iter()
                .flat_map(|w| [0.0, 0.5, -0.5].map(|side| vec![(w * span).ln(), self.spring_q0 + side * w * span]))
                .collect(),
            Kind::Dry => std::iter::once(0.02 * tq).chain(levels()).map(|c| vec![c]).collect(),
            // the level grid at a narrow and a wide band (a band lets a joint at rest creep where
            // the pure sign holds it, so the level's steps are smoothed out)
            Kind::DryBand => {
                [0.01, 0.1].iter().flat_map(|f| levels().map(move |c| vec![c, (f * self.v_typ).ln()])).collect()
            }
            Kind::Presliding => [2e-4f64, 2e-3].iter().map(|x| vec![x.ln()]).collect(),
            Kind::Delay => [-0.02, -0.005, 0.005, 0.02].iter().map(|d| vec![*d]).collect(),
        }
    }

    /// The force law of `θ` with `effects` (in θ's order after the model's terms).
    pub fn law(&self, th: &[f64], effects: &[Kind]) -> Law {
        let nb = self.nb();
        let mut law = Law {
            j: self.j,
            band: self.band,
            dahl: self.file_sigma,
            span: self.span(),
            pivot: self.spring_q0,
            table: self.table.clone(),
            ..Law::default()
        };
        let mut weight = (0.0, 0.0, 0.0);
        let mut has_weight = false;
        for (c, &b) in self.cols.iter().zip(th.iter().skip(2)) {
            match *c {
                Col::Qdd => law.j = b,
                Col::QdAbsQd => law.a += b,
                Col::Qd => law.b += b,
                Col::Sgn => law.c += b,
                Col::SinSq(s) => {
                    weight.0 = s;
                    weight.1 = b;
                    has_weight = true;
                }
                Col::CosSq(s) => {
                    weight.0 = s;
                    weight.2 = b;
                    has_weight = true;
                }
                Col::Q => law.k += b,
                Col::Const => law.konst += b,
                Col::Stribeck(v) => law.strib.push((b, v, 2.0)),
                Col::AbsSgn => law.delta += b,
                Col::RipSin(p) => push_ripple(&mut law, p, Some(b), None),
                Col::RipCos(p) => push_ripple(&mut law, p, None, Some(b)),
                Col::Cable { engage, width } => law.cables.push(Cable::Above { k: b, engage, width }),
                _ => {}
            }
        }
        if has_weight {
            if self.weight_s.is_some() {
                weight.0 = th.get(2 + self.cols.len()).copied().unwrap_or(weight.0);
            }
            law.weight = Some(weight);
        }
        let mut off = 2 + nb;
        for &k in effects {
            let e = th.get(off..).unwrap_or(&[]);
            let g = |i: usize| e.get(i).copied().unwrap_or(0.0);
            match k {
                Kind::Stribeck => law.strib.push((g(0), g(1).exp(), g(2))),
                Kind::Asymmetric => law.delta += g(0),
                Kind::Ripple => law.ripples.push((g(2).exp(), g(0), g(1))),
                Kind::Ripple2 => {
                    law.ripples.push((g(2).exp(), g(0), g(1)));
                    law.ripples.push((g(5).exp(), g(3), g(4)));
                }
                Kind::CableAbove => law.cables.push(Cable::Above { k: g(0), engage: g(1), width: g(2).exp() }),
                Kind::CableBelow => law.cables.push(Cable::Below { k: g(0), engage: g(1), width: g(2).exp() }),
                Kind::CableCubic if self.has(Col::Q) => law.cables.push(Cable::Cubic { k1: 0.0, k3: g(0), qs: g(1) }),
                Kind::CableCubic => law.cables.push(Cable::Cubic { k1: g(0), k3: g(1), qs: g(2) }),
                Kind::CableBump => law.cables.push(Cable::Bump { a: g(0), qb: g(1), w: g(2).exp() }),
                Kind::Backlash => law.backlash = Some((g(0).exp(), g(1))),
                Kind::Dry => law.c += g(0),
                Kind::DryBand => {
                    law.c += g(0);
                    law.band = g(1).exp();
                }
                Kind::Presliding => law.dahl = Some(law.c.max(0.0) / g(0).exp()),
                Kind::Delay => {}
            }
            off += self.len(k);
        }
        // Friction never pushes: a direction offset beyond the Coulomb level is held at it
        // (the fit is then marked implausible, see `implausible`).
        law.delta = law.delta.clamp(-law.c.max(0.0), law.c.max(0.0));
        law
    }

    /// How many entries of θ effect `k` takes.
    pub fn len(&self, k: Kind) -> usize {
        self.effect_bounds(k).0.len()
    }

    /// The input lag of `θ` with `effects`, s (0 without a delay): the joint felt the logged
    /// input of `lag` seconds earlier (negative: the logged input is late).
    pub fn delay(&self, th: &[f64], effects: &[Kind]) -> f64 {
        let mut off = 2 + self.nb();
        for &k in effects {
            if k == Kind::Delay {
                return th.get(off).copied().unwrap_or(0.0);
            }
            off += self.len(k);
        }
        0.0
    }

    /// Whether a fitted delay `d` (s) lies within the time the logged input's samples leave open
    /// for its edges ([`Layout::input_slack`]): the file's model with its edges placed, no delay.
    pub fn within_input_slack(&self, d: f64) -> bool {
        d.abs() <= self.input_slack
    }

    /// Why effect `k` (at `e`, its values) on top of the terms `base` is not the physical effect
    /// its name says: the same sign rules as torque mode, plus friction that would push in one
    /// direction.
    pub fn implausible(&self, k: Kind, base: &[f64], e: &[f64]) -> Option<&'static str> {
        let g = |i: usize| e.get(i).copied().unwrap_or(0.0);
        let c: f64 = self.cols.iter().zip(base).filter(|(c, _)| **c == Col::Sgn).map(|(_, b)| *b).sum();
        let tiny = 1e-9 * self.torque;
        match k {
            Kind::Stribeck if g(0) <= tiny => {
                Some("fitted Stribeck level is not positive: friction rising towards rest is no Stribeck effect")
            }
            Kind::CableAbove | Kind::CableBelow if g(0) <= tiny => {
                Some("fitted cable stiffness is not positive: a cable cannot push")
            }
            Kind::CableCubic if e.iter().rev().nth(1).copied().unwrap_or(0.0) <= tiny => {
                Some("fitted progressive stiffness is not positive: the element does not stiffen")
            }
            Kind::Dry | Kind::DryBand if g(0) <= tiny => {
                Some("fitted dry friction level is not positive: friction cannot drive the motion")
            }
            // a step logged at 50 Hz whose edge came 5 ms after where the cubic between its
            // samples puts it: the file's own model left 1.35× the floor and a 5.1 ms delay
            // took 82 % of it (null bench seed 777, case 130); the samples cannot say when
            // within the interval the edge came, so neither can they tell such a delay
            Kind::Delay if self.within_input_slack(g(0)) => Some(
                "fitted delay is within the time the input's samples leave open for its edges: this rate cannot tell \
                 it from when the edge came between two samples",
            ),
            Kind::Asymmetric if g(0).abs() >= c => {
                Some("fitted asymmetry exceeds the Coulomb level: friction would push the joint in one direction")
            }
            _ => None,
        }
    }
}

/// The file's weight `s` among `cols`, when the fits free it (a weight with `s ≠ 0`).
pub fn free_weight_s(cols: &[Col]) -> Option<f64> {
    cols.iter().find_map(|c| if let Col::SinSq(s) = c { Some(*s) } else { None }).filter(|s| *s != 0.0)
}

fn push_ripple(law: &mut Law, p: f64, s: Option<f64>, c: Option<f64>) {
    if let Some(r) = law.ripples.iter_mut().find(|r| r.0 == p) {
        if let Some(s) = s {
            r.1 = s;
        }
        if let Some(c) = c {
            r.2 = c;
        }
    } else {
        law.ripples.push((p, s.unwrap_or(0.0), c.unwrap_or(0.0)));
    }
}

/// The model's terms at `b` (the layout's term values), as "section.key".
pub fn refit_values(model: &ModelFile, lay: &Layout, b: &[f64]) -> Vec<(String, f64)> {
    let cols = &lay.cols;
    let v = |id| model.value(id);
    let mut out = Vec::new();
    let c = |want: Col| cols.iter().position(|x| *x == want).and_then(|k| b.get(k).copied());
    if let Some(j) = c(Col::Qdd) {
        out.push(("inertia.j".to_string(), j));
    }
    if let Some(a) = c(Col::QdAbsQd) {
        out.push(("friction.a".to_string(), a));
    }
    if let Some(bt) = c(Col::Qd) {
        if v(ParamId::FrictionB) != 0.0 || v(ParamId::SpringB) == 0.0 {
            out.push(("friction.b".into(), bt - v(ParamId::SpringB)));
        } else {
            out.push(("spring.b".into(), bt));
        }
    }
    if let Some(cc) = c(Col::Sgn) {
        let key = if v(ParamId::FrictionC) == 0.0 && v(ParamId::DryFrictionC) != 0.0 {
            "dry_friction.c"
        } else {
            "friction.c"
        };
        out.push((key.into(), cc));
    }
    if let Some(l) = c(Col::Stribeck(v(ParamId::StribeckSpeed))) {
        out.push(("stribeck.level".into(), l));
    }
    if let Some(dl) = c(Col::AbsSgn) {
        out.push(("asymmetric_friction.delta".into(), dl));
    }
    let per = v(ParamId::RipplePeriod);
    if let (Some(bs), Some(bc)) = (c(Col::RipSin(per)), c(Col::RipCos(per))) {
        out.push(("position_ripple.amplitude".into(), bs.hypot(bc)));
        out.push(("position_ripple.phase".into(), bc.atan2(bs)));
    }
    if let Some(kc) = c(Col::Cable { engage: v(ParamId::CableEngage), width: v(ParamId::CableWidth) }) {
        out.push(("cable_spring.k".into(), kc));
    }
    let ws = v(ParamId::WeightS);
    if let (Some(bs), Some(bc)) = (c(Col::SinSq(ws)), c(Col::CosSq(ws))) {
        out.push(("weight.amplitude".into(), bs.hypot(bc)));
        out.push(("weight.phi".into(), bc.atan2(bs)));
        if let Some(s) = lay.weight_s.and_then(|_| b.get(cols.len())) {
            out.push(("weight.s".into(), *s));
        }
    }
    let k = c(Col::Q);
    if let Some(k) = k {
        out.push(("spring.k".into(), k));
    }
    if let Some(cst) = c(Col::Const) {
        let k = k.unwrap_or(0.0);
        if v(ParamId::OffsetC0) != 0.0 || k == 0.0 {
            out.push(("offset.c0".into(), cst + k * v(ParamId::SpringQ0)));
        } else {
            out.push(("spring.q0".into(), -cst / k));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Kind::ALL`] holds exactly the kinds the vocabulary's terms map to, each under its own
    /// term, and every term is either fitted or has a reason.
    #[test]
    fn trajectory_kinds_are_the_vocabularys_terms() {
        let mut from_vocab: Vec<Kind> = Vocab::terms().filter_map(|v| Kind::of(v).ok()).flatten().copied().collect();
        let mut all = Kind::ALL.to_vec();
        from_vocab.sort();
        all.sort();
        assert_eq!(all, from_vocab);
        for k in Kind::ALL {
            assert!(Kind::of(k.effect()).is_ok_and(|ks| ks.contains(&k)), "{k:?}");
        }
        let not: Vec<&str> = Vocab::terms().filter(|&v| Kind::of(v).is_err()).map(Vocab::name).collect();
        assert_eq!(not, ["load_dependent_friction", "thermal_drift"]);
    }
}
