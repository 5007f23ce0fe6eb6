//! CAN FD on the simulated bus: FD joints' TPDO3 as FD frames with bit-rate switch, and the
//! bus load measured with the joints' real nodes (`jointctl bus-budget --measured`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::sim_bus::SimBus;
use joint_can::{timing, Bus};
use joint_core::canopen::node::{MemoryStorage, NodeConfig};
use joint_core::canopen::CanFrame;
use jointctl::cli::bus_budget::{load, measure};
use jointctl::sim_joint::{JointSim, SimStorage};
use std::sync::{Arc, Mutex};
use std::time::Duration;

#[test]
fn an_fd_joint_streams_its_state_as_32_byte_fd_frames_and_the_bus_times_them_so() {
    let mut bus = SimBus::new_fd(1_000_000, 5_000_000);
    let js =
        JointSim::with_config(NodeConfig::new(4).with_fd(true), None, SimStorage::Memory(MemoryStorage::default()), 0);
    bus.attach(Arc::new(Mutex::new(js)));
    bus.run_for(Duration::from_millis(2));
    bus.send(&CanFrame::new(0, &[1, 4]).unwrap()).unwrap();
    bus.run_for(Duration::from_millis(3));
    let before = bus.stats;
    bus.drain_inbox();
    bus.run_for(Duration::from_millis(100));
    let got = bus.drain_inbox();
    let tpdo: Vec<&CanFrame> = got.iter().filter(|f| f.id() == 0x384).collect();
    assert!((9..=11).contains(&tpdo.len()), "TPDO3 every 10 ms: {}", tpdo.len());
    for f in &tpdo {
        assert!(f.is_fd() && f.brs() && f.len() == 32 && f.dlc() == 13);
    }
    // the bus's busy time is the frames' ISO 11898-1 length: nominal 1 Mbit/s, data 5 Mbit/s
    let want: u64 = got.iter().map(|f| timing::frame_time_ns(f, 1_000_000, 5_000_000)).sum();
    assert_eq!(bus.stats.busy_ns - before.busy_ns, want);
    assert_eq!(bus.stats.fd_frames - before.fd_frames, tpdo.len() as u64);
    assert!(bus.describe().contains("CAN FD"));
}

#[test]
fn six_fd_joints_at_1_khz_load_the_bus_under_80_percent_and_classic_cannot_carry_them() {
    let fd = measure(6, 1, 1_000_000, Some(5_000_000)).unwrap();
    let classic = measure(6, 1, 1_000_000, None).unwrap();
    assert!(fd.load < 0.8, "FD 1/5 Mbit/s, 6 joints at 1 kHz: {:.3}", fd.load);
    assert!(classic.load > 0.8, "classic 1 Mbit/s: {:.3}", classic.load);
    // per ms: six TPDO3 and one shared command frame, all FD
    assert!((fd.fd_frames_per_s - 7000.0).abs() < 50.0, "{}", fd.fd_frames_per_s);
    assert!(fd.backlog <= 8, "the FD bus keeps up: {}", fd.backlog);
    // classic saturates: the frames wait
    assert!(classic.load > 0.99 && classic.backlog > 100, "{classic:?}");
    // the measurement agrees with the computed figure (worst-case stuffing bounds it)
    let (worst, _) = load(6, 1000.0, 1_000_000, Some(5_000_000));
    assert!(fd.load <= worst, "{} vs computed worst {worst}", fd.load);
    assert!(fd.load > 0.5 * worst);
    // one joint on classic: TPDO1, TPDO2 and the RPDO per ms, measured ≈ 31 %
    let one = measure(1, 1, 1_000_000, None).unwrap();
    assert!((0.25..0.35).contains(&one.load), "{}", one.load);
    assert!(one.backlog <= 3);
}
