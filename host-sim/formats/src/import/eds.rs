//! What a CAN capture's decoder needs from a CiA 306 electronic data sheet (EDS, or a DCF that
//! records a node's actual configuration): for one node id, each transmit PDO's COB-ID and the
//! objects mapped into it, with their data type, name and scale (`Factor`, a key most tools
//! read although CiA 306 does not define it).
//!
//! The reader is an INI reader with CiA 306's rules: section and key names are case-insensitive,
//! `;` starts a comment, numbers are decimal, `0x` hex or leading-`0` octal, and a value may add
//! `$NODEID`. A DCF's `ParameterValue` is preferred to the `DefaultValue`, since a node's PDOs
//! may have been remapped after it left the factory.

use std::collections::BTreeMap;

/// The CANopen basic data types a PDO can carry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataType {
    Boolean,
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    Real32,
    Real64,
}

impl DataType {
    fn from_code(c: u64) -> Option<DataType> {
        Some(match c {
            0x1 => DataType::Boolean,
            0x2 => DataType::I8,
            0x3 => DataType::I16,
            0x4 => DataType::I32,
            0x15 => DataType::I64,
            0x5 => DataType::U8,
            0x6 => DataType::U16,
            0x7 => DataType::U32,
            0x1B => DataType::U64,
            0x8 => DataType::Real32,
            0x11 => DataType::Real64,
            _ => return None,
        })
    }

    /// Bits on the wire.
    pub fn bits(&self) -> u32 {
        match self {
            DataType::Boolean => 1,
            DataType::I8 | DataType::U8 => 8,
            DataType::I16 | DataType::U16 => 16,
            DataType::I32 | DataType::U32 | DataType::Real32 => 32,
            DataType::I64 | DataType::U64 | DataType::Real64 => 64,
        }
    }

    /// The value of `bits` little-endian bits of `data` from bit `at`, or `None` past the end.
    pub fn read(&self, data: &[u8], at: u32) -> Option<f64> {
        let n = self.bits();
        if at % 8 != 0 && n >= 8 {
            return None;
        }
        let mut raw: u64 = 0;
        for k in 0..n {
            let bit = at + k;
            let byte = *data.get((bit / 8) as usize)?;
            raw |= u64::from((byte >> (bit % 8)) & 1) << k;
        }
        Some(match self {
            DataType::Boolean | DataType::U8 | DataType::U16 | DataType::U32 | DataType::U64 => raw as f64,
            DataType::I8 => f64::from(raw as u8 as i8),
            DataType::I16 => f64::from(raw as u16 as i16),
            DataType::I32 => f64::from(raw as u32 as i32),
            DataType::I64 => raw as i64 as f64,
            DataType::Real32 => f64::from(f32::from_bits(raw as u32)),
            DataType::Real64 => f64::from_bits(raw),
        })
    }
}

/// One object mapped into a PDO.
#[derive(Clone, Debug, PartialEq)]
pub struct Mapped {
    /// the object's `ParameterName`
    pub name: String,
    pub index: u16,
    pub sub: u8,
    pub dtype: DataType,
    /// bit offset in the PDO's payload
    pub at: u32,
    /// raw → physical: `raw / divisor` when the factor is 1/divisor for an integer divisor
    /// (exact decimals: 1234 · 0.0001 prints as 0.1234), else `raw · factor`
    pub factor: f64,
    pub divisor: Option<f64>,
}

impl Mapped {
    pub fn value(&self, data: &[u8]) -> Option<f64> {
        let raw = self.dtype.read(data, self.at)?;
        Some(match self.divisor {
            Some(d) => raw / d,
            None => raw * self.factor,
        })
    }
}

/// A transmit PDO of the node.
#[derive(Clone, Debug, PartialEq)]
pub struct Pdo {
    /// which TPDO (1-based, from its communication object 0x1800 + n − 1)
    pub number: u16,
    pub cob_id: u32,
    pub entries: Vec<Mapped>,
}

/// Every valid transmit PDO of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct PdoMap {
    pub node: u8,
    pub pdos: Vec<Pdo>,
}

/// Sections of an INI text: name (upper case, `sub` lower case) → key (lower case) → value.
struct Ini {
    sections: BTreeMap<String, BTreeMap<String, String>>,
}

impl Ini {
    fn parse(text: &str, file: &str) -> Result<Ini, String> {
        let mut sections: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        let mut current: Option<String> = None;
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with(';') || line.starts_with('#') {
                continue;
            }
            if let Some(name) = line.strip_prefix('[') {
                let name = name
                    .strip_suffix(']')
                    .ok_or_else(|| format!("{file}: line {}: section header without `]`", i + 1))?;
                let key = name.trim().to_ascii_uppercase().replace("SUB", "sub");
                sections.entry(key.clone()).or_default();
                current = Some(key);
                continue;
            }
            let Some((k, v)) = line.split_once('=') else {
                return Err(format!("{file}: line {}: expected KEY=VALUE or [SECTION]", i + 1));
            };
            if let Some(s) = current.as_ref().and_then(|c| sections.get_mut(c)) {
                s.insert(k.trim().to_ascii_lowercase(), v.trim().to_string());
            }
        }
        Ok(Ini { sections })
    }

    fn get(&self, section: &str, key: &str) -> Option<&str> {
        self.sections.get(section).and_then(|s| s.get(key)).map(String::as_str)
    }

    /// The value a node runs with: `ParameterValue` (DCF) before `DefaultValue`.
    fn value(&self, section: &str) -> Option<&str> {
        self.get(section, "parametervalue").or_else(|| self.get(section, "defaultvalue"))
    }
}

/// A CiA 306 integer: decimal, `0x` hex or leading-`0` octal, with `$NODEID` added where it
/// appears (`$NODEID+0x180`, `0x180+$NODEID`).
fn int_value(v: &str, node: u8) -> Option<u64> {
    let mut total: u64 = 0;
    for term in v.split('+') {
        let t = term.trim();
        if t.eq_ignore_ascii_case("$NODEID") {
            total = total.checked_add(u64::from(node))?;
            continue;
        }
        let n = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
            u64::from_str_radix(h, 16).ok()?
        } else if t.len() > 1 && t.starts_with('0') {
            u64::from_str_radix(t.get(1..)?, 8).ok()?
        } else {
            t.parse().ok()?
        };
        total = total.checked_add(n)?;
    }
    Some(total)
}

/// The divisor that makes `factor` exact when it is 1/integer (1e-4 → 10000).
fn divisor_of(factor: f64) -> Option<f64> {
    if !(factor > 0.0 && factor < 1.0) {
        return None;
    }
    let d = (1.0 / factor).round();
    (((1.0 / d) - factor).abs() <= factor * 1e-12).then_some(d)
}

impl PdoMap {
    /// The transmit PDOs of node `node` as the EDS/DCF `text` describes them. Errors name the file
    /// and the section.
    pub fn from_eds(text: &str, file: &str, node: u8) -> Result<PdoMap, String> {
        let ini = Ini::parse(text, file)?;
        let mut pdos = Vec::new();
        for n in 0u16..512 {
            let comm = format!("{:04X}", 0x1800 + n);
            let map = format!("{:04X}", 0x1A00 + n);
            if !ini.sections.contains_key(&comm) || !ini.sections.contains_key(&map) {
                continue;
            }
            let sec = format!("{comm}sub1");
            let raw = ini.value(&sec).ok_or_else(|| format!("{file}: [{sec}]: no COB-ID value"))?;
            let cob = int_value(raw, node).ok_or_else(|| format!("{file}: [{sec}]: `{raw}` is not a COB-ID"))?;
            if cob & 0x8000_0000 != 0 {
                continue; // PDO not valid
            }
            let sec0 = format!("{map}sub0");
            let count = ini
                .value(&sec0)
                .and_then(|v| int_value(v, node))
                .ok_or_else(|| format!("{file}: [{sec0}]: no number of mapped objects"))?;
            let mut entries = Vec::new();
            let mut at = 0u32;
            for s in 1..=count.min(64) {
                let sec = format!("{map}sub{s:X}");
                let v = ini
                    .value(&sec)
                    .and_then(|v| int_value(v, node))
                    .ok_or_else(|| format!("{file}: [{sec}]: mapping entry missing or not a number (0xIIIISSLL)"))?;
                let (index, sub, bits) = ((v >> 16) as u16, (v >> 8) as u8, (v & 0xFF) as u32);
                if index == 0 || (index < 0x20 && sub == 0) {
                    // a dummy entry (a data type's index) only reserves bits
                    at += bits;
                    continue;
                }
                let obj = [format!("{index:04X}sub{sub:X}"), format!("{index:04X}")]
                    .into_iter()
                    .find(|o| ini.get(o, "datatype").is_some())
                    .ok_or_else(|| {
                        format!("{file}: [{sec}] maps {index:04X}:{sub}, which the file does not describe")
                    })?;
                let dt_raw = ini.get(&obj, "datatype").unwrap_or("");
                let dtype = int_value(dt_raw, node).and_then(DataType::from_code).ok_or_else(|| {
                    format!("{file}: [{obj}]: data type `{dt_raw}` cannot be carried in a PDO by this reader")
                })?;
                if dtype.bits() != bits {
                    return Err(format!(
                        "{file}: [{sec}] maps {index:04X}:{sub} with {bits} bits, its data type has {}",
                        dtype.bits()
                    ));
                }
                let factor = match ini.get(&obj, "factor") {
                    None => 1.0,
                    Some(f) => f
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && *x != 0.0)
                        .ok_or_else(|| format!("{file}: [{obj}]: Factor `{f}` is not a non-zero number"))?,
                };
                let name = ini.get(&obj, "parametername").unwrap_or("").to_string();
                let name = if name.is_empty() { format!("{index:04X}sub{sub:X}") } else { name };
                entries.push(Mapped { name, index, sub, dtype, at, factor, divisor: divisor_of(factor) });
                at += bits;
            }
            if at > 512 {
                return Err(format!("{file}: [{map}] maps {at} bits, more than a CAN FD frame's 512"));
            }
            pdos.push(Pdo { number: n + 1, cob_id: cob as u32, entries });
        }
        if pdos.iter().all(|p| p.entries.is_empty()) {
            return Err(format!("{file}: no transmit PDO with mapped objects (sections 1800/1A00 …)"));
        }
        Ok(PdoMap { node, pdos })
    }

    /// The PDO and entry that carry the object named `name` (first match).
    pub fn find(&self, name: &str) -> Option<(&Pdo, &Mapped)> {
        self.pdos.iter().find_map(|p| p.entries.iter().find(|e| e.name == name).map(|e| (p, e)))
    }

    /// Every mapped name, for messages.
    pub fn names(&self) -> Vec<&str> {
        self.pdos.iter().flat_map(|p| p.entries.iter().map(|e| e.name.as_str())).collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    const EDS: &str = "[1800]\nParameterName=tpdo1\n[1800sub1]\nDefaultValue=$NODEID+0x180\n\
        [1A00]\n[1A00sub0]\nDefaultValue=3\n[1A00sub1]\nDefaultValue=0x60640020\n[1A00sub2]\nDefaultValue=0x00050008\n\
        [1A00sub3]\nDefaultValue=0x60770010\n\
        [6064]\nParameterName=Position actual value\nDataType=0x0004\nFactor=0.001\n\
        [6077]\nParameterName=Torque actual value\nDataType=0x0003\n\
        [1801]\n[1801sub1]\nDefaultValue=0x80000280\n[1A01]\n[1A01sub0]\nDefaultValue=0\n";

    #[test]
    fn reads_cob_ids_mappings_types_and_factors() {
        let m = PdoMap::from_eds(EDS, "d.eds", 5).unwrap();
        assert_eq!(m.pdos.len(), 1, "the invalid TPDO2 is left out");
        let p = &m.pdos[0];
        assert_eq!(p.cob_id, 0x185);
        assert_eq!(p.entries.len(), 2, "the dummy byte only moves the offset");
        assert_eq!((p.entries[0].dtype, p.entries[0].at, p.entries[0].divisor), (DataType::I32, 0, Some(1000.0)));
        assert_eq!((p.entries[1].dtype, p.entries[1].at), (DataType::I16, 40));
        let data = [0x39, 0x30, 0, 0, 0xFF, 0xFE, 0xFF];
        assert_eq!(p.entries[0].value(&data), Some(12.345));
        assert_eq!(p.entries[1].value(&data), Some(-2.0));
        assert!(m.find("Torque actual value").is_some());
    }

    #[test]
    fn errors_name_the_section() {
        let bad = EDS.replace("DataType=0x0003", "DataType=0x0009");
        let e = PdoMap::from_eds(&bad, "d.eds", 5).unwrap_err();
        assert!(e.contains("[6077]") && e.contains("0x0009"), "{e}");
        let bad = EDS.replace("0x60770010", "0x60770020");
        let e = PdoMap::from_eds(&bad, "d.eds", 5).unwrap_err();
        assert!(e.contains("[1A00sub3]") && e.contains("32 bits"), "{e}");
        let bad = EDS.replace("[6064]\nParameterName=Position actual value\nDataType=0x0004\nFactor=0.001\n", "");
        let e = PdoMap::from_eds(&bad, "d.eds", 5).unwrap_err();
        assert!(e.contains("6064:0") && e.contains("does not describe"), "{e}");
    }

    #[test]
    fn integers_follow_cia_306() {
        assert_eq!(int_value("0x180+$NODEID", 3), Some(0x183));
        assert_eq!(int_value("010", 0), Some(8));
        assert_eq!(int_value("12", 0), Some(12));
        assert_eq!(int_value("x", 0), None);
    }
}
