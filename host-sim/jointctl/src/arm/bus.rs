//! Four joint nodes on one simulated CAN bus, each the core's CANopen [`Node`] as the board
//! runs it: parameters arrive by the real SDO push ([`transfer::push`]), each joint sends its
//! angle in TPDO1 and takes the three others' angles from its RPDO2..4 (object 0x2311, pointed
//! at the other joints' TPDO1), and its control step computes the gravity torque (`C_c`,
//! which is the gravity term alone here: no friction, inertia, spring or offset is pushed).

use super::cad::others_of;
use joint_can::master::Master;
use joint_can::sim_bus::{SharedSimBus, SimBus, SimDevice};
use joint_can::transfer::{self, PushOptions};
use joint_core::canopen::node::{MemoryStorage, NmtState, Node, NodeConfig, NMT_START, TPDO1_BASE};
use joint_core::canopen::od;
use joint_core::canopen::CanFrame;
use joint_core::params::RawParams;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Node id of joint `j` (0-based).
pub fn node_id(j: usize) -> u8 {
    j as u8 + 1
}

/// One joint: its node, the arm's motor angles it reads its own from, its last output.
pub struct ArmJoint {
    pub node: Node<MemoryStorage>,
    j: usize,
    angles: Arc<Mutex<[f64; 4]>>,
    last_us: Option<u64>,
    /// gravity torque of the last control step, N·m
    pub gravity: f32,
    /// the others' angles the node used in it (from its RPDOs), rad
    pub others: [f32; 3],
}

impl SimDevice for ArmJoint {
    fn on_frame(&mut self, t_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>) {
        self.node.process(t_us, Some(f), &mut |f| out.push(f));
    }
    fn tick(&mut self, t_us: u64, out: &mut Vec<CanFrame>) {
        let dt = self.last_us.map_or(1.0e-3, |l| t_us.saturating_sub(l).max(1) as f64 * 1e-6);
        self.last_us = Some(t_us);
        let q = self.angles.lock().map(|a| a.get(self.j).copied().unwrap_or(0.0)).unwrap_or(0.0);
        // a static pose: q̇ = q̈ = 0
        let o = self.node.control(t_us, q as f32, 0.0, 0.0, dt as f32);
        self.gravity = o.c_c;
        self.others = self.node.others();
        self.node.process(t_us, None, &mut |f| out.push(f));
    }
    fn period_us(&self) -> u64 {
        1000
    }
}

/// The bus, the master and the four joints.
pub struct ArmBus {
    pub master: Master,
    pub joints: Vec<Arc<Mutex<ArmJoint>>>,
    angles: Arc<Mutex<[f64; 4]>>,
}

fn lock<T>(m: &Mutex<T>) -> anyhow::Result<std::sync::MutexGuard<'_, T>> {
    m.lock().map_err(|_| anyhow::anyhow!("joint lock poisoned"))
}

impl ArmBus {
    /// Four fresh nodes (ids 1..=4) on a 1 Mbit/s bus, each RPDO2..4 wired to the other
    /// joints' TPDO1 in [`others_of`] order.
    pub fn new() -> anyhow::Result<ArmBus> {
        let angles = Arc::new(Mutex::new([0.0f64; 4]));
        let mut bus = SimBus::new(1_000_000);
        let mut joints = Vec::new();
        for j in 0..4 {
            let node = Node::new(NodeConfig::new(node_id(j)), MemoryStorage::default(), 0);
            let dev = Arc::new(Mutex::new(ArmJoint {
                node,
                j,
                angles: angles.clone(),
                last_us: None,
                gravity: 0.0,
                others: [0.0; 3],
            }));
            bus.attach(dev.clone());
            joints.push(dev);
        }
        let shared = SharedSimBus(Arc::new(Mutex::new(bus)));
        let mut master = Master::new(Box::new(shared));
        master.listen(Duration::from_millis(5))?;
        for j in 0..4 {
            for (k, &o) in others_of(j).iter().enumerate() {
                let cob = u32::from(TPDO1_BASE) + u32::from(node_id(o));
                master.write(node_id(j), od::RPDO_COMM + 1 + k as u16, 1, &cob.to_le_bytes())?;
            }
        }
        Ok(ArmBus { master, joints, angles })
    }

    /// Push one parameter set per joint (pre-operational, whole-set commit), then start all.
    pub fn push(&mut self, sets: &[RawParams]) -> anyhow::Result<()> {
        for (j, raw) in sets.iter().enumerate() {
            transfer::push(
                &mut self.master,
                node_id(j),
                raw,
                PushOptions { pre_operational: true, save: false },
                &mut |_| {},
            )
            .map_err(|e| anyhow::anyhow!("joint {}: {e}", j + 1))?;
        }
        self.master.nmt(0, NMT_START)?;
        self.master.listen(Duration::from_millis(5))?;
        for (j, d) in self.joints.iter().enumerate() {
            let st = lock(d)?.node.nmt_state();
            if st != NmtState::Operational {
                anyhow::bail!("joint {} did not go operational ({})", j + 1, st.name());
            }
        }
        Ok(())
    }

    /// Hold the arm at motor angles `q` and let the joints exchange their angles; returns each
    /// joint's gravity torque from its last control step, and the others' angles it used.
    pub fn hold(&mut self, q: &[f64; 4]) -> anyhow::Result<([f32; 4], [[f32; 3]; 4])> {
        *lock(&self.angles)? = *q;
        // TPDOs every 10 ms: after 30 ms every node has the new angles of all the others.
        self.master.listen(Duration::from_millis(30))?;
        let mut g = [0.0f32; 4];
        let mut o = [[0.0f32; 3]; 4];
        for (j, d) in self.joints.iter().enumerate() {
            let d = lock(d)?;
            if let (Some(gj), Some(oj)) = (g.get_mut(j), o.get_mut(j)) {
                *gj = d.gravity;
                *oj = d.others;
            }
        }
        Ok((g, o))
    }
}
