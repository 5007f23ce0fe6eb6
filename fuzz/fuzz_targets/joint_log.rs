//! Fuzz the joint-log CSV reader (spec §1): any bytes must give either a log or an error, never
//! a panic; a log that is accepted holds what the reader promises (every column as long as `t`,
//! every value finite, time strictly increasing), and writing it out and reading it back gives
//! the same log.
#![no_main]

use joint_formats::log::JointLog;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(log) = JointLog::parse(data, "fuzz.csv") else { return };
    let n = log.t.len();
    assert!(n > 0);
    assert_eq!(log.q.len(), n);
    for c in [&log.qd, &log.qdd, &log.u, &log.tau, &log.temp].into_iter().flatten() {
        assert_eq!(c.len(), n);
        assert!(c.iter().all(|x| x.is_finite()));
    }
    for (_, c) in &log.others {
        assert_eq!(c.len(), n);
    }
    assert!(log.t.iter().chain(&log.q).all(|x| x.is_finite()));
    assert!(log.t.windows(2).all(|w| w[1] > w[0]));
    let mut out = Vec::new();
    log.write_csv(&mut out).expect("writes to memory");
    let back = JointLog::parse(&out, "again.csv").expect("a written log reads back");
    assert_eq!(back.t, log.t);
    assert_eq!(back.q, log.q);
    assert_eq!(back.tau, log.tau);
});
