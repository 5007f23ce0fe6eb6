//! What the log determines: every identified parameter with its 95 % confidence interval and a
//! status, and for the ones the log does not pin, the test that would.
//!
//! - **determined**: fitted, its CI narrower than its value, not collinear with the other terms
//!   over the log's range;
//! - **weakly determined**: fitted, but the CI is wider than the value (the data cannot tell it
//!   from 0), or other terms explain its column over this log (variance inflation factor above
//!   [`VIF_COLLINEAR`]: only their combination is determined), or it came out negative where
//!   the physics wants it ≥ 0;
//! - **not excited**: the log holds nothing that moves it: no motion, no speed range, no
//!   reversals, no poses spread over the angle, no acceleration above the noise.
//!
//! Only determined parameters are written to the model; the others are listed with the test
//! that would pin them.

use std::fmt::Write as _;

/// Above this variance inflation factor a column is collinear with the others over the log
/// (the usual rule of thumb: 90 % of its variance explained by them).
pub const VIF_COLLINEAR: f64 = 10.0;

/// The acceleration must stand this far above its noise in the fit's band to excite J.
pub const ACC_EXCITATION: f64 = 3.0;

pub const TEST_FRICTION: &str =
    "constant-velocity plateaus at several speeds both ways (a speed sweep over the working range, trunk §3.2)";
pub const TEST_WEIGHT: &str = "hold the joint still at 5+ angles spread over its range (static poses, trunk §3.3)";
pub const TEST_INERTIA: &str =
    "move the joint back and forth with strong accelerations for several seconds, with friction and weight known \
     (trunk §3.4)";
pub const TEST_OFFSET: &str = "static poses, or motion both ways, with friction and weight known (trunk §3.3–3.4)";
pub const TEST_SPRING_K: &str =
    "hold the joint at angles on both sides of its rest with the torque measured (elastic joint, Fig. 5)";
pub const TEST_SPRING_JB: &str =
    "release the joint from an angle and let it oscillate freely, with K known from static poses (elastic joint, \
     Fig. 6)";
pub const TEST_TABLE: &str = "static poses over a grid of q and the other joints' angles (arm paper §3.2.2)";

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Determined,
    WeaklyDetermined,
    NotExcited,
}

impl Status {
    pub fn label(self) -> &'static str {
        match self {
            Status::Determined => "determined",
            Status::WeaklyDetermined => "weakly determined",
            Status::NotExcited => "not excited",
        }
    }
}

/// One parameter of the model TOML (section, key) and what the log says about it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ParamStatus {
    /// TOML section: friction, weight, inertia, offset, spring, gravity_table
    pub term: &'static str,
    /// TOML key (or a name for a term judged as a whole)
    pub param: &'static str,
    /// the fitted value, when there is one
    pub value: Option<f64>,
    /// its 95 % confidence interval, when the fit gives one
    pub ci95: Option<(f64, f64)>,
    pub status: Status,
    /// the reason for the status
    pub why: String,
    /// the test that would pin it (absent when determined)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub test: Option<&'static str>,
}

impl ParamStatus {
    pub fn name(&self) -> String {
        format!("{}.{}", self.term, self.param)
    }

    pub fn determined(&self) -> bool {
        self.status == Status::Determined
    }

    pub fn not_excited(term: &'static str, param: &'static str, why: impl Into<String>, test: &'static str) -> Self {
        ParamStatus {
            term,
            param,
            value: None,
            ci95: None,
            status: Status::NotExcited,
            why: why.into(),
            test: Some(test),
        }
    }

    /// A fitted value judged by its CI (and a collinearity already found): weakly determined
    /// when the interval is wider than the value or `collinear` names a reason, else determined.
    pub fn from_ci(
        term: &'static str,
        param: &'static str,
        value: f64,
        ci: (f64, f64),
        collinear: Option<String>,
        test: &'static str,
    ) -> Self {
        let (status, why) = if !(value.is_finite() && ci.0.is_finite() && ci.1.is_finite()) {
            (Status::WeaklyDetermined, "the fit gives no finite confidence interval".to_string())
        } else if let Some(c) = collinear {
            (Status::WeaklyDetermined, c)
        } else if ci.1 - ci.0 > value.abs() {
            (
                Status::WeaklyDetermined,
                format!(
                    "its 95 % CI [{:.4}, {:.4}] is wider than the value: the log cannot tell it from 0",
                    ci.0, ci.1
                ),
            )
        } else {
            (Status::Determined, format!("95 % CI [{:.4}, {:.4}]", ci.0, ci.1))
        };
        let test = (status != Status::Determined).then_some(test);
        ParamStatus { term, param, value: Some(value), ci95: Some(ci), status, why, test }
    }

    /// A coefficient that came out negative where the physics wants it ≥ 0 and was left out.
    pub fn negative(term: &'static str, param: &'static str, what: &str, test: &'static str) -> Self {
        ParamStatus {
            term,
            param,
            value: Some(0.0),
            ci95: None,
            status: Status::WeaklyDetermined,
            why: format!("came out negative ({what}); left out, and the other terms refitted without it"),
            test: Some(test),
        }
    }
}

/// Human table of the statuses: one line per parameter, grouped by status.
pub fn text(status: &[ParamStatus]) -> String {
    let mut s = String::new();
    for st in [Status::Determined, Status::WeaklyDetermined, Status::NotExcited] {
        let v: Vec<&ParamStatus> = status.iter().filter(|p| p.status == st).collect();
        if v.is_empty() {
            continue;
        }
        let _ = writeln!(s, "{}:", st.label());
        for p in v {
            let val = match (p.value, p.ci95) {
                (Some(v), Some((lo, hi))) => format!("{v:.4} [{lo:.4}, {hi:.4}]"),
                (Some(v), None) => format!("{v:.4}"),
                _ => "—".to_string(),
            };
            let _ = writeln!(s, "  {:<18} {:<28} {}", p.name(), val, p.why);
            if let Some(t) = p.test {
                let _ = writeln!(s, "  {:<18} {:<28} to pin it: {t}", "", "");
            }
        }
    }
    s
}
