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
    #[error(
        "{file}: line 1: the header `{header}` is one column: the file is separated by `{delimiter}`, \
         not by commas (write it with `,` between the cells)"
    )]
    NotCommaSeparated { file: String, header: String, delimiter: &'static str },
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
        if let Some(log) = read_halves(path, &file) {
            return Ok(log);
        }
        let bytes = std::fs::read(path).map_err(|e| LogError::Io { file: file.clone(), msg: e.to_string() })?;
        Self::parse(&bytes, &file)
    }

    /// Parses log text; `file` is only used in error messages.
    pub fn parse(bytes: &[u8], file: &str) -> Result<JointLog, LogError> {
        let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
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
        let header = Header::parse(header, file)?;
        let layout = Layout { file, header: &header };
        let rows = layout.rows_parallel(rest).map_or_else(|| layout.rows(rest, 1), Ok)?;
        header.finish(rows, file)
    }

    /// Column names in the order [`write_csv`](Self::write_csv) writes them.
    pub fn column_names(&self) -> Vec<&str> {
        let mut v = vec!["t", "q"];
        for (name, col) in
            [("qd", &self.qd), ("qdd", &self.qdd), ("u", &self.u), ("tau", &self.tau), ("temp", &self.temp)]
        {
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

    /// Writes the log to `path` by the rules of [`crate::output`]: a regular file through a
    /// temporary file and a rename (a failed write never leaves a half-written log), a device
    /// or FIFO in place. A command that also reads files declares them in an
    /// [`output::Plan`](crate::output::Plan) instead, so the log cannot land on one of them.
    pub fn write_file(&self, path: &Path) -> Result<(), crate::output::OutputError> {
        crate::output::write_file(path, |w| self.write_csv(w))
    }
}

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// What the header row fixed: the column names, where each cell goes, which spec columns are
/// present, and the names of the `q_` and unknown columns.
struct Header {
    names: Vec<String>,
    slots: Vec<Slot>,
    known_present: [bool; KNOWN.len()],
    others: Vec<String>,
    unknown: Vec<String>,
}

impl Header {
    /// Parses the header line (without its line end; a trailing CR is removed here).
    fn parse(line: &str, file: &str) -> Result<Header, LogError> {
        let line = line.strip_suffix('\r').unwrap_or(line);
        if line.trim().is_empty() {
            return Err(LogError::Empty { file: file.to_string() });
        }
        let names: Vec<String> = line
            .split(',')
            .map(|c| {
                let c = c.trim();
                c.strip_prefix('"').and_then(|c| c.strip_suffix('"')).unwrap_or(c).trim().to_string()
            })
            .collect();
        let mut h = Header {
            names: Vec::new(),
            slots: Vec::with_capacity(names.len()),
            known_present: [false; KNOWN.len()],
            others: Vec::new(),
            unknown: Vec::new(),
        };
        for (i, name) in names.iter().enumerate() {
            if name.is_empty() {
                return Err(LogError::EmptyHeader { file: file.to_string(), index: i + 1 });
            }
            if names.iter().take(i).any(|n| n == name) {
                return Err(LogError::DuplicateColumn { file: file.to_string(), column: name.clone() });
            }
            if let Some(k) = KNOWN.iter().position(|k| k == name) {
                if let Some(f) = h.known_present.get_mut(k) {
                    *f = true;
                }
                h.slots.push(Slot::Known(k));
            } else if name.len() > 2 && name.starts_with("q_") {
                h.slots.push(Slot::Other(h.others.len()));
                h.others.push(name.clone());
            } else {
                h.slots.push(Slot::Skip);
                h.unknown.push(name.clone());
            }
        }
        // one column whose name holds another usual delimiter: the file is not comma-separated
        if let [only] = names.as_slice() {
            if let Some((_, name)) =
                [(';', ";"), ('\t', "tab"), ('|', "|")].into_iter().find(|(d, _)| only.contains(*d))
            {
                return Err(LogError::NotCommaSeparated {
                    file: file.to_string(),
                    header: only.clone(),
                    delimiter: name,
                });
            }
        }
        for (k, req) in [(0usize, "t"), (1, "q")] {
            if !h.known_present.get(k).copied().unwrap_or(false) {
                return Err(LogError::MissingColumn { file: file.to_string(), column: req });
            }
        }
        h.names = names;
        Ok(h)
    }

    /// The log from fully parsed rows. Option wrappers are set only here, so nothing
    /// half-filled ever escapes.
    fn finish(self, rows: Rows, file: &str) -> Result<JointLog, LogError> {
        let [t, q, qd, qdd, u, tau, temp] = rows.known;
        if t.is_empty() {
            return Err(LogError::NoRows { file: file.to_string() });
        }
        let p = self.known_present;
        let opt = |present: bool, v: Vec<f64>| if present { Some(v) } else { None };
        Ok(JointLog {
            t,
            q,
            qd: opt(p[2], qd),
            qdd: opt(p[3], qdd),
            u: opt(p[4], u),
            tau: opt(p[5], tau),
            temp: opt(p[6], temp),
            others: self.others.into_iter().zip(rows.others).collect(),
            unknown: self.unknown,
        })
    }
}

/// Where the header sends each cell. Shared by the one- and two-thread row parsers.
struct Layout<'a> {
    file: &'a str,
    header: &'a Header,
}

/// Parsed data rows: known columns by KNOWN index, `q_` columns in header order.
struct Rows {
    known: [Vec<f64>; KNOWN.len()],
    others: Vec<Vec<f64>>,
    /// first line of a run of blank lines at the end of the text parsed
    pending_blank: Option<usize>,
}

impl Rows {
    /// Room for `rows` more rows in every column the header fills.
    fn reserve(&mut self, header: &Header, rows: usize) {
        for (k, present) in header.known_present.iter().enumerate() {
            if let (true, Some(v)) = (*present, self.known.get_mut(k)) {
                v.reserve(rows);
            }
        }
        for v in self.others.iter_mut() {
            v.reserve(rows);
        }
    }

    /// Appends the rows parsed from the text that follows; `None` where the seam is not clean
    /// (a blank line before more data, time not increasing across it): the caller then parses
    /// everything on one thread, which names the exact line.
    fn join(mut self, next: Rows) -> Option<Rows> {
        let next_has_rows = next.known.first().is_some_and(|v| !v.is_empty());
        if next_has_rows {
            if self.pending_blank.is_some() {
                return None;
            }
            if let (Some(last), Some(first)) = (self.known.first()?.last(), next.known.first()?.first()) {
                if first <= last {
                    return None;
                }
            }
        }
        for (x, y) in self.known.iter_mut().zip(&next.known) {
            x.extend_from_slice(y);
        }
        for (x, y) in self.others.iter_mut().zip(&next.others) {
            x.extend_from_slice(y);
        }
        self.pending_blank = self.pending_blank.or(next.pending_blank);
        Some(self)
    }
}

/// Splits `s` at byte `sep` exactly as `str::split` does (a trailing separator gives a last,
/// empty piece), scanning bytes: `sep` is ASCII, so every piece is valid UTF-8.
fn pieces(s: &str, sep: u8) -> impl Iterator<Item = &str> {
    let mut rest = Some(s);
    std::iter::from_fn(move || {
        let r = rest?;
        match r.as_bytes().iter().position(|&b| b == sep) {
            Some(k) => {
                rest = r.get(k + 1..);
                r.get(..k)
            }
            None => {
                rest = None;
                Some(r)
            }
        }
    })
}

/// `str::trim` without the Unicode scan for the usual cell that has nothing to trim.
fn trim_cell(c: &str) -> &str {
    match (c.as_bytes().first(), c.as_bytes().last()) {
        (Some(a), Some(b)) if a.is_ascii_graphic() && b.is_ascii_graphic() => c,
        _ => c.trim(),
    }
}

impl Layout<'_> {
    /// Parses the data rows in `text`; `header_line` is the line number just before its first
    /// line (1 for the whole body after the header), so errors name the file's own line.
    fn rows(&self, text: &str, header_line: usize) -> Result<Rows, LogError> {
        let mut out = self.empty_rows();
        out.reserve(self.header, text.len() / (self.header.names.len() * 8).max(1));
        self.rows_into(text, header_line, &mut out)?;
        Ok(out)
    }

    /// No rows yet, one empty column per column the header sends cells to.
    fn empty_rows(&self) -> Rows {
        Rows { known: Default::default(), others: vec![Vec::new(); self.header.others.len()], pending_blank: None }
    }

    /// Parses the data rows in `text` onto the end of `out`, as if `text` followed the text
    /// `out` was parsed from: a blank line left pending before it and the time check carry over.
    /// `header_line` is the line number just before `text`'s first line.
    fn rows_into(&self, text: &str, header_line: usize, out: &mut Rows) -> Result<(), LogError> {
        let file = self.file;
        let Header { names, slots, .. } = self.header;
        let Rows { known, others, pending_blank } = out;
        let mut line_no = header_line;
        for line in pieces(text, b'\n') {
            let line = line.strip_suffix('\r').unwrap_or(line);
            line_no += 1;
            if trim_cell(line).is_empty() {
                pending_blank.get_or_insert(line_no);
                continue;
            }
            if let Some(blank) = *pending_blank {
                // A blank line followed by data: the file was cut or glued together.
                return Err(LogError::Ragged { file: file.to_string(), line: blank, found: 0, expected: names.len() });
            }
            let mut n_cells = 0usize;
            for (col, cell) in pieces(line, b',').enumerate() {
                n_cells += 1;
                let Some(slot) = slots.get(col) else { continue };
                let target = match *slot {
                    Slot::Skip => continue,
                    Slot::Known(k) => known.get_mut(k),
                    Slot::Other(o) => others.get_mut(o),
                };
                let cell = trim_cell(cell);
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
                return Err(LogError::Ragged {
                    file: file.to_string(),
                    line: line_no,
                    found: n_cells,
                    expected: names.len(),
                });
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
        Ok(())
    }

    /// Large bodies are parsed as two halves (split at a line end) on two threads. Only a clean
    /// result is taken from here: on any error in either half, a blank line before the second
    /// half's data, or time not increasing across the seam, `None` sends the caller to the
    /// one-thread parser, which finds the first problem with its exact line and column.
    fn rows_parallel(&self, text: &str) -> Option<Rows> {
        if text.len() < MIN_PARALLEL || !two_cores() {
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
        ra?.join(rb?)
    }
}

/// Bodies shorter than this are parsed on one thread.
const MIN_PARALLEL: usize = 1 << 20;

fn two_cores() -> bool {
    std::thread::available_parallelism().map_or(1, |n| n.get()) >= 2
}

/// A large log file read and parsed as two halves, each thread reading its own half from the
/// file (the read is half of the time on a 100 MB log) and parsing it. The halves meet at the
/// first line end after the middle. Each half is read a chunk at a time into one buffer, its
/// complete lines parsed and the cut line carried over, so the file's bytes are never held
/// whole: a 100 MB log no longer costs 100 MB of fresh pages (on this project's 2-core VM the
/// kernel zeroing pages was a third of the 1 M-sample diagnosis' CPU time). The first half's
/// columns are sized from its first chunk for the whole file, so the second half joins them
/// without a reallocation. `None` for anything but a clean result (small file, one core, an
/// I/O error, a line longer than a chunk, any error in the data or at the seam): the caller
/// then reads the whole file and parses it on the checked path, which names the first problem
/// exactly.
#[cfg(unix)]
fn read_halves(path: &Path, file: &str) -> Option<JointLog> {
    read_halves_in(path, file, 1 << 20)
}

/// [`read_halves`] a `chunk` of bytes at a time.
#[cfg(unix)]
fn read_halves_in(path: &Path, file: &str, chunk: usize) -> Option<JointLog> {
    use std::os::unix::fs::FileExt;
    const OVERHANG: usize = 1 << 16;
    let f = std::fs::File::open(path).ok()?;
    let len = usize::try_from(f.metadata().ok()?.len()).ok()?;
    if len < MIN_PARALLEL || !two_cores() {
        return None;
    }
    let read = |from: usize, to: usize| -> Option<Vec<u8>> {
        let mut v = vec![0u8; to.checked_sub(from)?];
        f.read_exact_at(&mut v, from as u64).ok()?;
        Some(v)
    };
    let head = read(0, OVERHANG.min(len))?;
    let bom = if head.starts_with(BOM) { BOM.len() } else { 0 };
    let head_end = bom + head.get(bom..)?.iter().position(|&b| b == b'\n')?;
    let header = Header::parse(std::str::from_utf8(head.get(bom..head_end)?).ok()?, file).ok()?;
    let layout = Layout { file, header: &header };
    let body = head_end + 1;
    let mid = body + (len - body) / 2;
    // the first line end at or after the middle: the first half ends before it
    let seam = mid + read(mid, (mid + OVERHANG).min(len))?.iter().position(|&c| c == b'\n')?;
    // The rows of the bytes [from, to), cut at line ends, with room for about as many rows as
    // `room` bytes hold.
    let part = |from: usize, to: usize, room: usize| -> Option<Rows> {
        let mut rows = layout.empty_rows();
        let mut buf: Vec<u8> = Vec::with_capacity(2 * chunk);
        let mut at = from;
        let mut sized = false;
        loop {
            let kept = buf.len();
            let take = chunk.min(to - at);
            buf.resize(kept + take, 0);
            f.read_exact_at(buf.get_mut(kept..)?, at as u64).ok()?;
            at += take;
            let last = at == to;
            // complete lines only; the cut one waits for the next chunk
            let cut = if last { buf.len() } else { buf.iter().rposition(|&c| c == b'\n')? };
            layout.rows_into(std::str::from_utf8(buf.get(..cut)?).ok()?, 1, &mut rows).ok()?;
            if !sized {
                sized = true;
                let n = rows.known.first().map_or(0, Vec::len);
                if n > 0 && cut > 0 {
                    let est = (room as f64 / cut as f64 * n as f64 * 1.02) as usize + 64;
                    rows.reserve(layout.header, est.saturating_sub(n));
                }
            }
            if last {
                return Some(rows);
            }
            buf.drain(..=cut);
        }
    };
    let (ra, rb) = std::thread::scope(|s| {
        let ha = s.spawn(|| part(body, seam, len - body));
        let rb = part(seam + 1, len, len - seam);
        (ha.join().ok().flatten(), rb)
    });
    let rows = ra?.join(rb?)?;
    header.finish(rows, file).ok()
}

#[cfg(not(unix))]
fn read_halves(_path: &Path, _file: &str) -> Option<JointLog> {
    None
}

/// Shortest representation that reads back to the same f64; exponent form for very small or
/// very large magnitudes so a cell never becomes hundreds of characters long.
/// `v` as the log writer writes it (shortest round-trip form).
pub(crate) fn fmt_num(v: f64) -> String {
    let mut s = String::new();
    push_num(&mut s, v);
    s
}

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

    /// The two halves read from the file give exactly what the in-memory parse gives, BOM and
    /// CRLF included, and the file path really is taken (not the fallback).
    #[test]
    fn reading_a_large_file_in_halves_equals_parsing_it() {
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in [
            ("lf.csv", text(&big(60_000))),
            ("crlf-bom.csv", format!("\u{feff}{}", text(&big(60_000)).replace('\n', "\r\n"))),
        ] {
            let path = dir.path().join(name);
            std::fs::write(&path, &text).unwrap();
            let want = JointLog::parse(text.as_bytes(), "x").unwrap();
            let halves = read_halves(&path, "x").expect("a clean 2 MB file is read in halves");
            assert_eq!(halves, want, "{name}");
            assert_eq!(JointLog::read_file(&path).unwrap(), want, "{name}");
        }
    }

    /// Read in chunks of any size, down to a few lines and to chunks that cut lines and CRLF
    /// pairs anywhere, the halves give what the in-memory parse gives, blank lines at the end
    /// included; a blank line inside the data is refused wherever the chunks cut it; a chunk
    /// shorter than a line gives up (the caller then parses the whole file).
    #[test]
    fn chunks_of_any_size_read_the_same_rows() {
        let dir = tempfile::tempdir().unwrap();
        let rows = big(60_000);
        let crlf = format!("{}\r\n\r\n", text(&rows).replace('\n', "\r\n"));
        let path = dir.path().join("c.csv");
        std::fs::write(&path, &crlf).unwrap();
        let want = JointLog::parse(crlf.as_bytes(), "x").unwrap();
        for chunk in [64, 97, 1000, 4096, 65_537, 1 << 20] {
            assert_eq!(read_halves_in(&path, "x", chunk).as_ref(), Some(&want), "chunk {chunk}");
        }
        assert!(read_halves_in(&path, "x", 8).is_none(), "a chunk shorter than a line");
        let mut gap = rows;
        gap.insert(20_000, String::new());
        let path = dir.path().join("gap.csv");
        std::fs::write(&path, text(&gap)).unwrap();
        for chunk in [64, 97, 1000, 4096, 1 << 20] {
            assert!(read_halves_in(&path, "x", chunk).is_none(), "chunk {chunk}");
        }
        assert!(matches!(JointLog::read_file(&path), Err(LogError::Ragged { line: 20_002, found: 0, .. })));
    }

    /// Errors in either half or at the seam of a file read in halves are reported by the
    /// one-thread parse, with the file's own line.
    #[test]
    fn errors_in_a_large_file_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let rows = big(60_000);
        let path = dir.path().join("bad.csv");
        let line_of = |r: &[String]| {
            std::fs::write(&path, text(r)).unwrap();
            assert!(read_halves(&path, "f").is_none());
            JointLog::read_file(&path).unwrap_err()
        };
        for at in [100usize, 30_000, 59_990] {
            let mut r = rows.clone();
            r[at] = format!("{},x,1", at as f64 / 1000.0);
            match line_of(&r) {
                LogError::NotNumeric { line, column, .. } => assert_eq!((line, column.as_str()), (at + 2, "q")),
                other => panic!("{other:?}"),
            }
        }
        // time going back somewhere in the second half
        let mut r = rows;
        r[45_000] = format!("0.0005,{},1", 0.5);
        match line_of(&r) {
            LogError::TimeNotIncreasing { line, .. } => assert_eq!(line, 45_002),
            other => panic!("{other:?}"),
        }
    }
}
