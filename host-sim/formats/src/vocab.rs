//! The effect vocabulary (spec §3), declared once.
//!
//! Every report, the diagnosis's candidates, the closed-loop workflow and the help text name
//! effects through [`Effect`], so a misspelt or forgotten one is a compile error, not a string
//! that silently matches nothing. Whether the joint compensates an effect is not written here:
//! it follows from the core's parameter table (an effect whose TOML section has parameters
//! there is a term the joint runs), so adding a term to that table makes it compensable
//! everywhere at once. What is written here is why the others cannot be.

use joint_core::params;

macro_rules! vocabulary {
    ($($v:ident => $name:literal, $section:expr, $meaning:literal, $not:expr;)*) => {
        /// One entry of the effect vocabulary.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Effect {
            $($v,)*
        }

        impl Effect {
            /// Every entry, in the spec's order.
            pub const ALL: &'static [Effect] = &[$(Effect::$v,)*];

            /// The name reports use (`asymmetric_friction`).
            pub const fn name(self) -> &'static str {
                match self {
                    $(Effect::$v => $name,)*
                }
            }

            /// The model/plant TOML section that carries the effect as a term, if it is one
            /// (`presliding_hysteresis` is emitted as `[presliding]`); verdicts such as
            /// `parameters` or `none` have none.
            pub const fn section(self) -> Option<&'static str> {
                match self {
                    $(Effect::$v => $section,)*
                }
            }

            /// What the effect means (the spec's table).
            pub const fn meaning(self) -> &'static str {
                match self {
                    $(Effect::$v => $meaning,)*
                }
            }

            /// Why the joint cannot compensate this term by feed-forward (for a term it
            /// cannot; see [`Effect::compensable`]).
            const fn why_not_declared(self) -> Option<&'static str> {
                match self {
                    $(Effect::$v => $not,)*
                }
            }
        }
    };
}

vocabulary! {
    Parameters => "parameters", None,
        "the model's own terms are right but their values are off; refitting them closes the gap", None;
    Stribeck => "stribeck", Some("stribeck"),
        "friction above the Coulomb level at low speed, falling off with speed", None;
    AsymmetricFriction => "asymmetric_friction", Some("asymmetric_friction"),
        "friction level depends on the direction of motion", None;
    LoadDependentFriction => "load_dependent_friction", Some("load_dependent_friction"),
        "friction grows with the transmitted torque", None;
    ThermalDrift => "thermal_drift", Some("thermal_drift"),
        "friction changes with temperature (or, without `temp`, over time)",
        Some("the friction scale follows the temperature; the control step gets no temperature input, and a time-based guess would be wrong after every pause");
    PositionRipple => "position_ripple", Some("position_ripple"),
        "torque periodic in position with a short period (gear mesh, cogging, wave generator)", None;
    CableSpring => "cable_spring", Some("cable_spring"),
        "an extra smooth, position-dependent torque (harness, cable, padding)", None;
    Backlash => "backlash", Some("backlash"),
        "a dead zone in the transmission or elastic element",
        Some("a dead zone in the transmission is structure, not an additive torque: feed-forward cannot remove it (it needs a backlash inverse or an output-side encoder)");
    Delay => "delay", Some("delay"),
        "a time shift between actuation and measurement",
        Some("a sensing/actuation delay is structure, not an additive torque: it can only be reduced (faster loop, less filtering) or lowered in gain (a smaller fraction), not compensated by a model term");
    DryFriction => "dry_friction", Some("dry_friction"),
        "a Coulomb torque that the model lacks entirely", None;
    PreslidingHysteresis => "presliding_hysteresis", Some("presliding"),
        "friction builds up over a small travelled angle after each reversal (Dahl/LuGre pre-sliding) instead of jumping with sign(q̇); emitted as `[presliding]`", None;
    InitialState => "initial_state", None,
        "trajectory mode: the response starts from a state other than the assumed one", None;
    None => "none", None, "nothing beyond noise", None;
    Unexplained => "unexplained", None,
        "a gap above the noise floor that no entry of this vocabulary explains", None;
}

impl Effect {
    /// The entry of this name.
    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::ALL.iter().copied().find(|e| e.name() == name)
    }

    /// The entry whose term is written as TOML section `section`.
    pub fn from_section(section: &str) -> Option<Effect> {
        Effect::ALL.iter().copied().find(|e| e.section() == Some(section))
    }

    /// A term the joint runs: its section has parameters in the core's table.
    pub fn compensable(self) -> bool {
        self.section().is_some_and(|s| params::sections().any(|t| t == s))
    }

    /// For a term the joint cannot run, why not (`None` for a term it runs and for verdicts
    /// that are no term).
    pub fn why_not_compensable(self) -> Option<&'static str> {
        if self.section().is_none() || self.compensable() {
            return None;
        }
        Some(self.why_not_declared().unwrap_or("the joint's parameter table has no term for it"))
    }

    /// The effect terms of the vocabulary (those with a section), in the spec's order.
    pub fn terms() -> impl Iterator<Item = Effect> {
        Effect::ALL.iter().copied().filter(|e| e.section().is_some())
    }
}

impl std::fmt::Display for Effect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_sections_round_trip_and_are_unique() {
        for &e in Effect::ALL {
            assert_eq!(Effect::from_name(e.name()), Some(e));
            if let Some(s) = e.section() {
                assert_eq!(Effect::from_section(s), Some(e), "{s} names two effects");
            }
        }
        assert_eq!(Effect::ALL.len(), 14, "the spec's vocabulary has 14 entries");
    }

    #[test]
    fn the_joint_compensates_exactly_the_terms_its_table_has() {
        let runs: Vec<&str> = Effect::terms().filter(|e| e.compensable()).map(Effect::name).collect();
        assert_eq!(
            runs,
            [
                "stribeck",
                "asymmetric_friction",
                "load_dependent_friction",
                "position_ripple",
                "cable_spring",
                "dry_friction",
                "presliding_hysteresis"
            ]
        );
        for e in Effect::terms().filter(|e| !e.compensable()) {
            assert!(e.why_not_compensable().is_some(), "{e} has no reason");
            assert!(!e.why_not_declared().unwrap_or("").is_empty());
        }
        // a declared reason on a term the table runs would be a stale sentence
        for e in Effect::terms().filter(|e| e.compensable()) {
            assert_eq!(e.why_not_declared(), None, "{e} is compensated but says why not");
        }
    }
}
