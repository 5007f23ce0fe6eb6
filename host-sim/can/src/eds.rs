//! The node's CiA 306 electronic data sheet, generated from the core's object dictionary
//! (which comes from the one parameter table), so the EDS lists exactly what the node serves.
//! Default values are read from a node built with the table defaults; COB-IDs that depend on
//! the node id are written `$NODEID+0x…`, so one EDS serves every node id.

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig};
use joint_core::canopen::od::{self, DataType, ObjectKind, SubInfo};
use joint_core::canopen::ControlStep;
use joint_core::control::Controller;
use joint_core::fixed::{Arithmetic, ControllerFx};
use joint_core::params::PARAMS;
use std::fmt::Write;

/// Node id the defaults are read with; node-relative values subtract it again.
const REF_ID: u8 = 1;

fn default_value<C: ControlStep>(node: &Node<MemoryStorage, C>, s: &SubInfo) -> String {
    if !s.access.readable() || s.dtype == DataType::Domain {
        return if s.dtype == DataType::Domain { String::new() } else { "0".into() };
    }
    let mut buf = vec![0u8; 256];
    let n = node.read(s.index, s.sub, &mut buf).unwrap_or(0);
    buf.truncate(n);
    let mut b4 = [0u8; 4];
    for (x, y) in b4.iter_mut().zip(&buf) {
        *x = *y;
    }
    let u = u32::from_le_bytes(b4);
    match s.dtype {
        DataType::VisibleString => String::from_utf8_lossy(&buf).into_owned(),
        DataType::Real32 => format!("{}", f32::from_le_bytes(b4)),
        DataType::Integer16 => format!("{}", u as u16 as i16),
        DataType::Integer32 => format!("{}", u as i32),
        // an FD node's RPDO1 listens to the host's shared command frame, whatever its id
        _ if s.index == od::RPDO_COMM && s.sub == 1 && u == u32::from(od::SHARED_CMD_COB) => format!("0x{u:X}"),
        _ if s.node_relative && u & 0x8000_0000 == 0 => format!("$NODEID+0x{:X}", u - u32::from(REF_ID)),
        _ => format!("0x{u:X}"),
    }
}

/// What a master needs to turn a raw value into a physical one, as python-canopen and most
/// tools read it from an EDS (`Factor`, `Unit`, `Description`: not in CiA 306, widely used):
/// the scale of every INTEGER16 process value, the unit of every parameter, the fault bits.
fn physical(s: &SubInfo) -> (Option<f32>, Option<String>, Option<String>) {
    use joint_core::canopen::pdo;
    let scaled = |f: f32, u: &str| (Some(f), Some(u.to_string()), None);
    match (s.index, s.sub) {
        (od::JOINT_STATE, od::JS_Q) => scaled(pdo::Q_LSB, "rad"),
        (od::JOINT_STATE, od::JS_QD) => scaled(pdo::QD_LSB, "rad/s"),
        (od::JOINT_STATE, od::JS_TAU) | (od::JOINT_STATE, od::JS_TAU_MEAS) => scaled(pdo::TAU_LSB, "N*m"),
        (od::JOINT_STATE, od::JS_QDD) => scaled(pdo::QDD_LSB, "rad/s^2"),
        (od::JOINT_STATE, od::JS_TEMP) => scaled(pdo::TEMP_LSB, "degC"),
        (od::JOINT_STATE, od::JS_GAIN) => scaled(1.0e-3, "1 (assist gain, 1000 = full)"),
        (od::JOINT_STATE, od::JS_FAULTS) => {
            let bits: Vec<String> = (0..16u16)
                .filter_map(|b| {
                    joint_core::safety::Faults::from_bits_truncate(1 << b)
                        .names()
                        .next()
                        .map(|n| format!("bit {b} {n}"))
                })
                .collect();
            (None, None, Some(format!("fault bits: {}", bits.join(", "))))
        }
        (od::JOINT_STATE_F32, sub) => {
            // REAL32 in SI units: a master needs no scale (Factor 1)
            let unit = match sub {
                od::JF_Q => "rad",
                od::JF_QD => "rad/s",
                od::JF_QDD => "rad/s^2",
                od::JF_TAU | od::JF_TAU_MEAS | od::JF_ASSIST => "N*m",
                od::JF_U_MOTOR => "N*m (at the motor)",
                od::JF_TEMP => "degC",
                od::JF_GAIN => "1 (assist gain, 1 = full)",
                od::JF_MODE => return (None, None, Some("0 torque off, 1 assist (operational)".into())),
                _ => return (None, None, None),
            };
            (Some(1.0), Some(unit.into()), None)
        }
        (od::HOST_COMMAND, _) => scaled(pdo::TAU_LSB, "N*m"),
        (od::OTHER_ANGLES, sub) if sub > 0 => scaled(pdo::Q_LSB, "rad"),
        (od::PARAMS_CRC, _) => {
            (None, None, Some("CRC-32 of a parameter set's record payload (joint_core::store::set_crc)".into()))
        }
        (od::COMMIT_CRC, _) => (
            None,
            None,
            Some(
                "commit: write the CRC-32 of the set you mean (computed from it; 0x2204 sub 2 is what is staged): \
                 the staged set is checked and goes live whole only if it is that set, else abort 0x08000022 and \
                 commit error 7, so another master's staged values never go live with yours"
                    .into(),
            ),
        ),
        (od::COMMIT, _) => (
            None,
            None,
            Some(
                "0 discards the staged set; 1 (a plain commit, which names no set) is refused with abort \
                 0x06010000 and commit error 9: commit by CRC at 0x2205"
                    .into(),
            ),
        ),
        (od::COMMIT_ERROR, 1) => (
            None,
            None,
            Some(
                "0 none, 1 not finite, 2 out of range, 3 inconsistent, 4 gravity table, 5 safety parameter outside \
                 pre-operational, 6 gravity series, 7 the CRC named is not the staged set's, 8 staged set discarded \
                 (its master quiet 3 s), 9 plain commit refused (commit by CRC at 0x2205)"
                    .into(),
            ),
        ),
        (i, 0) if (od::PARAM_BASE..od::PARAM_BASE + PARAMS.len() as u16).contains(&i) => {
            let d = PARAMS.get((i - od::PARAM_BASE) as usize);
            (None, d.map(|d| d.unit.replace('·', "*").replace('²', "^2").replace('°', "deg")), None)
        }
        _ => (None, None, None),
    }
}

fn write_var<C: ControlStep>(out: &mut String, node: &Node<MemoryStorage, C>, section: &str, s: &SubInfo) {
    let _ = writeln!(out, "[{section}]");
    let _ = writeln!(out, "ParameterName={}", s.name);
    let _ = writeln!(out, "ObjectType=0x7");
    let _ = writeln!(out, "DataType=0x{:04X}", s.dtype as u16);
    let _ = writeln!(out, "AccessType={}", s.access.eds());
    let _ = writeln!(out, "DefaultValue={}", default_value(node, s));
    if let Some((lo, hi)) = s.limits {
        let _ = writeln!(out, "LowLimit={lo}");
        let _ = writeln!(out, "HighLimit={hi}");
    }
    let _ = writeln!(out, "PDOMapping={}", u8::from(s.pdo));
    let (factor, unit, description) = physical(s);
    if let Some(f) = factor {
        let _ = writeln!(out, "Factor={f}");
    }
    if let Some(u) = unit.filter(|u| !u.is_empty()) {
        let _ = writeln!(out, "Unit={u}");
    }
    if let Some(d) = description {
        let _ = writeln!(out, "Description={d}");
    }
    out.push('\n');
}

/// The EDS text of a joint node with the f32 control step (the G431 board's).
pub fn generate() -> String {
    generate_for(Arithmetic::F32)
}

/// The EDS text of a joint node whose control step runs in `a`: a Q16.16 node (the G0B1
/// board's default) has its own product number and name (0x1018 sub 2, 0x1008), which is how a
/// master tells which numbers the joint computes; everything else is the same dictionary.
pub fn generate_for(a: Arithmetic) -> String {
    generate_for_bus(a, false)
}

/// The EDS of a node on a CAN FD bus (`fd`): the same dictionary, with the defaults of an FD
/// node — TPDO3 (0x1802/0x1A02: the whole state in REAL32, 32 bytes, FD frames with bit-rate
/// switch) valid and the classic TPDO1/2 invalid.
pub fn generate_for_bus(a: Arithmetic, fd: bool) -> String {
    match a {
        Arithmetic::F32 => generate_with::<Controller>(fd),
        Arithmetic::Q16 => generate_with::<ControllerFx>(fd),
    }
}

fn generate_with<C: ControlStep>(fd: bool) -> String {
    let cfg = NodeConfig::new(REF_ID).with_fd(fd);
    let node = Node::<MemoryStorage, C>::with_step(cfg, MemoryStorage::default(), 0);
    let cfg = cfg.with_arithmetic(C::ARITHMETIC);
    let mut out = String::new();
    let idx: Vec<u16> = od::indices().collect();
    let mandatory = [od::DEVICE_TYPE, od::ERROR_REGISTER, od::IDENTITY];
    let optional: Vec<u16> = idx.iter().copied().filter(|i| !mandatory.contains(i) && *i < 0x2000).collect();
    let manufacturer: Vec<u16> = idx.iter().copied().filter(|i| *i >= 0x2000).collect();

    let _ = writeln!(out, "[FileInfo]");
    let _ = match C::ARITHMETIC {
        Arithmetic::F32 => writeln!(out, "FileName=joint-node{}.eds", if fd { "-fd" } else { "" }),
        Arithmetic::Q16 => writeln!(out, "FileName=joint-node-q16{}.eds", if fd { "-fd" } else { "" }),
    };
    let _ = writeln!(out, "FileVersion=1");
    let _ = writeln!(out, "FileRevision=0");
    let _ = writeln!(out, "EDSVersion=4.0");
    let _ = writeln!(
        out,
        "Description=Exoskeleton/robot-arm joint node (generated by jointctl eds from the core's parameter table){}",
        match C::ARITHMETIC {
            Arithmetic::F32 => "",
            Arithmetic::Q16 => "; control step in Q16.16 fixed point",
        }
    );
    if fd {
        // CiA 306 v4.0 has no key for CAN FD: say it where a reader looks
        let _ = writeln!(
            out,
            "Comment=CAN FD node (CiA 1301 frames, 1 Mbit/s nominal, 5 Mbit/s data with BRS): TPDO3 carries the \
             joint state in 32 bytes (0x2301 sub 1..8: q, qd, qdd, tau, tau measured, u, temperature in REAL32, SI \
             units, no scale, and the mode; the fault bits; the error register), not the assist gain and command \
             (0x2301 sub 9, 10: a 48-byte frame); SDO is CiA 301 SDO in 8-byte frames (no USDO)"
        );
    }
    let _ = writeln!(out, "CreatedBy=jointctl {}", env!("CARGO_PKG_VERSION"));
    out.push('\n');
    let _ = writeln!(out, "[DeviceInfo]");
    // no CiA vendor id has been assigned to this project: 0 says so rather than borrowing one
    let _ = writeln!(out, "VendorName=unassigned (no CiA vendor id)");
    let _ = writeln!(out, "VendorNumber=0x{:X}", cfg.identity.vendor_id);
    let _ = writeln!(out, "ProductName={}", cfg.device_name);
    let _ = writeln!(out, "ProductNumber=0x{:X}", cfg.identity.product_code);
    let _ = writeln!(out, "RevisionNumber=0x{:X}", cfg.identity.revision);
    // What the board images run: 1 Mbit/s, fixed at build time (firmware/board CAN_BITRATE);
    // LSS configure bit timing answers every other rate with error 1. The host tools and the
    // simulated bus take any rate.
    for (rate, ok) in [(10, 0), (20, 0), (50, 0), (125, 0), (250, 0), (500, 0), (800, 0), (1000, 1)] {
        let _ = writeln!(out, "BaudRate_{rate}={ok}");
    }
    let _ = writeln!(out, "SimpleBootUpMaster=0");
    let _ = writeln!(out, "SimpleBootUpSlave=1");
    let _ = writeln!(out, "Granularity=8");
    let _ = writeln!(out, "DynamicChannelsSupported=0");
    let _ = writeln!(out, "GroupMessaging=0");
    let _ = writeln!(out, "NrOfRXPDO={}", od::RPDO_COUNT);
    let _ = writeln!(out, "NrOfTXPDO={}", od::TPDO_COUNT);
    // CiA 305 LSS slave: in `jointctl sim`, both board images (the G431 since b391aa6, node id
    // and bit timing stored in the flash record's communication block) and the QEMU images
    let lss = joint_core::canopen::lss::SERVED;
    let _ = writeln!(out, "LSS_Supported={}", u8::from(lss));
    out.push('\n');
    let _ = writeln!(out, "[DummyUsage]");
    for d in 1..=7 {
        // an FD node's RPDO1 maps UNSIGNED16/32 dummies before its slot of the shared frame
        let _ = writeln!(out, "Dummy000{d}={}", u8::from(fd && (d == 6 || d == 7)));
    }
    out.push('\n');
    // Units and documentation of the parameter objects (EDS has no unit field).
    let _ = writeln!(out, "[Comments]");
    let _ = writeln!(out, "Lines={}", PARAMS.len());
    for (i, d) in PARAMS.iter().enumerate() {
        let safety = if d.safety { " [safety: writable only in pre-operational]" } else { "" };
        let _ = writeln!(
            out,
            "Line{}=0x{:04X} {} [{}] {}..{}: {}{}",
            i + 1,
            od::PARAM_BASE + i as u16,
            d.name,
            d.unit,
            d.min,
            d.max,
            d.doc,
            safety
        );
    }
    out.push('\n');
    for (title, list) in [
        ("MandatoryObjects", &mandatory.to_vec()),
        ("OptionalObjects", &optional),
        ("ManufacturerObjects", &manufacturer),
    ] {
        let _ = writeln!(out, "[{title}]");
        let _ = writeln!(out, "SupportedObjects={}", list.len());
        for (k, i) in list.iter().enumerate() {
            let _ = writeln!(out, "{}=0x{:04X}", k + 1, i);
        }
        out.push('\n');
    }
    for index in idx {
        let Some(obj) = od::object_info(index) else { continue };
        if obj.kind == ObjectKind::Var {
            if let Ok(s) = od::sub_info(index, 0) {
                write_var(&mut out, &node, &format!("{index:04X}"), &s);
            }
            continue;
        }
        let _ = writeln!(out, "[{index:04X}]");
        let _ = writeln!(out, "ParameterName={}", obj.name);
        let _ = writeln!(out, "ObjectType=0x{}", if obj.kind == ObjectKind::Array { 8 } else { 9 });
        let _ = writeln!(out, "SubNumber={}", obj.subs.len());
        out.push('\n');
        for &sub in obj.subs {
            if let Ok(s) = od::sub_info(index, sub) {
                write_var(&mut out, &node, &format!("{index:04X}sub{sub:X}"), &s);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Q16.16 board's EDS names its step where a master reads the identity, and differs
    /// from the f32 board's in nothing else: the same dictionary.
    #[test]
    fn the_q16_eds_differs_only_in_the_identity_and_its_names() {
        let f = generate();
        assert_eq!(f, generate_for(Arithmetic::F32));
        let q = generate_for(Arithmetic::Q16);
        assert!(f.contains("ProductNumber=0x4A4E0001\n") && f.contains("ProductName=joint-node\n"));
        assert!(q.contains("ProductNumber=0x4A4E0002\n") && q.contains("ProductName=joint-node q16.16\n"));
        let differing: Vec<(&str, &str)> = f.lines().zip(q.lines()).filter(|(a, b)| a != b).collect();
        assert_eq!(f.lines().count(), q.lines().count());
        for (a, b) in &differing {
            let key = a.split('=').next().unwrap_or("");
            assert!(
                ["FileName", "Description", "ProductName", "ProductNumber", "DefaultValue"].contains(&key),
                "{a} / {b}"
            );
        }
        // the two DefaultValue lines: 0x1008 (the name) and 0x1018 sub 2 (the product code)
        assert_eq!(differing.iter().filter(|(a, _)| a.starts_with("DefaultValue")).count(), 2, "{differing:?}");
    }

    /// LSS is in every image the EDS describes since b391aa6 (the G431's too); the EDS once
    /// said the G431 left it out. The FD EDS names what TPDO3 leaves out.
    #[test]
    fn lss_is_declared_for_every_board_and_the_fd_comment_says_what_tpdo3_carries() {
        let f = generate();
        assert!(f.contains("LSS_Supported=1\n"));
        assert!(!f.contains("G431"), "no board is singled out");
        let fd = generate_for_bus(Arithmetic::F32, true);
        let comment = fd.lines().find(|l| l.starts_with("Comment=")).unwrap_or_default();
        assert!(comment.contains("32 bytes") && comment.contains("not the assist gain and command"), "{comment}");
    }
}
