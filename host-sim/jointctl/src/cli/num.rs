//! Numeric options checked like file values: every number a subcommand takes goes through a
//! clap value parser that refuses NaN, infinities, zero or negative values where a positive
//! quantity is meant and absurd sizes, with the option and the allowed range named
//! (`invalid value 'nan' for '--seconds <S>': allowed: 0 < x ≤ 86400 s`). Limits that join two
//! options (samples = rate × seconds) are [`budget`] checks at the start of a run, before any
//! file is read. `docs/outputs.md` lists every option with its range; the test
//! `tests/numeric_args.rs` checks the list against `jointctl --help`.

use joint_core::params::ParamId;

/// The most samples one log may hold (rows × columns of f64 in memory, then CSV on disk: a
/// 10 M-row torque log is ≈ 0.5 GB in memory and ≈ 1 GB of text).
pub const MAX_LOG_SAMPLES: f64 = 1.0e7;

/// The most plant integration steps one `simulate` run may take (≈ 4 min at ~0.2 µs a step).
pub const MAX_PLANT_STEPS: f64 = 1.0e9;

/// Classic CAN bitrates (ISO 11898: 10 kbit/s … 1 Mbit/s), bit/s.
pub const CAN_BITRATE: (u64, u64) = (10_000, 1_000_000);

/// CAN FD data-phase bitrates (at least the nominal rate; 8 Mbit/s is the fastest transceivers
/// are specified for), bit/s.
pub const CAN_FD_DATA_BITRATE: (u64, u64) = (10_000, 8_000_000);

/// Node ids a CANopen node may have.
pub fn node_id() -> impl Fn(&str) -> Result<u8, String> + Clone + Send + Sync + 'static {
    int(1, 127)
}

/// A count in `lo..=hi`.
pub fn count(lo: u64, hi: u64) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    int(lo, hi)
}

/// A bitrate in `range`, bit/s.
pub fn bitrate(range: (u64, u64)) -> impl Fn(&str) -> Result<u32, String> + Clone + Send + Sync + 'static {
    int(range.0, range.1)
}

/// A whole number in `lo..=hi` (`T` holds every value of the range).
pub fn int<T: TryFrom<u64> + Clone + Send + Sync + 'static>(
    lo: u64,
    hi: u64,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |s: &str| {
        let v: u64 = s.trim().parse().map_err(|_| format!("not a whole number; allowed: {lo}..={hi}"))?;
        if !(lo..=hi).contains(&v) {
            return Err(format!("outside the allowed range: {lo}..={hi}"));
        }
        T::try_from(v).map_err(|_| format!("outside the allowed range: {lo}..={hi}"))
    }
}

/// A finite real number `lo < x ≤ hi` (`lo_open`) or `lo ≤ x ≤ hi`, in `unit`.
#[derive(Clone, Copy, Debug)]
pub struct Real {
    lo: f64,
    hi: f64,
    lo_open: bool,
    unit: &'static str,
}

impl Real {
    /// The allowed range as the error message and docs write it.
    pub fn allowed(&self) -> String {
        let unit = if self.unit.is_empty() { String::new() } else { format!(" {}", self.unit) };
        format!("{} {} x ≤ {}{unit}", short(self.lo), if self.lo_open { "<" } else { "≤" }, short(self.hi))
    }

    pub fn check(&self, s: &str) -> Result<f64, String> {
        let v: f64 = s.trim().parse().map_err(|_| format!("not a number; allowed: {}", self.allowed()))?;
        let inside = v.is_finite() && v <= self.hi && (v > self.lo || (!self.lo_open && v == self.lo));
        if !inside {
            return Err(format!("outside the allowed range: {}", self.allowed()));
        }
        Ok(v)
    }

    /// The clap value parser.
    pub fn parser(self) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
        move |s: &str| self.check(s)
    }
}

fn short(x: f64) -> String {
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// `0 < x ≤ hi`.
pub fn positive(hi: f64, unit: &'static str) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    Real { lo: 0.0, hi, lo_open: true, unit }.parser()
}

/// `lo ≤ x ≤ hi`.
pub fn within(
    lo: f64,
    hi: f64,
    unit: &'static str,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    Real { lo, hi, lo_open: false, unit }.parser()
}

/// The range the core's parameter table gives `id` (the joint would refuse anything else).
pub fn param(id: ParamId) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    let d = id.desc();
    let unit = if d.unit == "1" { "" } else { d.unit };
    Real { lo: f64::from(d.min), hi: f64::from(d.max), lo_open: false, unit }.parser()
}

/// A product of options that must stay under a budget: refused before any work, naming the
/// options, their values and the budget.
pub fn budget(what: &str, terms: &[(&str, f64)], max: f64) -> anyhow::Result<()> {
    let total: f64 = terms.iter().map(|(_, v)| v).product();
    if total > max {
        let named: Vec<String> = terms.iter().map(|(n, v)| format!("{n} {v}")).collect();
        anyhow::bail!(
            "{} gives {total:.3e} {what}, more than the {max:.0e} one run may take: lower one of them",
            named.join(" × ")
        );
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn reals_refuse_non_finite_and_out_of_range_values_and_say_the_range() {
        let p = Real { lo: 0.0, hi: 3600.0, lo_open: true, unit: "s" };
        for bad in ["nan", "NaN", "inf", "-inf", "0", "-1", "3600.5", "1e400", "x", ""] {
            let e = p.check(bad).unwrap_err();
            assert!(e.contains("0 < x ≤ 3600 s"), "{bad}: {e}");
        }
        assert_eq!(p.check("3600").unwrap(), 3600.0);
        assert_eq!(p.check(" 1e-3 ").unwrap(), 1e-3);
        let q = Real { lo: 0.0, hi: 1.0, lo_open: false, unit: "" };
        assert_eq!(q.check("0").unwrap(), 0.0);
        assert_eq!(q.allowed(), "0 ≤ x ≤ 1");
    }

    #[test]
    fn budgets_name_the_options() {
        budget("samples", &[("--rate", 1000.0), ("--seconds", 10.0)], 1e7).unwrap();
        let e = budget("samples", &[("--rate", 1000.0), ("--seconds", 1e5)], 1e7).unwrap_err().to_string();
        assert!(e.contains("--rate 1000 × --seconds 100000") && e.contains("1e7"), "{e}");
    }

    #[test]
    fn whole_numbers_say_the_range_for_every_refusal() {
        let p = node_id();
        for bad in ["0", "128", "-1", "1.5", "x", "", "99999999999999999999"] {
            let e = p(bad).unwrap_err();
            assert!(e.contains("1..=127"), "{bad}: {e}");
        }
        assert_eq!(p("127").unwrap(), 127u8);
        assert_eq!(bitrate(CAN_BITRATE)(" 1000000").unwrap(), 1_000_000u32);
    }
}
