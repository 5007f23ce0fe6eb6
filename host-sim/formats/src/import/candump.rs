//! CAN bus captures in can-utils' log format (`candump -l`, `canplayer -I`, python-can's
//! `CanutilsLogWriter`), and their decoding into a joint log through a node's PDO mapping.
//!
//! A line is `(SECONDS.FRACTION) IFACE FRAME`, FRAME being `ID#DATA` (classic; ID 3 hex digits
//! standard, 8 extended), `ID#R[LEN]` (remote request) or `ID##FDATA` (CAN FD, F = flags nibble,
//! bit 0 bit-rate switch). A trailing direction flag (` R`/` T`, candump `-x`) is allowed.
//!
//! Decoding ([`decode`]): one row per frame of the PDO that carries `q`; every other column takes
//! the last value received before (or with) that frame; rows before every mapped value has
//! arrived once are not written (a placeholder would read as data). `t` is the frame's time
//! since the capture's first frame. Two extra columns a joint log may carry (spec §1: columns
//! the reader does not know are listed, never an error): `faults` when mapped, and `nmt`, the
//! node's last heartbeat state byte (empty before its first heartbeat).

use super::csv_map::{self, Entry};
use super::eds::PdoMap;

/// One frame of a capture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// time stamp, nanoseconds (µs in every writer known; ns kept when a file has them)
    pub t_ns: u64,
    pub iface: String,
    pub id: u32,
    pub extended: bool,
    pub remote: bool,
    /// CAN FD flags (bit 0 BRS, bit 1 ESI) for an FD frame
    pub fd_flags: Option<u8>,
    pub data: Vec<u8>,
}

/// A frame as the decoder and the capture writer read it, borrowed (a live bus's frames need
/// no copy into [`Record`]s to be decoded or written).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRef<'a> {
    pub t_ns: u64,
    pub id: u32,
    pub extended: bool,
    pub remote: bool,
    pub data: &'a [u8],
}

impl FrameRef<'_> {
    /// The line `candump -l` writes for this frame on `iface` (no line end); `fd_flags` for a
    /// CAN FD frame.
    pub fn line(&self, iface: &str, fd_flags: Option<u8>) -> String {
        let (s, ns) = (self.t_ns / 1_000_000_000, self.t_ns % 1_000_000_000);
        let stamp = if ns % 1000 == 0 { format!("{s:010}.{:06}", ns / 1000) } else { format!("{s:010}.{ns:09}") };
        let id = if self.extended { format!("{:08X}", self.id) } else { format!("{:03X}", self.id) };
        let hex: String = self.data.iter().map(|b| format!("{b:02X}")).collect();
        let frame = match (fd_flags, self.remote) {
            (Some(f), _) => format!("{id}##{f:X}{hex}"),
            (None, true) => format!("{id}#R"),
            (None, false) => format!("{id}#{hex}"),
        };
        format!("({stamp}) {iface} {frame}")
    }
}

/// The error-frame flag of SocketCAN's 32-bit id (candump writes error frames with it).
const CAN_ERR_FLAG: u32 = 0x2000_0000;

fn hex_bytes(s: &str) -> Option<Vec<u8>> {
    if s.len() % 2 != 0 {
        return None;
    }
    (0..s.len() / 2).map(|i| s.get(2 * i..2 * i + 2).and_then(|b| u8::from_str_radix(b, 16).ok())).collect()
}

impl Record {
    /// Parses one line; `Ok(None)` for a line that is not a frame the decoder uses (an error
    /// frame). Errors say what is wrong; the caller adds file and line.
    pub fn parse(line: &str) -> Result<Option<Record>, String> {
        let mut parts = line.split_whitespace();
        let stamp = parts.next().ok_or("empty line")?;
        let stamp = stamp
            .strip_prefix('(')
            .and_then(|s| s.strip_suffix(')'))
            .ok_or_else(|| format!("time stamp `{stamp}` is not (SECONDS.FRACTION)"))?;
        let (sec, frac) = stamp.split_once('.').unwrap_or((stamp, ""));
        let sec: u64 = sec.parse().map_err(|_| format!("time stamp `({stamp})`: seconds are not a number"))?;
        if frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("time stamp `({stamp})`: the fraction must be 0–9 digits"));
        }
        let mut ns: u64 = if frac.is_empty() { 0 } else { frac.parse().unwrap_or(0) };
        for _ in frac.len()..9 {
            ns *= 10;
        }
        let t_ns = sec
            .checked_mul(1_000_000_000)
            .and_then(|s| s.checked_add(ns))
            .ok_or_else(|| format!("time stamp `({stamp})` is too large"))?;
        let iface = parts.next().ok_or("no interface after the time stamp")?.to_string();
        let frame = parts.next().ok_or("no frame after the interface")?;
        match parts.next() {
            None | Some("R") | Some("T") => {}
            Some(x) => return Err(format!("unexpected `{x}` after the frame")),
        }
        let (id_s, rest) = frame.split_once('#').ok_or_else(|| format!("frame `{frame}` has no `#`"))?;
        let extended = match id_s.len() {
            3 => false,
            8 => true,
            _ => return Err(format!("frame `{frame}`: the id must be 3 (standard) or 8 (extended) hex digits")),
        };
        let id = u32::from_str_radix(id_s, 16).map_err(|_| format!("frame `{frame}`: id `{id_s}` is not hex"))?;
        if extended && id & CAN_ERR_FLAG != 0 {
            return Ok(None);
        }
        if (!extended && id > 0x7FF) || id > 0x1FFF_FFFF {
            return Err(format!("frame `{frame}`: id 0x{id:X} is out of range"));
        }
        let (fd_flags, remote, data) = if let Some(fd) = rest.strip_prefix('#') {
            let flags = fd.get(..1).and_then(|f| u8::from_str_radix(f, 16).ok());
            let data = fd.get(1..).and_then(hex_bytes);
            match (flags, data) {
                (Some(f), Some(d)) if d.len() <= 64 => (Some(f), false, d),
                _ => return Err(format!("frame `{frame}`: CAN FD data must be a flags digit and ≤ 64 hex bytes")),
            }
        } else if let Some(r) = rest.strip_prefix('R') {
            if !(r.is_empty() || (r.len() == 1 && r.as_bytes().first().is_some_and(|b| (b'0'..=b'8').contains(b)))) {
                return Err(format!("frame `{frame}`: a remote request is ID#R or ID#R0..8"));
            }
            (None, true, Vec::new())
        } else {
            match hex_bytes(rest) {
                Some(d) if d.len() <= 8 => (None, false, d),
                _ => return Err(format!("frame `{frame}`: classic CAN data must be 0–8 bytes in hex pairs")),
            }
        };
        Ok(Some(Record { t_ns, iface, id, extended, remote, fd_flags, data }))
    }

    /// The frame, borrowed.
    pub fn view(&self) -> FrameRef<'_> {
        FrameRef { t_ns: self.t_ns, id: self.id, extended: self.extended, remote: self.remote, data: &self.data }
    }

    /// The line `candump -l` writes for this frame (no line end).
    pub fn line(&self) -> String {
        self.view().line(&self.iface, self.fd_flags)
    }
}

/// Parses a whole capture; errors name the file and line. Returns the frames and the number of
/// error frames skipped.
pub fn parse_capture(text: &str, file: &str) -> Result<(Vec<Record>, usize), String> {
    let mut out = Vec::new();
    let mut skipped = 0;
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match Record::parse(line).map_err(|e| format!("{file}: line {}: {e}", i + 1))? {
            Some(r) => out.push(r),
            None => skipped += 1,
        }
    }
    if out.is_empty() {
        return Err(format!("{file}: no CAN frames"));
    }
    Ok((out, skipped))
}

/// The capture text of classic `frames` seen on `iface`, one line each.
pub fn write_capture<'a>(frames: impl IntoIterator<Item = FrameRef<'a>>, iface: &str) -> String {
    let mut s = String::new();
    for f in frames {
        s.push_str(&f.line(iface, None));
        s.push('\n');
    }
    s
}

/// How to decode: the node and the map from log columns to the EDS's object names.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodeOpts {
    pub node: u8,
    /// `COLUMN=OBJECT_NAME[:STEP…]`, as `--map` of `--format csv` but naming mapped objects;
    /// empty: the joint's own EDS names (q, qd, qdd, tau_cmd → u, temperature → temp, faults)
    pub map: String,
    /// the joint has a load cell: `tau_measured` → `tau` (default map only)
    pub load_cell: bool,
}

/// The default map for the joint's own EDS (what `jointctl log` writes).
pub fn default_map(load_cell: bool) -> String {
    let mut m = String::from("q=q,qd=qd,qdd=qdd,u=tau_cmd,");
    if load_cell {
        m.push_str("tau=tau_measured,");
    }
    m.push_str("temp=temperature,faults=faults");
    m
}

/// A decoded capture: the joint-log CSV text, its row count, and notes.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    pub csv: String,
    pub rows: usize,
    /// frames of the row PDO before every mapped value had arrived (not written)
    pub early: usize,
    pub notes: Vec<String>,
}

/// Decodes `frames` into joint-log CSV text (see the module documentation).
pub fn decode<'a>(
    frames: impl IntoIterator<Item = FrameRef<'a>>,
    pdos: &PdoMap,
    o: &DecodeOpts,
) -> Result<Decoded, String> {
    let map = if o.map.trim().is_empty() { default_map(o.load_cell) } else { o.map.clone() };
    let entries: Vec<Entry> = csv_map::parse_entries(&map, |c| c == "faults")?;
    if entries.iter().any(|e| e.column == "t") {
        return Err("--map: `t` comes from the capture's time stamps; do not map it".into());
    }
    if !entries.iter().any(|e| e.column == "q") {
        return Err("--map: the required column `q` is not mapped".into());
    }
    // spec order, then the other joints' angles, then faults
    let rank = |c: &str| ["q", "qd", "qdd", "u", "tau", "temp"].iter().position(|x| *x == c).unwrap_or(6);
    let mut entries = entries;
    entries.sort_by_key(|e| (rank(&e.column), e.column == "faults"));
    let mut slots = Vec::with_capacity(entries.len());
    for e in &entries {
        let name = e.source_name().ok_or_else(|| format!("--map entry `{}`: name a mapped object", e.text))?;
        let (pdo, m) = pdos.find(name).ok_or_else(|| {
            format!(
                "--map entry `{}`: node {} maps no object named `{name}` (its PDOs carry: {})",
                e.text,
                pdos.node,
                pdos.names().join(", ")
            )
        })?;
        slots.push((pdo.cob_id, m.clone()));
    }
    let Some(row_cob) = slots.first().map(|s| s.0) else {
        return Err("--map: nothing mapped".into());
    };
    // the slots each COB-ID carries, found once rather than per frame
    let mut groups: Vec<(u32, Vec<usize>)> = Vec::new();
    for (i, (cob, _)) in slots.iter().enumerate() {
        match groups.iter_mut().find(|g| g.0 == *cob) {
            Some(g) => g.1.push(i),
            None => groups.push((*cob, vec![i])),
        }
    }
    let mut got: Vec<f64> = Vec::with_capacity(slots.len());
    let hb_id = 0x700 + u32::from(o.node);
    let mut last: Vec<Option<f64>> = vec![None; slots.len()];
    let mut nmt: Option<u8> = None;
    let mut header = String::from("t");
    for e in &entries {
        header.push(',');
        header.push_str(&e.column);
    }
    header.push_str(",nmt\n");
    let mut csv = header;
    let (mut rows, mut early, mut same_time, mut short) = (0usize, 0usize, 0usize, 0usize);
    let mut t0: Option<u64> = None;
    let mut last_t: Option<u64> = None;
    for r in frames {
        let t0 = *t0.get_or_insert(r.t_ns);
        if r.extended || r.remote {
            continue;
        }
        if r.id == hb_id && r.data.len() == 1 {
            nmt = r.data.first().copied();
            continue;
        }
        let Some((_, mine)) = groups.iter().find(|g| g.0 == r.id) else { continue };
        // a frame shorter than its mapping gives nothing: no value of it is taken
        got.clear();
        for &i in mine {
            match slots.get(i).and_then(|(_, m)| m.value(r.data)) {
                Some(x) => got.push(x),
                None => break,
            }
        }
        if got.len() < mine.len() {
            short += 1;
            continue;
        }
        for (&i, &x) in mine.iter().zip(&got) {
            if let Some(v) = last.get_mut(i) {
                *v = Some(x);
            }
        }
        if r.id != row_cob {
            continue;
        }
        if last.iter().any(Option::is_none) {
            early += 1;
            continue;
        }
        // (a capture's stamps need not be in order: a row before the one written, or before the
        // first frame, is not written)
        if last_t.is_some_and(|lt| r.t_ns <= lt) || r.t_ns < t0 {
            same_time += 1;
            continue;
        }
        last_t = Some(r.t_ns);
        csv.push_str(&crate::log::fmt_num((r.t_ns - t0) as f64 / 1e9));
        for (e, v) in entries.iter().zip(last.iter().flatten()) {
            csv.push(',');
            csv.push_str(&crate::log::fmt_num(e.apply(*v)));
        }
        csv.push(',');
        if let Some(b) = nmt {
            csv.push_str(&b.to_string());
        }
        csv.push('\n');
        rows += 1;
    }
    if rows == 0 {
        return Err(format!(
            "no row: node {} sent no frame with COB-ID 0x{row_cob:03X} after every mapped value had arrived",
            o.node
        ));
    }
    let mut notes = Vec::new();
    if early > 0 {
        notes.push(format!("{early} frames before every mapped value had arrived once: not written"));
    }
    if same_time > 0 {
        notes.push(format!("{same_time} rows whose time did not increase: not written"));
    }
    if short > 0 {
        notes.push(format!("{short} frames shorter than their mapping: not taken"));
    }
    Ok(Decoded { csv, rows, early, notes })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn lines_round_trip_in_every_frame_kind() {
        for line in [
            "(1436509052.249713) can0 185#39300000FFFE",
            "(0000000001.000000) vcan0 12345678#",
            "(0000000002.000001) can1 701#R",
            "(0000000003.123456789) can0 205##1",
        ] {
            let r = Record::parse(line).unwrap().unwrap();
            let again = Record::parse(&r.line()).unwrap().unwrap();
            assert_eq!(r, again, "{line}");
        }
        let r = Record::parse("(1.5) can0 185#0102 R").unwrap().unwrap();
        assert_eq!((r.t_ns, r.id, r.data.clone()), (1_500_000_000, 0x185, vec![1, 2]));
        assert_eq!(Record::parse("(1.0) can0 20000004#0000000000000000").unwrap(), None, "error frame");
    }

    #[test]
    fn bad_lines_say_what_is_wrong() {
        for (line, what) in [
            ("1.0 can0 185#00", "time stamp"),
            ("(1.0) can0 185", "no `#`"),
            ("(1.0) can0 1850#00", "3 (standard) or 8"),
            ("(1.0) can0 185#0", "hex pairs"),
            ("(1.0) can0 185#001122334455667788", "0–8 bytes"),
            ("(1.0) can0 800#00", "out of range"),
            ("(1.0x) can0 185#00", "fraction"),
            ("(1.0) can0", "no frame"),
        ] {
            let e = Record::parse(line).unwrap_err();
            assert!(e.contains(what), "{line}: {e}");
        }
        let e = parse_capture("(1.0) can0 185#00\n(2.0) can0 185\n", "c.log").unwrap_err();
        assert!(e.starts_with("c.log: line 2:"), "{e}");
    }

    const EDS: &str = "[1800]\n[1800sub1]\nDefaultValue=$NODEID+0x180\n[1A00]\n[1A00sub0]\nDefaultValue=2\n\
        [1A00sub1]\nDefaultValue=0x23000110\n[1A00sub2]\nDefaultValue=0x23000210\n\
        [1801]\n[1801sub1]\nDefaultValue=$NODEID+0x280\n[1A01]\n[1A01sub0]\nDefaultValue=1\n[1A01sub1]\nDefaultValue=0x23000710\n\
        [2300sub1]\nParameterName=q\nDataType=0x0003\nFactor=0.0001\n[2300sub2]\nParameterName=qd\nDataType=0x0003\nFactor=0.001\n\
        [2300sub7]\nParameterName=temperature\nDataType=0x0003\nFactor=0.01\n";

    #[test]
    fn rows_start_once_every_value_has_arrived() {
        let pdos = PdoMap::from_eds(EDS, "e", 5).unwrap();
        let cap = "(100.000000) can0 185#D2040A00\n(100.000500) can0 705#05\n(100.001000) can0 285#C409\n\
                   (100.002000) can0 185#2E0BF6FF\n(100.002000) can0 185#2E0BF6FF\n(100.003000) can0 185#0000\n";
        let (recs, _) = parse_capture(cap, "c").unwrap();
        let o = DecodeOpts { node: 5, map: "q=q,qd=qd:*2,temp=temperature".into(), load_cell: false };
        let d = decode(recs.iter().map(Record::view), &pdos, &o).unwrap();
        assert_eq!(d.csv, "t,q,qd,temp,nmt\n0.002,0.2862,-0.02,25,5\n", "{}", d.csv);
        assert!(d.notes.iter().any(|n| n.contains("1 frames before")), "{:?}", d.notes);
        assert!(d.notes.iter().any(|n| n.contains("1 rows whose time did not increase")), "{:?}", d.notes);
        assert!(d.notes.iter().any(|n| n.contains("1 frames shorter")), "{:?}", d.notes);
        // stamps out of order (two interfaces merged): a row earlier than the first frame is
        // not written, nothing wraps
        let cap = "(100.000000) can0 285#C409\n(99.000000) can0 185#D2040A00\n(100.001000) can0 185#D2040A00\n";
        let (recs2, _) = parse_capture(cap, "c").unwrap();
        let d2 = decode(recs2.iter().map(Record::view), &pdos, &o).unwrap();
        assert_eq!(d2.rows, 1, "{}", d2.csv);
        assert!(d2.csv.ends_with("0.001,0.1234,0.02,25,\n"), "{}", d2.csv);
        let o = DecodeOpts { map: "q=position".into(), ..o };
        let e = decode(recs.iter().map(Record::view), &pdos, &o).unwrap_err();
        assert!(e.contains("no object named `position`") && e.contains("q, qd, temperature"), "{e}");
    }
}
