//! The joint log (spec §1): a CSV with one header row and one row per sample.
//!
//! The reader is strict because every later tool (identification, diagnosis) trusts what it
//! returns: a missing required column, a cell that is empty, non-numeric, NaN or infinite, a
//! ragged row or a time that does not strictly increase is refused with the file, the line
//! number (1-based, the header is line 1) and the column named, and nothing is returned on
//! error. Harmless variants are accepted: any column order, CRLF line ends, a UTF-8 BOM,
//! spaces around cells, double-quoted header names, blank lines at the end of the file.
//! Unknown columns are kept aside (listed by name, their cells not interpreted) — never an error.
//!
//! Storage is column-oriented (one `Vec<f64>` per column) and the parser works on one byte
//! buffer without per-cell allocation, so a million-row log reads in a fraction of a second.

use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// The columns the spec names; everything else that does not start with `q_` is unknown.
const KNOWN: [&str; 7] = ["t", "q", "qd", "qdd", "u", "tau", "temp"];

/// How a log can be used (spec §1 "Two modes").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LogMode {
    /// `u` and `tau` present: the model predicts `d = u − tau` sample by sample.
    Torque,
    /// no torques: the model is integrated and compared with the logged `q(t)`.
    Trajectory,
}

/// A joint log held column by column. `t` and `q` always have the same length as every other
/// present column.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointLog {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Option<Vec<f64>>,
    pub qdd: Option<Vec<f64>>,
    pub u: Option<Vec<f64>>,
    pub tau: Option<Vec<f64>>,
    pub temp: Option<Vec<f64>>,
    /// `q_<name>` columns (angles of other joints), full column name and values, in file order.
    pub others: Vec<(String, Vec<f64>)>,
    /// Names of columns the spec does not know, in file order; their cells are not read.
    pub unknown: Vec<String>,
}

/// Why a log was refused. `line` is the 1-based line of the file (header = 1).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LogError {
    #[error("{file}: cannot read: {msg}")]
    Io { file: String, msg: String },
    #[error("{file}: line {line}: not UTF-8 text")]
    NotUtf8 { file: String, line: usize },
    #[error("{file}: the file is empty (a header row with at least `t` and `q` is required)")]
    Empty { file: String },
    #[error("{file}: line 1: required column `{column}` is missing")]
    MissingColumn { file: String, column: &'static str },
    #[error("{file}: line 1: column `{column}` appears twice")]
    DuplicateColumn { file: String, column: String },
    #[error("{file}: line 1: column {index} has an empty name")]
    EmptyHeader { file: String, index: usize },
    #[error("{file}: line {line}: {found} cells, the header has {expected} columns")]
    Ragged { file: String, line: usize, found: usize, expected: usize },
    #[error("{file}: line {line}, column `{column}`: empty cell")]
    EmptyCell { file: String, line: usize, column: String },
    #[error("{file}: line {line}, column `{column}`: `{cell}` is not a number")]
    NotNumeric { file: String, line: usize, column: String, cell: String },
    #[error("{file}: line {line}, column `{column}`: `{cell}` is not finite (NaN/inf refused)")]
    NotFinite { file: String, line: usize, column: String, cell: String },
    #[error("{file}: line {line}, column `t`: time {t} does not increase (previous sample {prev})")]
    TimeNotIncreasing { file: String, line: usize, t: f64, prev: f64 },
    #[error("{file}: no data rows after the header")]
    NoRows { file: String },
}

/// Where a parsed column goes.
#[derive(Clone, Copy)]
enum Slot {
    Known(usize), // index into KNOWN
    Other(usize), // index into others
    Skip,
}

impl JointLog {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn mode(&self) -> LogMode {
        if self.u.is_some() && self.tau.is_some() {
            LogMode::Torque
        } else {
            LogMode::Trajectory
        }
    }

    /// Values of a `q_<name>` column by its full name.
    pub fn other(&self, column: &str) -> Option<&[f64]> {
        self.others.iter().find(|(n, _)| n == column).map(|(_, v)| v.as_slice())
    }

    /// Reads and validates a log file. `Err` carries the file, line and column; no partial data.
    pub fn read_file(path: &Path) -> Result<JointLog, LogError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| LogError::Io { file: file.clone(), msg: e.to_string() })?;
        Self::parse(&bytes, &file)
    }

    /// Parses log text; `file` is only used in error messages.
    pub fn parse(bytes: &[u8], file: &str) -> Result<JointLog, LogError> {
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        let text = match std::str::from_utf8(bytes) {
            Ok(s) => s,
            Err(e) => {
                let line = 1 + bytes.iter().take(e.valid_up_to()).filter(|&&b| b == b'\n').count();
                return Err(LogError::NotUtf8 { file: file.to_string(), line });
            }
        };
        let (header, rest) = match text.find('\n') {
            Some(p) => (text.get(..p).unwrap_or(""), text.get(p + 1..).unwrap_or("")),
            None => (text, ""),
        };
        let header = header.strip_suffix('\r').unwrap_or(header);
        if header.trim().is_empty() {
            return Err(LogError::Empty { file: file.to_string() });
        }
        let names: Vec<String> = header
            .split(',')
            .map(|c| {
                let c = c.trim();
                c.strip_prefix('"').and_then(|c| c.strip_suffix('"')).unwrap_or(c).trim().to_string()
            })
            .collect();
        let mut log = JointLog::default();
        let mut slots = Vec::with_capacity(names.len());
        let mut known_present = [false; KNOWN.len()];
        for (i, name) in names.iter().enumerate() {
            if name.is_empty() {
                return Err(LogError::EmptyHeader { file: file.to_string(), index: i + 1 });
            }
            if names.iter().take(i).any(|n| n == name) {
                return Err(LogError::DuplicateColumn { file: file.to_string(), column: name.clone() });
            }
            if let Some(k) = KNOWN.iter().position(|k| k == name) {
                if let Some(f) = known_present.get_mut(k) {
                    *f = true;
                }
                slots.push(Slot::Known(k));
            } else if name.len() > 2 && name.starts_with("q_") {
                slots.push(Slot::Other(log.others.len()));
                log.others.push((name.clone(), Vec::new()));
            } else {
                slots.push(Slot::Skip);
                log.unknown.push(name.clone());
            }
        }
        for (k, req) in [(0usize, "t"), (1, "q")] {
            if !known_present.get(k).copied().unwrap_or(false) {
                return Err(LogError::MissingColumn { file: file.to_string(), column: req });
            }
        }
        // Parse into plain vectors first; Option wrappers are set at the end so that nothing
        // half-filled ever escapes.
        let layout = Layout { file, names: &names, slots: &slots, known_present, n_others: log.others.len() };
        let rows = layout.rows_parallel(rest).map_or_else(|| layout.rows(rest, 1), Ok)?;
        for ((_, v), parsed) in log.others.iter_mut().zip(rows.others) {
            *v = parsed;
        }
        let known = rows.known;
        let [t, q, qd, qdd, u, tau, temp] = known;
        if t.is_empty() {
            return Err(LogError::NoRows { file: file.to_string() });
        }
        let opt = |present: bool, v: Vec<f64>| if present { Some(v) } else { None };
        log.t = t;
        log.q = q;
        log.qd = opt(known_present[2], qd);
        log.qdd = opt(known_present[3], qdd);
        log.u = opt(known_present[4], u);
        log.tau = opt(known_present[5], tau);
        log.temp = opt(known_present[6], temp);
        Ok(log)
    }

    /// Column names in the order [`write_csv`](Self::write_csv) writes them.
    pub fn column_names(&self) -> Vec<&str> {
        let mut v = vec!["t", "q"];
        for (name, col) in [("qd", &self.qd), ("qdd", &self.qdd), ("u", &self.u), ("tau", &self.tau), ("temp", &self.temp)] {
            if col.is_some() {
                v.push(name);
            }
        }
        v.extend(self.others.iter().map(|(n, _)| n.as_str()));
        v
    }

    /// Writes the log as CSV (LF line ends, shortest round-trip number format, so the same
    /// data always gives the same bytes and reading it back gives the same f64 values).
    /// Unknown columns are not written: their cells were never read.
    pub fn write_csv<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        let mut cols: Vec<&[f64]> = vec![&self.t, &self.q];
        for c in [&self.qd, &self.qdd, &self.u, &self.tau, &self.temp].into_iter().flatten() {
            cols.push(c);
        }
        cols.extend(self.others.iter().map(|(_, v)| v.as_slice()));
        let mut buf = String::with_capacity(1 << 16);
        buf.push_str(&self.column_names().join(","));
        buf.push('\n');
        for i in 0..self.len() {
            for (j, c) in cols.iter().enumerate() {
                if j > 0 {
                    buf.push(',');
                }
                push_num(&mut buf, c.get(i).copied().unwrap_or(f64::NAN));
            }
            buf.push('\n');
            if buf.len() > (1 << 16) - 512 {
                w.write_all(buf.as_bytes())?;
                buf.clear();
            }
        }
        w.write_all(buf.as_bytes())
    }

    /// Writes the log to `path` through a temporary file in the same directory and a rename,
    /// so a failed run never leaves a half-written log behind.
    pub fn write_file(&self, path: &Path) -> std::io::Result<()> {
        write_atomic(path, |f| self.write_csv(f))
    }
}

/// What the header fixed: where each cell goes. Shared by the one- and two-thread row parsers.
struct Layout<'a> {
    file: &'a str,
    names: &'a [String],
    slots: &'a [Slot],
    known_present: [bool; KNOWN.len()],
    n_others: usize,
}

/// Parsed data rows: known columns by KNOWN index, `q_` columns in header order.
struct Rows {
    known: [Vec<f64>; KNOWN.len()],
    others: Vec<Vec<f64>>,
    /// first line of a run of blank lines at the end of the text parsed
    pending_blank: Option<usize>,
}

impl Layout<'_> {
    /// Parses the data rows in `text`; `header_line` is the line number just before its first
    /// line (1 for the whole body after the header), so errors name the file's own line.
    fn rows(&self, text: &str, header_line: usize) -> Result<Rows, LogError> {
        let file = self.file;
        let names = self.names;
        let mut known: [Vec<f64>; KNOWN.len()] = Default::default();
        let mut others: Vec<Vec<f64>> = vec![Vec::new(); self.n_others];
        let est_rows = text.len() / (names.len() * 8).max(1);
        for (k, present) in self.known_present.iter().enumerate() {
            if *present {
                if let Some(v) = known.get_mut(k) {
                    v.reserve(est_rows);
                }
            }
        }
        for v in others.iter_mut() {
            v.reserve(est_rows);
        }
        let mut line_no = header_line;
        let mut pending_blank: Option<usize> = None;
        for line in text.split('\n') {
            let line = line.strip_suffix('\r').unwrap_or(line);
            line_no += 1;
            if line.trim().is_empty() {
                pending_blank.get_or_insert(line_no);
                continue;
            }
            if let Some(blank) = pending_blank {
                // A blank line followed by data: the file was cut or glued together.
                return Err(LogError::Ragged { file: file.to_string(), line: blank, found: 0, expected: names.len() });
            }
            let mut n_cells = 0usize;
            for (col, cell) in line.split(',').enumerate() {
                n_cells += 1;
                let Some(slot) = self.slots.get(col) else { continue };
                let target = match *slot {
                    Slot::Skip => continue,
                    Slot::Known(k) => known.get_mut(k),
                    Slot::Other(o) => others.get_mut(o),
                };
                let cell = cell.trim();
                let name = || names.get(col).cloned().unwrap_or_default();
                if cell.is_empty() {
                    return Err(LogError::EmptyCell { file: file.to_string(), line: line_no, column: name() });
                }
                let v: f64 = match cell.parse() {
                    Ok(v) => v,
                    Err(_) => {
                        return Err(LogError::NotNumeric {
                            file: file.to_string(),
                            line: line_no,
                            column: name(),
                            cell: cell.chars().take(40).collect(),
                        })
                    }
                };
                if !v.is_finite() {
                    return Err(LogError::NotFinite {
                        file: file.to_string(),
                        line: line_no,
                        column: name(),
                        cell: cell.to_string(),
                    });
                }
                if let Some(t) = target {
                    t.push(v);
                }
            }
            if n_cells != names.len() {
                return Err(LogError::Ragged { file: file.to_string(), line: line_no, found: n_cells, expected: names.len() });
            }
            // Time check right away so the error names this line.
            if let Some(tcol) = known.first() {
                if let [.., prev, t] = tcol.as_slice() {
                    let (prev, t) = (*prev, *t);
                    if t <= prev {
                        return Err(LogError::TimeNotIncreasing { file: file.to_string(), line: line_no, t, prev });
                    }
                }
            }
        }
        Ok(Rows { known, others, pending_blank })
    }

    /// Large bodies are parsed as two halves (split at a line end) on two threads. Only a clean
    /// result is taken from here: on any error in either half, a blank line before the second
    /// half's data, or time not increasing across the seam, `None` sends the caller to the
    /// one-thread parser, which finds the first problem with its exact line and column.
    fn rows_parallel(&self, text: &str) -> Option<Rows> {
        const MIN_PARALLEL: usize = 1 << 20;
        if text.len() < MIN_PARALLEL || std::thread::available_parallelism().map_or(1, |n| n.get()) < 2 {
            return None;
        }
        let mid = text.len() / 2;
        let nl = mid + text.as_bytes().get(mid..)?.iter().position(|&b| b == b'\n')?;
        let (a, b) = (text.get(..nl)?, text.get(nl + 1..)?);
        let (ra, rb) = std::thread::scope(|s| {
            let ha = s.spawn(|| self.rows(a, 1).ok());
            let rb = self.rows(b, 1).ok();
            (ha.join().ok().flatten(), rb)
        });
        let (mut ra, rb) = (ra?, rb?);
        let b_has_rows = rb.known.first().is_some_and(|v| !v.is_empty());
        if b_has_rows {
            if ra.pending_blank.is_some() {
                return None;
            }
            if let (Some(last), Some(first)) = (ra.known.first()?.last(), rb.known.first()?.first()) {
                if first <= last {
                    return None;
                }
            }
        }
        for (x, y) in ra.known.iter_mut().zip(&rb.known) {
            x.extend_from_slice(y);
        }
        for (x, y) in ra.others.iter_mut().zip(&rb.others) {
            x.extend_from_slice(y);
        }
        ra.pending_blank = ra.pending_blank.or(rb.pending_blank);
        Some(ra)
    }
}

/// Shortest representation that reads back to the same f64; exponent form for very small or
/// very large magnitudes so a cell never becomes hundreds of characters long.
fn push_num(buf: &mut String, v: f64) {
    let a = v.abs();
    // Writing to a String cannot fail.
    let _ = if v == 0.0 {
        write!(buf, "0")
    } else if (1e-4..1e15).contains(&a) {
        write!(buf, "{v}")
    } else {
        write!(buf, "{v:e}")
    };
}

/// Creates `path` via a sibling temporary file and a rename (atomic on one filesystem).
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let f = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(f);
        body(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// A body over the two-thread threshold: `n` rows of t,q,qd with t = k/1000.
    fn big(n: usize) -> Vec<String> {
        (0..n).map(|k| format!("{},{},{}", k as f64 / 1000.0, 0.123456789 * k as f64, -1.5e-3 * k as f64)).collect()
    }

    fn text(rows: &[String]) -> String {
        format!("t,q,qd\n{}\n", rows.join("\n"))
    }

    /// The line of the first row of the second half, as `rows_parallel` splits the body.
    fn seam_row(rows: &[String]) -> usize {
        let s = text(rows);
        let body = &s[s.find('\n').unwrap() + 1..];
        let mid = body.len() / 2;
        let nl = mid + body.as_bytes()[mid..].iter().position(|&b| b == b'\n').unwrap();
        body[..=nl].matches('\n').count()
    }

    #[test]
    fn two_thread_parse_equals_one_thread_parse() {
        let rows = big(60_000);
        let s = text(&rows);
        assert!(s.len() > 1 << 20, "the test body must take the two-thread path");
        let log = JointLog::parse(s.as_bytes(), "big.csv").unwrap();
        assert_eq!(log.len(), 60_000);
        for (k, row) in rows.iter().enumerate() {
            let v: Vec<f64> = row.split(',').map(|c| c.parse().unwrap()).collect();
            assert_eq!((log.t[k], log.q[k], log.qd.as_ref().unwrap()[k]), (v[0], v[1], v[2]), "row {k}");
        }
    }

    #[test]
    fn errors_at_and_around_the_seam_name_the_file_line() {
        let rows = big(60_000);
        let seam = seam_row(&rows);
        assert!(seam > 1000 && seam < 59_000);
        // time going back exactly at the first row of the second half
        let mut r = rows.clone();
        r[seam] = format!("0.0005,{},1", 0.5);
        match JointLog::parse(text(&r).as_bytes(), "f") {
            Err(LogError::TimeNotIncreasing { line, .. }) => assert_eq!(line, seam + 2),
            other => panic!("{other:?}"),
        }
        // a blank line at the end of the first half followed by data
        let mut r = rows.clone();
        r[seam - 1] = String::new();
        match JointLog::parse(text(&r).as_bytes(), "f") {
            Err(LogError::Ragged { line, found: 0, .. }) => assert_eq!(line, seam + 1),
            other => panic!("{other:?}"),
        }
        // errors in both halves: the earlier one is reported
        let mut r = rows.clone();
        r[seam + 10] = "x,1,1".into();
        r[100] = "0.1,,1".into();
        match JointLog::parse(text(&r).as_bytes(), "f") {
            Err(LogError::EmptyCell { line, column, .. }) => assert_eq!((line, column.as_str()), (102, "q")),
            other => panic!("{other:?}"),
        }
        // an error only in the second half
        let mut r = rows;
        r[seam + 10] = "1e999,1,1".into();
        match JointLog::parse(text(&r).as_bytes(), "f") {
            Err(LogError::NotFinite { line, column, .. }) => assert_eq!((line, column.as_str()), (seam + 12, "t")),
            other => panic!("{other:?}"),
        }
    }
}
