//! The bring-your-own-data readers take files nobody checked: arbitrary text or bytes, and
//! inputs built from each format's own pieces (so most cases get past the first line), never
//! panic, and what they accept holds the joint log's promises.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use joint_formats::import::candump::{self, DecodeOpts, Record};
use joint_formats::import::csv_map::{self, CsvOpts};
use joint_formats::import::eds::PdoMap;
use joint_formats::import::mcap::{self, McapOpts};
use joint_formats::log::JointLog;
use proptest::prelude::*;

fn check_log(log: &JointLog) {
    let n = log.t.len();
    assert!(n > 0 && log.q.len() == n);
    assert!(log.t.windows(2).all(|w| w[1] > w[0]), "time increases");
    for c in [&log.qd, &log.qdd, &log.u, &log.tau, &log.temp].into_iter().flatten() {
        assert_eq!(c.len(), n);
    }
}

fn piece() -> impl Strategy<Value = String> {
    prop::sample::select(vec![
        "t", "q", "time", "angle", ",", ";", "\t", "|", " ", "\n", "\r\n", "#", "1", "-2.5", "1,5", "1e3", "nan", "\"",
        "=", ":", "deg", "*2", "/0", "x",
    ])
    .prop_map(str::to_string)
}

fn line_piece() -> impl Strategy<Value = String> {
    prop::sample::select(vec![
        "(",
        ")",
        "1.000001",
        "0000000001.5",
        " ",
        "can0",
        "185",
        "12345678",
        "#",
        "##",
        "R",
        "00",
        "FF",
        "1",
        "\n",
        "20000004",
        "7FF",
        "800",
        "0102030405060708",
    ])
    .prop_map(str::to_string)
}

const EDS: &str = "[1800]\n[1800sub1]\nDefaultValue=$NODEID+0x180\n[1A00]\n[1A00sub0]\nDefaultValue=2\n\
    [1A00sub1]\nDefaultValue=0x23000110\n[1A00sub2]\nDefaultValue=0x23000210\n\
    [2300sub1]\nParameterName=q\nDataType=0x0003\nFactor=0.0001\n[2300sub2]\nParameterName=qd\nDataType=0x0003\n";

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn csv_maps_never_panic(text in prop::collection::vec(piece(), 0..60), map in prop::collection::vec(piece(), 0..12)) {
        let o = CsvOpts { map: format!("t=time,q=angle,{}", map.concat()), ..CsvOpts::default() };
        if let Ok((log, _)) = csv_map::convert(&format!("time,angle\n{}", text.concat()), "p.csv", &o) {
            check_log(&log);
        }
    }

    #[test]
    fn capture_lines_never_panic_and_round_trip(parts in prop::collection::vec(line_piece(), 0..12)) {
        let line = parts.concat();
        if let Ok(Some(r)) = Record::parse(&line) {
            prop_assert_eq!(Record::parse(&r.line()).unwrap(), Some(r));
        }
    }

    #[test]
    fn captures_decode_without_panic(lines in prop::collection::vec((0u64..3_000_000, prop::sample::select(vec![0x185u32, 0x705, 0x285]), prop::collection::vec(any::<u8>(), 0..9)), 0..40)) {
        let pdos = PdoMap::from_eds(EDS, "p.eds", 5).unwrap();
        let mut t = 0;
        let recs: Vec<Record> = lines.into_iter().map(|(dt, id, data)| {
            t += dt;
            Record { t_ns: t, iface: "can0".into(), id, extended: false, remote: false, fd_flags: None, data }
        }).collect();
        let o = DecodeOpts { node: 5, map: "q=q,qd=qd".into(), load_cell: false };
        if let Ok(d) = candump::decode(recs.iter().map(Record::view), &pdos, &o) {
            let log = JointLog::parse(d.csv.as_bytes(), "decoded").expect("decoded text is a joint log");
            check_log(&log);
            prop_assert_eq!(log.len(), d.rows);
        }
    }

    #[test]
    fn eds_text_never_panics(text in prop::collection::vec(prop::sample::select(vec![
        "[1800]\n", "[1A00]\n", "[1800sub1]\n", "[1A00sub0]\n", "[1A00sub1]\n", "[2300sub1]\n", "DefaultValue=", "ParameterValue=",
        "$NODEID+", "0x180", "0x23000110", "0x23000120", "3", "0", "DataType=", "0x0003", "0x0008", "Factor=", "0", "1e-3",
        "\n", "[", "=", ";c\n", "0xFFFFFFFF",
    ]), 0..80)) {
        let _ = PdoMap::from_eds(&text.concat(), "p.eds", 5);
    }

    #[test]
    fn mcap_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400), cut in 0usize..400) {
        let o = McapOpts { topic: "/joint_states".into(), joint: "j".into(), ..McapOpts::default() };
        let _ = mcap::convert(&bytes, "p.mcap", &o);
        // a real file's head with garbage after it
        let mut b = b"\x89MCAP0\r\n".to_vec();
        b.extend(bytes.iter().take(cut));
        let _ = mcap::convert(&b, "p.mcap", &o);
    }
}
