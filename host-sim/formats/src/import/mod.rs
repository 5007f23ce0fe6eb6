//! Converters from the public real-joint data sets (`shared/data/real`) to the joint-log CSV
//! (spec §1), as a user would convert their own logger's files.
//!
//! - `dfki-pendulum`: `time, position, velocity, torque` of the DFKI simple pendulum (AK80-6
//!   motor's own torque estimate). The motor torque is the only torque: `u = torque`,
//!   `tau = 0`, so `d = u − tau` is the torque the model must explain.
//! - `jensen-free-swing`: `time_s_nominal, angle_deg` of a free-swinging pendulum (no torque):
//!   a trajectory-mode log, angle converted to rad. The time stamps are nominal (see the data
//!   set's README).
//! - `panda-gaz`: the Franka Panda exciting trajectory (`time_s, q1..q7, dq1..dq7, tau1..tau7`),
//!   one joint per log (`joint` 1..=7): `q, qd` of that joint, `u = tau_j` (link-side torque
//!   sensor), `tau = 0`, and the other joints' angles as `q_j<k>` columns.
//! - `dfki-double-pendulum`: the DFKI double pendulum's sys-id record (`time, pos_meas1/2,
//!   vel_meas1/2, tau_meas1/2, …`), one joint per log (`joint` 1 or 2): `q, qd` of that joint,
//!   `u = tau_meas` (the motor's current-based torque), `tau = 0`, and the other joint's angle
//!   as a `q_j<k>` column. A two-link arm: each joint's torque also depends on the other joint's
//!   angle and acceleration, which a single-joint model does not have.
//! - `ur5e-friction`: the UR5e factory friction table (one row per joint and speed, torque on
//!   the motor side). Each steady-state row becomes a stretch of constant velocity at the
//!   log rate, rows of equal |speed| as an out-and-back pair (+v, then −v over the same angles,
//!   which is what a speed sweep does), torque × `gear_ratio` to the joint side as `u`,
//!   `tau = 0`. No sample is invented beyond holding each measured value for `hold` s.
//!
//! Rows whose time does not increase (loggers repeat stale samples) are dropped and counted.

pub mod candump;
pub mod csv_map;
pub mod eds;
pub mod mcap;

use crate::log::JointLog;

/// The known formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    DfkiPendulum,
    DfkiDoublePendulum,
    JensenFreeSwing,
    PandaGaz,
    Ur5eFriction,
    /// any delimited file through a column map ([`csv_map`])
    Csv,
    /// a can-utils bus capture decoded through an EDS ([`candump`])
    Candump,
    /// a ROS 2 bag in MCAP ([`mcap`])
    Mcap,
}

impl Format {
    /// Every format with the name a command line or a script gives it.
    pub const NAMES: [(&'static str, Format); 8] = [
        ("csv", Format::Csv),
        ("candump", Format::Candump),
        ("mcap", Format::Mcap),
        ("dfki-pendulum", Format::DfkiPendulum),
        ("dfki-double-pendulum", Format::DfkiDoublePendulum),
        ("jensen-free-swing", Format::JensenFreeSwing),
        ("panda-gaz", Format::PandaGaz),
        ("ur5e-friction", Format::Ur5eFriction),
    ];
}

/// Options some formats need.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOpts {
    /// Panda: 1..=7; UR5e: 0..=5; DFKI double pendulum: 1..=2
    pub joint: Option<usize>,
    /// UR5e: motor-to-joint torque ratio
    pub gear_ratio: f64,
    /// UR5e: seconds each table row is held
    pub hold: f64,
    /// UR5e: samples per second of the generated log
    pub rate: f64,
    /// csv: the column map, delimiter and decimal mark
    pub csv: csv_map::CsvOpts,
}

impl Default for ImportOpts {
    fn default() -> Self {
        ImportOpts { joint: None, gear_ratio: 101.0, hold: 1.0, rate: 1000.0, csv: csv_map::CsvOpts::default() }
    }
}

/// A converted log and what the converter had to do to it.
#[derive(Debug)]
pub struct Imported {
    pub log: JointLog,
    pub notes: Vec<String>,
}

/// A CSV with a header, parsed to columns by name; errors name the line and column.
struct Table {
    names: Vec<String>,
    cols: Vec<Vec<f64>>,
}

impl Table {
    fn parse(text: &str, file: &str) -> Result<Table, String> {
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines.next().ok_or_else(|| format!("{file}: empty file"))?;
        let names: Vec<String> = header.split(',').map(|s| s.trim().trim_matches('"').to_string()).collect();
        let mut cols = vec![Vec::new(); names.len()];
        for (ln, line) in lines {
            let cells: Vec<&str> = line.split(',').collect();
            if cells.len() != names.len() {
                return Err(format!("{file}: line {}: {} cells, the header has {}", ln + 1, cells.len(), names.len()));
            }
            for ((c, cell), name) in cols.iter_mut().zip(cells).zip(&names) {
                let v: f64 = cell.trim().parse().map_err(|_| {
                    format!("{file}: line {}, column `{name}`: `{}` is not a number", ln + 1, cell.trim())
                })?;
                if !v.is_finite() {
                    return Err(format!("{file}: line {}, column `{name}`: not finite", ln + 1));
                }
                c.push(v);
            }
        }
        Ok(Table { names, cols })
    }

    fn col(&self, name: &str, file: &str) -> Result<&[f64], String> {
        self.names
            .iter()
            .position(|n| n == name)
            .and_then(|i| self.cols.get(i))
            .map(Vec::as_slice)
            .ok_or_else(|| format!("{file}: line 1: column `{name}` is missing (found: {})", self.names.join(", ")))
    }
}

/// Keeps the rows whose time strictly increases; returns the kept indices and the count dropped.
fn increasing(t: &[f64]) -> (Vec<usize>, usize) {
    let mut keep = Vec::with_capacity(t.len());
    let mut last = f64::NEG_INFINITY;
    for (i, &x) in t.iter().enumerate() {
        if x > last {
            keep.push(i);
            last = x;
        }
    }
    let dropped = t.len() - keep.len();
    (keep, dropped)
}

fn pick(v: &[f64], idx: &[usize]) -> Vec<f64> {
    idx.iter().filter_map(|&i| v.get(i).copied()).collect()
}

/// Converts the text of one upstream file. Bus captures and bags have their own readers
/// ([`candump::decode`] needs the node's EDS, [`mcap::convert`] reads bytes).
pub fn convert(format: Format, text: &str, file: &str, o: &ImportOpts) -> Result<Imported, String> {
    match format {
        Format::Csv => {
            let (log, notes) = csv_map::convert(text, file, &o.csv)?;
            return Ok(Imported { log, notes });
        }
        Format::Candump => return Err(format!("{file}: a bus capture is decoded through an EDS (candump::decode)")),
        Format::Mcap => return Err(format!("{file}: an MCAP bag is binary (mcap::convert)")),
        _ => {}
    }
    let tab = Table::parse(text, file)?;
    let mut notes = Vec::new();
    let log = match format {
        Format::DfkiPendulum => {
            let (idx, dropped) = increasing(tab.col("time", file)?);
            if dropped > 0 {
                notes.push(format!("dropped {dropped} rows whose time did not increase"));
            }
            let u = pick(tab.col("torque", file)?, &idx);
            JointLog {
                t: pick(tab.col("time", file)?, &idx),
                q: pick(tab.col("position", file)?, &idx),
                qd: Some(pick(tab.col("velocity", file)?, &idx)),
                tau: Some(vec![0.0; u.len()]),
                u: Some(u),
                ..JointLog::default()
            }
        }
        Format::DfkiDoublePendulum => {
            let j = o.joint.filter(|j| (1..=2).contains(j)).ok_or("dfki-double-pendulum needs --joint 1..=2")?;
            let (idx, dropped) = increasing(tab.col("time", file)?);
            if dropped > 0 {
                notes.push(format!("dropped {dropped} rows whose time did not increase"));
            }
            let k = 3 - j;
            let u = pick(tab.col(&format!("tau_meas{j}"), file)?, &idx);
            JointLog {
                t: pick(tab.col("time", file)?, &idx),
                q: pick(tab.col(&format!("pos_meas{j}"), file)?, &idx),
                qd: Some(pick(tab.col(&format!("vel_meas{j}"), file)?, &idx)),
                tau: Some(vec![0.0; u.len()]),
                u: Some(u),
                others: vec![(format!("q_j{k}"), pick(tab.col(&format!("pos_meas{k}"), file)?, &idx))],
                ..JointLog::default()
            }
        }
        Format::JensenFreeSwing => {
            let (idx, dropped) = increasing(tab.col("time_s_nominal", file)?);
            if dropped > 0 {
                notes.push(format!("dropped {dropped} rows whose time did not increase"));
            }
            let deg = tab.col("angle_deg", file)?;
            JointLog {
                t: pick(tab.col("time_s_nominal", file)?, &idx),
                q: idx.iter().filter_map(|&i| deg.get(i)).map(|d| d.to_radians()).collect(),
                ..JointLog::default()
            }
        }
        Format::PandaGaz => {
            let j = o.joint.filter(|j| (1..=7).contains(j)).ok_or("panda-gaz needs --joint 1..=7")?;
            let (idx, dropped) = increasing(tab.col("time_s", file)?);
            if dropped > 0 {
                notes.push(format!("dropped {dropped} rows whose time did not increase (stale samples)"));
            }
            let u = pick(tab.col(&format!("tau{j}_Nm"), file)?, &idx);
            let mut others = Vec::new();
            for k in (1..=7).filter(|&k| k != j) {
                others.push((format!("q_j{k}"), pick(tab.col(&format!("q{k}_rad"), file)?, &idx)));
            }
            JointLog {
                t: pick(tab.col("time_s", file)?, &idx),
                q: pick(tab.col(&format!("q{j}_rad"), file)?, &idx),
                qd: Some(pick(tab.col(&format!("dq{j}_rad_s"), file)?, &idx)),
                tau: Some(vec![0.0; u.len()]),
                u: Some(u),
                others,
                ..JointLog::default()
            }
        }
        Format::Csv | Format::Candump | Format::Mcap => return Err(format!("{file}: not a data-set format")),
        Format::Ur5eFriction => {
            let j = o.joint.filter(|j| *j <= 5).ok_or("ur5e-friction needs --joint 0..=5")?;
            if !(o.hold > 0.0 && o.rate > 0.0 && o.gear_ratio > 0.0 && o.hold * o.rate >= 10.0) {
                return Err("ur5e-friction: --hold, --rate and --gear-ratio must be > 0 (and hold·rate ≥ 10)".into());
            }
            let joints = tab.col("joint", file)?;
            let vel = tab.col("ang_vel_rad_s", file)?;
            let fr = tab.col("friction_torque_motor_side_Nm", file)?;
            let rows: Vec<(f64, f64)> = joints
                .iter()
                .zip(vel.iter().zip(fr))
                .filter(|(joint, _)| joint.round() as usize == j)
                .map(|(_, (v, f))| (*v, f * o.gear_ratio))
                .collect();
            if rows.is_empty() {
                return Err(format!("{file}: no rows for joint {j}"));
            }
            // Out-and-back pairs by |speed|, slowest first.
            let mut speeds: Vec<f64> = rows.iter().map(|r| r.0.abs()).collect();
            speeds.sort_by(f64::total_cmp);
            speeds.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            let n_hold = (o.hold * o.rate).round() as usize;
            let dt = 1.0 / o.rate;
            let mut log =
                JointLog { qd: Some(Vec::new()), u: Some(Vec::new()), tau: Some(Vec::new()), ..JointLog::default() };
            let mut q = 0.0;
            for s in speeds {
                for sign in [1.0, -1.0] {
                    let Some(&(v, f)) = rows.iter().find(|r| (r.0 - sign * s).abs() < 1e-9) else {
                        notes.push(format!("speed {:+} rad/s has no row; left out", sign * s));
                        continue;
                    };
                    for _ in 0..n_hold {
                        log.t.push(log.t.len() as f64 * dt);
                        log.q.push(q);
                        if let (Some(a), Some(b), Some(c)) = (log.qd.as_mut(), log.u.as_mut(), log.tau.as_mut()) {
                            a.push(v);
                            b.push(f);
                            c.push(0.0);
                        }
                        q += v * dt;
                    }
                }
            }
            notes.push(format!(
                "{} table rows held {} s each at {} Hz; torque × {} to the joint side",
                rows.len(),
                o.hold,
                o.rate,
                o.gear_ratio
            ));
            log
        }
    };
    if log.t.is_empty() {
        return Err(format!("{file}: no data rows"));
    }
    Ok(Imported { log, notes })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dfki_rows_map_to_spec_columns_and_repeated_times_are_dropped() {
        let text =
            "time,position,velocity,torque\n0,0.1,0.2,0.3\n0.01,0.2,0.3,0.4\n0.01,0.2,0.3,0.4\n0.02,0.3,0.4,0.5\n";
        let im = convert(Format::DfkiPendulum, text, "x.csv", &ImportOpts::default()).unwrap();
        assert_eq!(im.log.t, vec![0.0, 0.01, 0.02]);
        assert_eq!(im.log.u.as_deref(), Some(&[0.3, 0.4, 0.5][..]));
        assert_eq!(im.log.tau.as_deref(), Some(&[0.0, 0.0, 0.0][..]));
        assert!(im.notes[0].contains("dropped 1"));
    }

    #[test]
    fn bad_cell_is_named() {
        let text = "time,position,velocity,torque\n0,0.1,x,0.3\n";
        let e = convert(Format::DfkiPendulum, text, "x.csv", &ImportOpts::default()).unwrap_err();
        assert!(e.contains("line 2") && e.contains("`velocity`"), "{e}");
        let e = convert(Format::DfkiPendulum, "time,position\n0,1\n", "x.csv", &ImportOpts::default()).unwrap_err();
        assert!(e.contains("line 1") && e.contains("is missing"), "{e}");
    }

    #[test]
    fn double_pendulum_joint_takes_its_columns_and_the_other_angle() {
        let text = "time,pos_meas1,pos_meas2,vel_meas1,vel_meas2,tau_meas1,tau_meas2\n0,0.1,0.2,1,2,0.5,0.6\n0.002,0.11,0.22,1,2,0.4,0.7\n";
        let o = ImportOpts { joint: Some(2), ..ImportOpts::default() };
        let im = convert(Format::DfkiDoublePendulum, text, "d.csv", &o).unwrap();
        assert_eq!(im.log.q, vec![0.2, 0.22]);
        assert_eq!(im.log.u.as_deref(), Some(&[0.6, 0.7][..]));
        assert_eq!(im.log.others, vec![("q_j1".to_string(), vec![0.1, 0.11])]);
        let o = ImportOpts { joint: Some(3), ..ImportOpts::default() };
        assert!(convert(Format::DfkiDoublePendulum, text, "d.csv", &o).unwrap_err().contains("1..=2"));
    }

    #[test]
    fn ur5e_rows_become_out_and_back_plateaus() {
        let text =
            "joint,ang_vel_rad_s,motor_voltage_V,motor_current_A,temperature_C,friction_torque_motor_side_Nm,Km\n\
                    0,-1.0,0,0,40,-0.1,0\n0,1.0,0,0,40,0.1,0\n1,1.0,0,0,40,0.5,0\n";
        let o = ImportOpts { joint: Some(0), hold: 0.1, rate: 100.0, gear_ratio: 100.0, ..ImportOpts::default() };
        let im = convert(Format::Ur5eFriction, text, "t.csv", &o).unwrap();
        assert_eq!(im.log.len(), 20);
        let u = im.log.u.as_ref().unwrap();
        assert!((u[0] - 10.0).abs() < 1e-9 && (u[19] + 10.0).abs() < 1e-9);
        assert!(im.log.q[19].abs() < 0.011, "back where it started: {}", im.log.q[19]);
    }
}
