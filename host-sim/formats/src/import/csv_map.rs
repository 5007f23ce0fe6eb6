//! `--format csv`: any delimited text file with a header row, turned into a joint log by a
//! column map the user writes on the command line (docs/import.md):
//!
//! ```text
//! t=time_s,q=angle_deg:deg,u=motor_current_A:*0.75*160,tau=0
//! ```
//!
//! Each entry is `COLUMN=SOURCE[:STEP[:STEP…]]` or `COLUMN=SOURCE:STEPSTEP…` for arithmetic:
//! - `COLUMN` is a joint-log column of spec §1: `t`, `q`, `qd`, `qdd`, `u`, `tau`, `temp` or
//!   `q_<name>` (another joint's angle);
//! - `SOURCE` is a header name of the file (quotes and surrounding spaces ignored), `#N` for its
//!   N-th column (1-based), or a number for a constant column (`tau=0`: a log whose only torque
//!   is the motor's);
//! - each `STEP` converts to SI and is applied left to right: a unit (`deg`, `rad`, `deg/s`,
//!   `rpm`, `deg/s2`, `ms`, `us`, `ns`, `mNm`, `K`) or arithmetic `*X`, `/X`, `+X`, `-X`
//!   (several in a row: `*0.75*160`).
//!
//! The delimiter (`,` `;` tab `|` or runs of spaces) and the decimal separator (`.` or `,`) are
//! detected from the file unless given; a decimal comma needs a delimiter other than `,`.
//! Lines starting with `#` and blank lines are skipped. Rows whose time does not increase are
//! dropped and counted, as the data-set importers do. Everything else that is wrong (a missing
//! column, a cell that is not a number, a unit that does not fit the column) is refused with the
//! file, line and column named; nothing is half-read.

use crate::log::JointLog;

/// One delimiter the reader knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    Comma,
    Semicolon,
    Tab,
    Pipe,
    /// one or more spaces (fixed-width or whitespace-separated exports)
    Spaces,
}

impl Delimiter {
    pub const NAMES: [(&'static str, Delimiter); 5] = [
        ("comma", Delimiter::Comma),
        ("semicolon", Delimiter::Semicolon),
        ("tab", Delimiter::Tab),
        ("pipe", Delimiter::Pipe),
        ("spaces", Delimiter::Spaces),
    ];

    fn split<'a>(&self, line: &'a str) -> Vec<&'a str> {
        match self {
            Delimiter::Comma => line.split(',').collect(),
            Delimiter::Semicolon => line.split(';').collect(),
            Delimiter::Tab => line.split('\t').collect(),
            Delimiter::Pipe => line.split('|').collect(),
            Delimiter::Spaces => line.split_whitespace().collect(),
        }
    }

    fn name(&self) -> &'static str {
        Self::NAMES.iter().find(|(_, d)| d == self).map_or("?", |(n, _)| n)
    }
}

/// How the file writes decimals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decimal {
    Point,
    Comma,
}

/// The reader's settings: the map and, when the user fixed them, delimiter and decimal mark.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CsvOpts {
    pub map: String,
    pub delimiter: Option<Delimiter>,
    pub decimal: Option<Decimal>,
}

/// Where a column's values come from (a name that no header has and that reads as a number is a
/// constant column).
#[derive(Clone, Debug, PartialEq)]
enum Source {
    Name(String),
    /// 0-based
    Index(usize),
}

/// One conversion step, applied as `v → v·mul + add`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Step {
    mul: f64,
    add: f64,
}

/// One `COLUMN=SOURCE[:STEP…]` of a map.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Entry {
    pub(super) column: String,
    source: Source,
    steps: Vec<Step>,
    /// the entry as written, for messages
    pub(super) text: String,
}

impl Entry {
    /// The source's name (`None` for a column number).
    pub(super) fn source_name(&self) -> Option<&str> {
        match &self.source {
            Source::Name(n) => Some(n),
            Source::Index(_) => None,
        }
    }

    /// The steps applied to a raw value.
    pub(super) fn apply(&self, raw: f64) -> f64 {
        self.steps.iter().fold(raw, |v, s| v * s.mul + s.add)
    }
}

/// The columns of spec §1 a map may fill, and the units that fit each.
const COLUMNS: [&str; 7] = ["t", "q", "qd", "qdd", "u", "tau", "temp"];

/// Units by name: (name, the columns it fits, multiplier, offset).
const UNITS: [(&str, &[&str], f64, f64); 12] = [
    ("rad", &["q", "q_"], 1.0, 0.0),
    ("deg", &["q", "q_"], std::f64::consts::PI / 180.0, 0.0),
    ("rad/s", &["qd"], 1.0, 0.0),
    ("deg/s", &["qd"], std::f64::consts::PI / 180.0, 0.0),
    ("rpm", &["qd"], std::f64::consts::PI / 30.0, 0.0),
    ("deg/s2", &["qdd"], std::f64::consts::PI / 180.0, 0.0),
    ("s", &["t"], 1.0, 0.0),
    ("ms", &["t"], 1e-3, 0.0),
    ("us", &["t"], 1e-6, 0.0),
    ("ns", &["t"], 1e-9, 0.0),
    ("mNm", &["u", "tau"], 1e-3, 0.0),
    ("K", &["temp"], 1.0, -273.15),
];

fn number(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

fn parse_steps(column: &str, spec: &str, entry: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for part in spec.split(':') {
        let part = part.trim();
        if part.is_empty() {
            return Err(format!("--map entry `{entry}`: an empty conversion step"));
        }
        if part.starts_with(['*', '/', '+', '-']) {
            // a run of arithmetic: `*0.75*160`, `-273.15`, `/1000*2`
            let mut rest = part;
            while let Some(op) = rest.chars().next() {
                let body = rest.get(1..).unwrap_or("");
                // the operand runs to the next operator that is not an exponent's sign
                let mut end = body.len();
                let bytes = body.as_bytes();
                for (i, c) in body.char_indices().skip(1) {
                    if matches!(c, '*' | '/' | '+' | '-') && !matches!(bytes.get(i - 1), Some(b'e' | b'E')) {
                        end = i;
                        break;
                    }
                }
                let operand = body.get(..end).unwrap_or("");
                let x = number(operand).ok_or_else(|| {
                    format!("--map entry `{entry}`: `{op}{operand}` is not an operator and a finite number")
                })?;
                steps.push(match op {
                    '*' => Step { mul: x, add: 0.0 },
                    '/' if x == 0.0 => return Err(format!("--map entry `{entry}`: division by zero")),
                    '/' => Step { mul: 1.0 / x, add: 0.0 },
                    '+' => Step { mul: 1.0, add: x },
                    _ => Step { mul: 1.0, add: -x },
                });
                rest = body.get(end..).unwrap_or("");
            }
            continue;
        }
        let Some((name, fits, mul, add)) = UNITS.iter().find(|(n, ..)| *n == part) else {
            let known: Vec<&str> = UNITS.iter().map(|u| u.0).collect();
            return Err(format!(
                "--map entry `{entry}`: unknown conversion `{part}` (units: {}; arithmetic: *X /X +X -X)",
                known.join(" ")
            ));
        };
        let col_kind = if column.starts_with("q_") { "q_" } else { column };
        if !fits.contains(&col_kind) {
            return Err(format!("--map entry `{entry}`: unit `{name}` does not fit column `{column}`"));
        }
        steps.push(Step { mul: *mul, add: *add });
    }
    Ok(steps)
}

/// The entries of a map whose columns are spec columns or those `extra` admits.
pub(super) fn parse_entries(map: &str, extra: impl Fn(&str) -> bool) -> Result<Vec<Entry>, String> {
    let mut entries: Vec<Entry> = Vec::new();
    for text in map.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (column, rhs) =
            text.split_once('=').ok_or_else(|| format!("--map entry `{text}`: expected COLUMN=SOURCE[:UNIT]"))?;
        let column = column.trim();
        let is_other = column.len() > 2 && column.starts_with("q_");
        if !COLUMNS.contains(&column) && !is_other && !extra(column) {
            return Err(format!(
                "--map entry `{text}`: `{column}` is not a joint-log column (t, q, qd, qdd, u, tau, temp, q_<name>)"
            ));
        }
        if entries.iter().any(|e| e.column == column) {
            return Err(format!("--map: column `{column}` is mapped twice"));
        }
        let (src, steps) = match rhs.split_once(':') {
            Some((s, rest)) => (s.trim(), parse_steps(column, rest, text)?),
            None => (rhs.trim(), Vec::new()),
        };
        if src.is_empty() {
            return Err(format!("--map entry `{text}`: no source column"));
        }
        let source = if let Some(n) = src.strip_prefix('#') {
            match n.parse::<usize>() {
                Ok(k) if k >= 1 => Source::Index(k - 1),
                _ => return Err(format!("--map entry `{text}`: `{src}` is not a column number (#1, #2, …)")),
            }
        } else {
            Source::Name(src.trim_matches('"').to_string())
        };
        entries.push(Entry { column: column.to_string(), source, steps, text: text.to_string() });
    }
    Ok(entries)
}

fn parse_map(map: &str) -> Result<Vec<Entry>, String> {
    let entries = parse_entries(map, |_| false)?;
    for need in ["t", "q"] {
        if !entries.iter().any(|e| e.column == need) {
            return Err(format!("--map: the required column `{need}` is not mapped (e.g. --map t=time,q=angle)"));
        }
    }
    if entries.iter().any(|e| e.column == "u") != entries.iter().any(|e| e.column == "tau") {
        return Err("--map: torque mode needs both `u` and `tau` (map `tau=0` when only the motor torque is logged)"
            .to_string());
    }
    Ok(entries)
}

/// The lines that hold data or the header: (1-based line number, text).
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
}

/// The delimiter that splits the header and most of the first data lines into the same number
/// (> 1) of cells, tried in the order `;` tab `|` `,` spaces (a `;` or tab file may hold decimal
/// commas, a comma file holds no semicolons).
fn detect_delimiter(text: &str, file: &str) -> Result<Delimiter, String> {
    let sample: Vec<&str> = content_lines(text).take(20).map(|(_, l)| l).collect();
    for d in [Delimiter::Semicolon, Delimiter::Tab, Delimiter::Pipe, Delimiter::Comma, Delimiter::Spaces] {
        // the header and most of the first rows agree (a ragged row is reported by its line later)
        let counts: Vec<usize> = sample.iter().map(|l| d.split(l).len()).collect();
        if let Some(&n) = counts.first() {
            if n > 1 && 2 * counts.iter().filter(|&&c| c == n).count() > counts.len() {
                return Ok(d);
            }
        }
    }
    Err(format!(
        "{file}: cannot tell the delimiter: none of ; tab | , spaces splits the header and the first rows alike (give --delimiter)"
    ))
}

/// Decimal comma when the delimiter leaves room for one and a data cell uses it.
fn detect_decimal(text: &str, d: Delimiter) -> Decimal {
    if d == Delimiter::Comma {
        return Decimal::Point;
    }
    let uses_comma = content_lines(text).skip(1).take(20).any(|(_, l)| {
        d.split(l).iter().any(|c| {
            let c = c.trim();
            c.contains(',') && c.replace(',', ".").parse::<f64>().is_ok()
        })
    });
    if uses_comma {
        Decimal::Comma
    } else {
        Decimal::Point
    }
}

/// Reads `text` through the map. Returns the log and notes on what was detected or dropped.
pub fn convert(text: &str, file: &str, o: &CsvOpts) -> Result<(JointLog, Vec<String>), String> {
    let entries = parse_map(&o.map)?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let delim = match o.delimiter {
        Some(d) => d,
        None => detect_delimiter(text, file)?,
    };
    let decimal = o.decimal.unwrap_or_else(|| detect_decimal(text, delim));
    if delim == Delimiter::Comma && decimal == Decimal::Comma {
        return Err(format!("{file}: a decimal comma needs a delimiter other than `,`"));
    }
    let mut notes = vec![format!(
        "read as {}-separated, decimal {}",
        delim.name(),
        if decimal == Decimal::Comma { "comma" } else { "point" }
    )];
    let mut lines = content_lines(text);
    let (hline, header) = lines.next().ok_or_else(|| format!("{file}: no header row"))?;
    let names: Vec<String> =
        delim.split(header).iter().map(|s| s.trim().trim_matches('"').trim().to_string()).collect();
    // each entry: the column index it reads, or a constant
    let mut picks: Vec<Result<usize, f64>> = Vec::with_capacity(entries.len());
    for e in &entries {
        picks.push(match &e.source {
            Source::Index(i) if *i < names.len() => Ok(*i),
            Source::Index(i) => {
                return Err(format!(
                    "{file}: line {hline}: --map entry `{}` reads column #{}, the header has {} columns",
                    e.text,
                    i + 1,
                    names.len()
                ))
            }
            Source::Name(n) => match names.iter().position(|h| h == n) {
                Some(i) => Ok(i),
                None => match number(n) {
                    Some(c) => Err(c),
                    None => {
                        return Err(format!(
                            "{file}: line {hline}: --map entry `{}`: no column `{n}` (the header has: {})",
                            e.text,
                            names.join(", ")
                        ))
                    }
                },
            },
        });
    }
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); entries.len()];
    for (ln, line) in lines {
        let cells = delim.split(line);
        if cells.len() != names.len() {
            return Err(format!("{file}: line {ln}: {} cells, the header has {}", cells.len(), names.len()));
        }
        for ((e, pick), col) in entries.iter().zip(&picks).zip(cols.iter_mut()) {
            let raw = match pick {
                Err(c) => *c,
                Ok(i) => {
                    let cell = cells.get(*i).map_or("", |c| c.trim().trim_matches('"'));
                    let parsed = match decimal {
                        Decimal::Comma => number(&cell.replace(',', ".")),
                        Decimal::Point => number(cell),
                    };
                    parsed.ok_or_else(|| {
                        let name = names.get(*i).map_or("?", String::as_str);
                        if cell.is_empty() {
                            format!("{file}: line {ln}, column `{name}` (for `{}`): empty cell", e.column)
                        } else {
                            format!("{file}: line {ln}, column `{name}` (for `{}`): `{cell}` is not a number", e.column)
                        }
                    })?
                }
            };
            col.push(e.apply(raw));
        }
    }
    let get = |c: &str| entries.iter().position(|e| e.column == c).and_then(|i| cols.get(i)).cloned();
    let t = get("t").unwrap_or_default();
    if t.is_empty() {
        return Err(format!("{file}: no data rows"));
    }
    let mut keep = Vec::with_capacity(t.len());
    let mut last = f64::NEG_INFINITY;
    for (i, &x) in t.iter().enumerate() {
        if x > last {
            keep.push(i);
            last = x;
        }
    }
    if keep.len() < t.len() {
        notes.push(format!("dropped {} rows whose time did not increase", t.len() - keep.len()));
    }
    let pick = |v: Vec<f64>| -> Vec<f64> { keep.iter().filter_map(|&i| v.get(i).copied()).collect() };
    let opt = |c: &str| get(c).map(pick);
    let log = JointLog {
        t: pick(t),
        q: opt("q").unwrap_or_default(),
        qd: opt("qd"),
        qdd: opt("qdd"),
        u: opt("u"),
        tau: opt("tau"),
        temp: opt("temp"),
        others: entries
            .iter()
            .zip(&cols)
            .filter(|(e, _)| e.column.starts_with("q_"))
            .map(|(e, c)| (e.column.clone(), pick(c.clone())))
            .collect(),
        unknown: Vec::new(),
    };
    Ok((log, notes))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn opts(map: &str) -> CsvOpts {
        CsvOpts { map: map.to_string(), ..CsvOpts::default() }
    }

    #[test]
    fn units_and_arithmetic_apply_left_to_right() {
        let text = "time_ms;angle_deg;I_A;T_K\n0;90;1,5;300\n10;180;2;301\n";
        let (log, notes) =
            convert(text, "x.csv", &opts("t=time_ms:ms,q=angle_deg:deg,u=I_A:*0.75*160,tau=0,temp=T_K:K")).unwrap();
        assert!(notes[0].contains("semicolon") && notes[0].contains("comma"), "{notes:?}");
        assert_eq!(log.t, vec![0.0, 0.01]);
        assert!((log.q[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(log.u.as_deref(), Some(&[180.0, 240.0][..]));
        assert_eq!(log.tau.as_deref(), Some(&[0.0, 0.0][..]));
        assert!((log.temp.as_ref().unwrap()[0] - 26.85).abs() < 1e-9);
    }

    #[test]
    fn delimiters_are_detected_and_columns_can_be_numbered() {
        for (sep, name) in [("\t", "tab"), ("|", "pipe"), ("  ", "spaces"), (",", "comma")] {
            let text = format!("# exported\nt{sep}a{sep}b\n0{sep}1.5{sep}2\n1{sep}2.5{sep}3\n");
            let (log, notes) = convert(&text, "x", &opts("t=#1,q=b,q_hip=a:-1")).unwrap();
            assert!(notes[0].contains(name), "{sep:?}: {notes:?}");
            assert_eq!(log.q, vec![2.0, 3.0]);
            assert_eq!(log.others, vec![("q_hip".to_string(), vec![0.5, 1.5])]);
        }
    }

    #[test]
    fn exponents_keep_their_sign_inside_arithmetic() {
        let (log, _) = convert("t,x\n0,1\n1,2\n", "x", &opts("t=t,q=x:*1e-3+2.5e-1")).unwrap();
        assert_eq!(log.q, vec![0.251, 0.252]);
    }

    #[test]
    fn errors_name_the_entry_the_line_and_the_column() {
        let text = "time,angle\n0,1\n0.1,x\n";
        let e = convert(text, "f.csv", &opts("t=time,q=angl")).unwrap_err();
        assert!(e.contains("f.csv: line 1") && e.contains("no column `angl`") && e.contains("time, angle"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle")).unwrap_err();
        assert!(e.contains("line 3, column `angle`") && e.contains("`x` is not a number"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle:rpm")).unwrap_err();
        assert!(e.contains("`rpm` does not fit column `q`"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle:furlong")).unwrap_err();
        assert!(e.contains("unknown conversion `furlong`"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time")).unwrap_err();
        assert!(e.contains("`q` is not mapped"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle,u=angle")).unwrap_err();
        assert!(e.contains("both `u` and `tau`"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle,speed=angle")).unwrap_err();
        assert!(e.contains("`speed` is not a joint-log column"), "{e}");
        let e = convert("t,q\n0,1\n1,2,3\n", "f.csv", &opts("t=t,q=q")).unwrap_err();
        assert!(e.contains("line 3: 3 cells"), "{e}");
        let e = convert(text, "f.csv", &opts("t=time,q=angle:/0")).unwrap_err();
        assert!(e.contains("division by zero"), "{e}");
    }

    #[test]
    fn repeated_times_are_dropped_and_counted() {
        let (log, notes) = convert("t,q\n0,1\n0,1\n1,2\n", "x", &opts("t=t,q=q")).unwrap();
        assert_eq!(log.t, vec![0.0, 1.0]);
        assert!(notes.iter().any(|n| n.contains("dropped 1")), "{notes:?}");
    }
}
