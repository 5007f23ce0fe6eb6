//! Parameter sets over SDO: `push` (stage every value, read it back, commit as a whole,
//! optionally save) and `pull` (read the set back into a `RawParams`).
//!
//! The push is one SDO transfer after another (CiA 301 allows one transfer per server at a
//! time): scalar values are expedited (request + response, 2 frames each); the gravity table
//! goes as its shape bytes and three segmented DOMAIN transfers, the gravity series as its term
//! count and one DOMAIN of 12-byte terms. Nothing runs on the joint
//! until the commit, which names the set by its CRC-32 (0x2205; the joint refuses a plain
//! commit), and the node checks the whole staged set then, so a push cut off anywhere before
//! the commit leaves the old set running, and what it staged can go live only whole (the
//! staged changes stay pending, `params_pending` = 1, until discarded: by [`push_verified`],
//! by writing 0 to 0x2200, or by the joint when the channel goes quiet for 3 s).

use super::master::{Master, SdoError};
use joint_core::canopen::node::NMT_PRE_OPERATIONAL;
use joint_core::canopen::od;
use joint_core::canopen::sdo::Abort;
use joint_core::params::{ParamId, RawParams, RawSeries, RawTable, PARAMS, PARAM_COUNT};
use joint_core::series::{TERMS_MAX, TERM_BYTES};
use joint_core::store::set_crc;
use joint_core::table::{AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};

/// One step of a push, for progress bars.
#[derive(Clone, Debug, PartialEq)]
pub struct Progress {
    pub done: usize,
    pub total: usize,
    pub what: String,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct PushOptions {
    /// send NMT pre-operational first (needed to change safety-relevant parameters)
    pub pre_operational: bool,
    /// persist the committed set (0x1010 "save")
    pub save: bool,
}

/// What a push did, with the figures for the performance check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PushReport {
    pub sdo_transfers: usize,
    pub frames: u64,
    /// bits of those frames on the wire, stuffing and intermission included
    pub bits: u64,
    /// bus-clock time from the first request to the last response, µs
    pub elapsed_us: u64,
    pub saved: bool,
    /// SDO transfers tried again after a lost frame
    pub retries: u32,
}

enum Op {
    Write { index: u16, sub: u8, data: Vec<u8>, what: String, safety: bool },
    Verify { index: u16, sub: u8, data: Vec<u8>, what: String },
    Commit,
    Save,
}

fn f32s(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(|x| x.to_le_bytes()).collect()
}

fn table_ops(t: &RawTable) -> Vec<(u16, u8, Vec<u8>, String)> {
    let mut v = Vec::new();
    let shape = |s: u8, b: u8, w: &str| (od::TABLE_SHAPE, s, vec![b], format!("gravity_table_shape.{w}"));
    v.push(shape(1, t.n_axes, "n_axes"));
    for (a, (src, pts)) in t.axis_source.iter().zip(t.points.iter()).enumerate() {
        v.push(shape(2 + a as u8, *src, &format!("axis_source_{a}")));
        v.push(shape(6 + a as u8, *pts, &format!("points_{a}")));
    }
    v.push(shape(10, u8::from(t.has_sigma), "has_sigma"));
    v.push(shape(11, u8::from(t.residual), "residual"));
    if t.n_axes > 0 {
        let n = (t.n_axes as usize).min(AXES_MAX);
        let cells = t.cells().min(CELLS_MAX);
        v.push((
            od::TABLE_GRID,
            0,
            f32s(t.grid.iter().take(n).flat_map(|r| r.iter().copied())),
            "gravity_table_grid".into(),
        ));
        v.push((od::TABLE_TORQUE, 0, f32s(t.torque.iter().take(cells).copied()), "gravity_table_torque".into()));
        if t.has_sigma {
            v.push((od::TABLE_SIGMA, 0, f32s(t.sigma.iter().take(cells).copied()), "gravity_table_sigma".into()));
        }
    }
    v
}

fn series_ops(s: &RawSeries) -> Vec<(u16, u8, Vec<u8>, String)> {
    let n = (s.n_terms as usize).min(TERMS_MAX);
    let mut v = vec![(od::SERIES_COUNT, 0, vec![s.n_terms], "gravity_series_count".to_string())];
    if n > 0 {
        let data = (0..n).flat_map(|k| s.term_bytes(k)).collect();
        v.push((od::SERIES_TERMS, 0, data, "gravity_series_terms".to_string()));
    }
    v
}

/// Attempts per SDO transfer when the bus loses frames: CiA 301 lets a client abort a transfer
/// that timed out and start it again (the server drops its half-done transfer on the new
/// initiate, and applies a download only once it is complete), so a lost frame costs a retry,
/// not the push.
pub const SDO_ATTEMPTS: u32 = 8;

/// Whether a failed transfer may be tried again: no answer, or an answer that shows the two
/// sides out of step (a lost segment's toggle, a late reply) — never a refusal of the value.
fn retryable(e: &SdoError) -> bool {
    match e {
        SdoError::Timeout { .. } | SdoError::Protocol { .. } => true,
        SdoError::Abort { code, .. } => {
            [Abort::Toggle.code(), Abort::Command.code(), Abort::Timeout.code()].contains(code)
        }
        SdoError::Io(_) => false,
    }
}

/// `op` with up to [`SDO_ATTEMPTS`] tries, aborting the server's transfer between them; the
/// retries are counted in `retries`.
fn retry<T>(
    m: &mut Master,
    node: u8,
    at: (u16, u8),
    retries: &mut u32,
    mut op: impl FnMut(&mut Master) -> Result<T, SdoError>,
) -> Result<T, SdoError> {
    let mut k = 1;
    loop {
        match op(m) {
            Err(e) if k < SDO_ATTEMPTS && retryable(&e) => {
                m.abort_transfer(node, at.0, at.1);
                *retries += 1;
                k += 1;
            }
            r => return r,
        }
    }
}

/// Push `raw` to `node`. `progress` is called after every SDO transfer.
pub fn push(
    m: &mut Master,
    node: u8,
    raw: &RawParams,
    opts: PushOptions,
    progress: &mut dyn FnMut(&Progress),
) -> anyhow::Result<PushReport> {
    push_until(m, node, raw, opts, progress, &std::sync::atomic::AtomicBool::new(false))
}

/// [`push`], stopping before the next transfer once `cancel` is set (Ctrl-C): nothing is
/// committed then, and the error says the push was interrupted.
pub fn push_until(
    m: &mut Master,
    node: u8,
    raw: &RawParams,
    opts: PushOptions,
    progress: &mut dyn FnMut(&Progress),
    cancel: &std::sync::atomic::AtomicBool,
) -> anyhow::Result<PushReport> {
    let mut ops = Vec::new();
    for d in PARAMS.iter() {
        let data = raw.get(d.id).to_le_bytes().to_vec();
        ops.push(Op::Write {
            index: od::PARAM_BASE + d.id.index() as u16,
            sub: 0,
            data,
            what: d.name.to_string(),
            safety: d.safety,
        });
    }
    let mut table = table_ops(&raw.table);
    table.extend(series_ops(&raw.series));
    for (index, sub, data, what) in &table {
        ops.push(Op::Write { index: *index, sub: *sub, data: data.clone(), what: what.clone(), safety: false });
    }
    for d in PARAMS.iter() {
        let data = raw.get(d.id).to_le_bytes().to_vec();
        ops.push(Op::Verify { index: od::PARAM_BASE + d.id.index() as u16, sub: 0, data, what: d.name.to_string() });
    }
    for (index, sub, data, what) in table {
        ops.push(Op::Verify { index, sub, data, what });
    }
    ops.push(Op::Commit);
    if opts.save {
        ops.push(Op::Save);
    }

    if opts.pre_operational {
        m.nmt(node, NMT_PRE_OPERATIONAL)?;
    }
    let frames0 = m.sdo_frames;
    let bits0 = m.sdo_bits;
    let t0 = m.bus.now_us();
    let total = ops.len();
    let mut transfers = 0usize;
    let mut retries = 0u32;
    for (k, op) in ops.into_iter().enumerate() {
        if cancel.load(std::sync::atomic::Ordering::SeqCst) {
            anyhow::bail!("interrupted after {k} of {total} transfers, before the commit");
        }
        let what = match op {
            Op::Write { index, sub, data, what, safety } => {
                transfers += 1;
                let mut written = retry(m, node, (index, sub), &mut retries, |m| m.write(node, index, sub, &data));
                if safety
                    && opts.pre_operational
                    && written.as_ref().is_err_and(|e| e.abort_code() == Some(Abort::DeviceState.code()))
                {
                    // NMT is unconfirmed: the command may have been lost on the bus. Again, once.
                    m.nmt(node, NMT_PRE_OPERATIONAL)?;
                    m.listen(std::time::Duration::from_millis(2))?;
                    retries += 1;
                    written = retry(m, node, (index, sub), &mut retries, |m| m.write(node, index, sub, &data));
                }
                match written {
                    Ok(()) => {}
                    Err(e) if safety && e.abort_code() == Some(Abort::DeviceState.code()) => {
                        // Refused because the node is not pre-operational: fine if the value is
                        // already the one we want (checked by the read-back), else say how.
                        transfers += 1;
                        let cur = retry(m, node, (index, sub), &mut retries, |m| m.read(node, index, sub))?;
                        if cur != data {
                            anyhow::bail!(
                                "node {node}: {what} is safety-relevant and differs ({} → {}); it can only change in pre-operational: push again with --pre-operational",
                                f32::from_le_bytes(cur.get(..4).and_then(|b| b.try_into().ok()).unwrap_or([0; 4])),
                                f32::from_le_bytes(data.get(..4).and_then(|b| b.try_into().ok()).unwrap_or([0; 4]))
                            );
                        }
                    }
                    Err(e) => return Err(anyhow::anyhow!("staging {what}: {e}")),
                }
                what
            }
            Op::Verify { index, sub, data, what } => {
                transfers += 1;
                let back = retry(m, node, (index, sub), &mut retries, |m| m.read(node, index, sub))
                    .map_err(|e| anyhow::anyhow!("reading back {what}: {e}"))?;
                if back != data {
                    anyhow::bail!("node {node}: {what} reads back {back:02X?}, {data:02X?} was written");
                }
                what
            }
            Op::Commit => {
                transfers += 1;
                // the commit names the set it commits: the node refuses it if anything wrote to
                // the staged set since it was read back (another master on the bus)
                let crc = set_crc(raw).to_le_bytes();
                if let Err(e) =
                    retry(m, node, (od::COMMIT_CRC, 0), &mut retries, |m| m.write(node, od::COMMIT_CRC, 0, &crc))
                {
                    if retryable(&e) {
                        anyhow::bail!("node {node}: no confirmation of the commit ({e}): whether the new set runs is not known yet");
                    }
                    let why = m.read_string(node, od::COMMIT_ERROR, 3).unwrap_or_default();
                    anyhow::bail!("node {node} refused the parameter set, the old set stays in force: {why} ({e})");
                }
                "commit".to_string()
            }
            Op::Save => {
                transfers += 1;
                retry(m, node, (od::STORE_PARAMETERS, 1), &mut retries, |m| {
                    m.write(node, od::STORE_PARAMETERS, 1, &od::SAVE_SIGNATURE.to_le_bytes())
                })
                .map_err(|e| anyhow::anyhow!("save: {e}"))?;
                "save".to_string()
            }
        };
        progress(&Progress { done: k + 1, total, what });
    }
    Ok(PushReport {
        sdo_transfers: transfers,
        frames: m.sdo_frames - frames0,
        bits: m.sdo_bits - bits0,
        elapsed_us: m.bus.now_us() - t0,
        saved: opts.save,
        retries,
    })
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    b.get(4 * i..4 * i + 4).and_then(|s| s.try_into().ok()).map_or(0.0, f32::from_le_bytes)
}

/// Read the node's parameter set (the staged values, which equal the running ones unless
/// `pending`). Returns the set and whether staged changes are pending. Every read is retried
/// on a lost frame.
pub fn pull(m: &mut Master, node: u8) -> Result<(RawParams, bool), SdoError> {
    let mut retries = 0;
    let mut read =
        |m: &mut Master, index: u16, sub: u8| retry(m, node, (index, sub), &mut retries, |m| m.read(node, index, sub));
    let mut raw = RawParams::defaults();
    for i in 0..PARAM_COUNT {
        let Some(id) = ParamId::from_index(i) else { continue };
        let b = read(m, od::PARAM_BASE + i as u16, 0)?;
        raw.set(id, f32_at(&b, 0));
    }
    let mut t = RawTable::EMPTY;
    let mut byte = |m: &mut Master, s: u8| -> Result<u8, SdoError> {
        Ok(read(m, od::TABLE_SHAPE, s)?.first().copied().unwrap_or(0))
    };
    t.n_axes = byte(m, 1)?;
    if t.n_axes > 0 {
        for a in 0..AXES_MAX {
            let (src, pts) = (byte(m, 2 + a as u8)?, byte(m, 6 + a as u8)?);
            if let (Some(s), Some(p)) = (t.axis_source.get_mut(a), t.points.get_mut(a)) {
                (*s, *p) = (src, pts);
            }
        }
        t.has_sigma = byte(m, 10)? == 1;
        t.residual = byte(m, 11)? == 1;
        let g = read(m, od::TABLE_GRID, 0)?;
        for (a, row) in t.grid.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x = f32_at(&g, a * AXIS_POINTS_MAX + k);
            }
        }
        let tq = read(m, od::TABLE_TORQUE, 0)?;
        for (k, x) in t.torque.iter_mut().enumerate() {
            *x = f32_at(&tq, k);
        }
        if t.has_sigma {
            let s = read(m, od::TABLE_SIGMA, 0)?;
            for (k, x) in t.sigma.iter_mut().enumerate() {
                *x = f32_at(&s, k);
            }
        }
    }
    raw.table = t;
    let n = read(m, od::SERIES_COUNT, 0)?.first().copied().unwrap_or(0);
    raw.series.n_terms = n;
    if n > 0 {
        let d = read(m, od::SERIES_TERMS, 0)?;
        for (k, c) in d.chunks_exact(TERM_BYTES).enumerate() {
            raw.series.set_term_bytes(k, c);
        }
    }
    let pending = read(m, od::PENDING, 0)?.first().copied().unwrap_or(0) == 1;
    Ok((raw, pending))
}

/// Which parameter set runs on the joint after a push, as read back from it.
#[derive(Clone, Debug, PartialEq)]
pub enum InForce {
    /// the pushed set, read back whole with nothing pending
    New,
    /// not the pushed set: the one the joint ran before (its commit is all or nothing), or the
    /// stored set it loaded when it reset
    Previous,
    /// the joint could not be read back: nobody knows
    Unknown(String),
}

/// A push and what it left on the joint.
#[derive(Clone, Debug)]
pub struct Verified {
    /// the last attempt's figures, when it ran to the end
    pub report: Option<PushReport>,
    /// whole pushes started (a joint that reset mid-push is pushed again, up to 3 times)
    pub attempts: u32,
    /// SDO transfers tried again, all attempts and the read-back together
    pub retries: u32,
    pub in_force: InForce,
    /// why the push did not complete (also set when the new set runs but a save failed)
    pub error: Option<String>,
}

impl Verified {
    /// The new set runs and everything asked for (the save included) was done.
    pub fn ok(&self) -> bool {
        self.in_force == InForce::New && self.error.is_none()
    }
}

/// Whole pushes to start when the joint resets in the middle of one.
pub const PUSH_ATTEMPTS: u32 = 3;

/// [`push`], then ask the joint which set runs (the CRC of its set in force, 0x2204:1, against
/// the pushed set's): the pushed one, the previous one, or unknown (the joint did not answer).
/// Lost frames are retried per transfer; a push that failed has its staged values discarded
/// (commit object ← 0) first, so nothing half-pushed waits for anyone's commit; a joint that
/// reset during the push (boot-up heard) is pushed again. Never reports the new set unless the
/// joint's own CRC of what runs says so.
pub fn push_verified(
    m: &mut Master,
    node: u8,
    raw: &RawParams,
    opts: PushOptions,
    progress: &mut dyn FnMut(&Progress),
) -> Verified {
    push_verified_until(m, node, raw, opts, progress, &std::sync::atomic::AtomicBool::new(false))
}

/// [`push_verified`] that stops once `cancel` is set (Ctrl-C): what was staged is discarded and
/// the joint's set in force read back, so an interrupted push leaves nothing staged and says
/// which set runs. Not pushed again after an interruption.
pub fn push_verified_until(
    m: &mut Master,
    node: u8,
    raw: &RawParams,
    opts: PushOptions,
    progress: &mut dyn FnMut(&Progress),
    cancel: &std::sync::atomic::AtomicBool,
) -> Verified {
    let want = set_crc(raw);
    let mut attempts = 0;
    let mut retries = 0;
    loop {
        attempts += 1;
        let boots0 = m.seen.get(&node).map_or(0, |s| s.boots);
        let pushed = push_until(m, node, raw, opts, progress, cancel);
        let (report, error) = match pushed {
            Ok(r) => {
                retries += r.retries;
                (Some(r), None)
            }
            Err(e) => (None, Some(e.to_string())),
        };
        // what runs: the CRC of the set in force (0x2204:1) against the pushed set's; a failed
        // push first discards what it staged, so nothing half-pushed waits for a commit
        let read_back = (|| {
            if error.is_some() {
                retry(m, node, (od::COMMIT, 0), &mut retries, |m| m.write(node, od::COMMIT, 0, &[0]))?;
            }
            retry(m, node, (od::PARAMS_CRC, 1), &mut retries, |m| m.read_u32(node, od::PARAMS_CRC, 1))
        })();
        let rebooted = m.seen.get(&node).map_or(0, |s| s.boots) > boots0;
        let in_force = match read_back {
            Ok(crc) if crc == want => InForce::New,
            Ok(_) if rebooted && attempts < PUSH_ATTEMPTS && !cancel.load(std::sync::atomic::Ordering::SeqCst) => {
                continue
            }
            Ok(_) => InForce::Previous,
            Err(e) => InForce::Unknown(format!("reading the set in force from node {node} failed: {e}")),
        };
        let error = match (&in_force, error) {
            (InForce::Previous, None) => Some(format!(
                "node {node} runs a set other than the one pushed{}",
                if rebooted { " (it reset during the push and loaded its stored set)" } else { "" }
            )),
            // the commit landed though its confirmation was lost (a failed push has no report):
            // the push did its job unless a save was asked for
            (InForce::New, Some(_)) if !opts.save => None,
            (_, e) => e,
        };
        return Verified { report, attempts, retries, in_force, error };
    }
}

/// The wire-time minimum of a push's SDO frames at `bitrate`, µs.
pub fn wire_minimum_us(r: &PushReport, bitrate: u32) -> f64 {
    r.bits as f64 * 1e6 / f64::from(bitrate.max(1))
}

/// What a push's elapsed time may be held against. The wire minimum of its frames means
/// something only where the frames cross a wire at a known bit rate: the simulated bus (its
/// bit-timing model and virtual clock), a SocketCAN interface that reports its bit timing, an
/// slcan adapter whose user says its bus runs at the rate given. A pty (`socat`) has no bit
/// timing: a push over one was printed at 0.484 of a "wire minimum" it never had.
#[derive(Clone, Debug, PartialEq)]
pub enum TimeBasis {
    /// frames on a wire at this nominal bit rate, `how` it is known
    Wire { bitrate: u32, how: &'static str },
    /// host and transport time only, and why there is no wire to compare with
    Host { why: String },
}

impl TimeBasis {
    /// The basis of a push on `spec`: `slcan_is_real` says the slcan adapter drives a real bus
    /// at the spec's bit rate; `sim_bitrate` is the simulated bus's; `socketcan_bitrate` the
    /// interface's own, if it reports one.
    pub fn of(
        spec: &super::BusSpec,
        slcan_is_real: bool,
        sim_bitrate: u32,
        socketcan_bitrate: impl FnOnce(&str) -> Option<u32>,
    ) -> TimeBasis {
        use super::BusSpec;
        match spec {
            BusSpec::Sim => TimeBasis::Wire { bitrate: sim_bitrate, how: "the simulated bus's bit timing" },
            BusSpec::Slcan { bitrate, .. } if slcan_is_real => {
                TimeBasis::Wire { bitrate: *bitrate, how: "the adapter's bus rate, as stated (--real-bus)" }
            }
            BusSpec::Slcan { path, .. } => TimeBasis::Host {
                why: format!(
                    "slcan {path} may be a pty or a link to another program, which has no bit timing \
                     (--real-bus says it is an adapter on a real bus at its @BITRATE)"
                ),
            },
            BusSpec::SocketCan { iface } => match socketcan_bitrate(iface) {
                Some(bitrate) => TimeBasis::Wire { bitrate, how: "the interface's bit timing" },
                None => TimeBasis::Host {
                    why: format!("{iface} reports no bit timing (a vcan, or its settings cannot be read)"),
                },
            },
            BusSpec::Replay { .. } => TimeBasis::Host { why: "a replayed capture is no bus".into() },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BusSpec;

    #[test]
    fn only_a_bus_with_bit_timing_gets_a_wire_minimum() {
        let slcan = BusSpec::Slcan { path: "/tmp/canA".into(), bitrate: 500_000 };
        let none = |_: &str| None;
        assert_eq!(
            TimeBasis::of(&BusSpec::Sim, false, 250_000, none),
            TimeBasis::Wire { bitrate: 250_000, how: "the simulated bus's bit timing" }
        );
        assert!(
            matches!(TimeBasis::of(&slcan, false, 1_000_000, none), TimeBasis::Host { why } if why.contains("pty"))
        );
        assert!(matches!(TimeBasis::of(&slcan, true, 1_000_000, none), TimeBasis::Wire { bitrate: 500_000, .. }));
        let can0 = BusSpec::SocketCan { iface: "can0".into() };
        assert!(matches!(
            TimeBasis::of(&can0, false, 1_000_000, |_| Some(125_000)),
            TimeBasis::Wire { bitrate: 125_000, .. }
        ));
        let vcan = BusSpec::SocketCan { iface: "vcan0".into() };
        assert!(
            matches!(TimeBasis::of(&vcan, false, 1_000_000, none), TimeBasis::Host { why } if why.contains("vcan0"))
        );
        let replay = BusSpec::Replay { path: "x.log".into() };
        assert!(matches!(TimeBasis::of(&replay, true, 1_000_000, none), TimeBasis::Host { .. }));
    }
}
