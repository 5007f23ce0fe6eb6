//! SocketCAN transport against a simulated joint on a virtual CAN interface (`vcan0`, or the
//! one named by `JOINT_VCAN`). Machines without vcan (no `vcan` module, no AF_CAN sockets, as
//! on our CI runners) cannot run it: the test then prints why and skips explicitly.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::master::Master;
use joint_can::socketcan::SocketCanBus;
use joint_can::Bus;
use joint_core::canopen::node::MemoryStorage;
use jointctl::sim_joint::{JointSim, SimStorage};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[test]
fn sdo_over_socketcan_when_a_vcan_interface_exists() {
    let iface = std::env::var("JOINT_VCAN").unwrap_or_else(|_| "vcan0".into());
    let master_bus = match SocketCanBus::open(&iface) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("SKIPPED: SocketCAN test needs a vcan interface ({e}); create one with `ip link add dev vcan0 type vcan && ip link set up vcan0`");
            return;
        }
    };
    let mut joint_bus = SocketCanBus::open(&iface).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let server = std::thread::spawn(move || {
        let mut j = JointSim::new(12, None, SimStorage::Memory(MemoryStorage::default()), joint_bus.now_us());
        let mut out = Vec::new();
        let mut next = joint_bus.now_us();
        while !s2.load(Ordering::SeqCst) {
            let now = joint_bus.now_us();
            if now >= next {
                j.step(now, &mut out);
                next += 1000;
            } else if let Some(f) = joint_bus.recv(Duration::from_micros(next - now)).unwrap() {
                j.receive(joint_bus.now_us(), &f, &mut out);
            }
            for f in out.drain(..) {
                joint_bus.send(&f).unwrap();
            }
        }
    });
    let mut m = Master::new(Box::new(master_bus));
    m.listen(Duration::from_millis(300)).unwrap();
    let r = m.read_u32(12, 0x1018, 2);
    let name = m.read_string(12, 0x1008, 0);
    stop.store(true, Ordering::SeqCst);
    server.join().unwrap();
    assert!(m.seen.contains_key(&12), "heartbeat of node 12 heard");
    assert_eq!(r.unwrap(), 0x4A4E_0001);
    assert_eq!(name.unwrap(), "joint-node");
}
