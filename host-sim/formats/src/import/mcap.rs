//! ROS 2 bags in MCAP (the default `ros2 bag` storage since Iron): one joint's
//! `sensor_msgs/msg/JointState` (position → `q`, velocity → `qd`, effort → `u`) and, when the
//! bag has one, a topic with the measured external torque (`tau`): `std_msgs/msg/Float64`
//! (`data`), `geometry_msgs/msg/WrenchStamped` (`wrench.torque` about one axis) or another
//! `JointState` (the effort of the same joint name).
//!
//! Messages are CDR (little or big endian, ROS 2's `cdr` message encoding), decoded here from
//! the message definitions' layouts; the bag's own schema name is checked, so a topic of another
//! type is refused with its name rather than misread. Time is the message header's stamp (the
//! sensor's time), or the bag's log time where a stamp is zero, relative to the first row.
//! `tau` is the last torque message at or before each joint state (no row before the first one);
//! without a torque topic, `tau = 0` (the effort is the only torque, as in the DFKI importer).

use crate::log::JointLog;

/// Which topics and joint to read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct McapOpts {
    /// the JointState topic (e.g. `/joint_states`)
    pub topic: String,
    /// the joint's name in `JointState.name`
    pub joint: String,
    /// optional topic with the measured external torque
    pub tau_topic: Option<String>,
    /// `WrenchStamped`: the torque's axis
    pub tau_axis: Axis,
}

/// An axis of a `WrenchStamped` torque.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    #[default]
    Z,
}

impl Axis {
    pub const NAMES: [(&'static str, Axis); 3] = [("x", Axis::X), ("y", Axis::Y), ("z", Axis::Z)];
}

/// A CDR reader over one message (offsets aligned from after the 4-byte encapsulation).
struct Cdr<'a> {
    buf: &'a [u8],
    pos: usize,
    le: bool,
}

impl<'a> Cdr<'a> {
    fn new(data: &'a [u8]) -> Result<Cdr<'a>, String> {
        let kind = data.get(..4).ok_or("message shorter than its CDR header")?;
        let le = match kind.get(1) {
            Some(0x01) | Some(0x03) => true,
            Some(0x00) | Some(0x02) => false,
            _ => return Err(format!("unknown CDR encapsulation {kind:02X?}")),
        };
        Ok(Cdr { buf: data.get(4..).unwrap_or(&[]), pos: 0, le })
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let align = n.min(8);
        self.pos = self.pos.div_ceil(align) * align;
        let s = self.buf.get(self.pos..self.pos + n).ok_or("message ends inside a field")?;
        self.pos += n;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, String> {
        let b: [u8; 4] = self.take(4)?.try_into().map_err(|_| "short u32")?;
        Ok(if self.le { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }

    fn f64(&mut self) -> Result<f64, String> {
        let b: [u8; 8] = self.take(8)?.try_into().map_err(|_| "short f64")?;
        Ok(if self.le { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }

    fn string(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        if n > self.buf.len() {
            return Err("string longer than the message".into());
        }
        let start = self.pos;
        let s = self.buf.get(start..start + n).ok_or("message ends inside a string")?;
        self.pos += n;
        let s = s.strip_suffix(&[0]).unwrap_or(s);
        Ok(String::from_utf8_lossy(s).into_owned())
    }

    fn f64_seq(&mut self) -> Result<Vec<f64>, String> {
        let n = self.u32()? as usize;
        if n > self.buf.len() / 8 + 1 {
            return Err("sequence longer than the message".into());
        }
        (0..n).map(|_| self.f64()).collect()
    }

    /// `std_msgs/Header`: the stamp in ns (frame_id skipped).
    fn header(&mut self) -> Result<u64, String> {
        let sec = self.u32()? as i32;
        let nsec = self.u32()?;
        self.string()?;
        Ok(if sec < 0 { 0 } else { sec as u64 * 1_000_000_000 + u64::from(nsec) })
    }
}

struct JointState {
    stamp: u64,
    names: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

fn joint_state(data: &[u8]) -> Result<JointState, String> {
    let mut c = Cdr::new(data)?;
    let stamp = c.header()?;
    let n = c.u32()? as usize;
    if n > data.len() {
        return Err("name sequence longer than the message".into());
    }
    let names = (0..n).map(|_| c.string()).collect::<Result<Vec<_>, _>>()?;
    Ok(JointState { stamp, names, position: c.f64_seq()?, velocity: c.f64_seq()?, effort: c.f64_seq()? })
}

const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
const FLOAT64: &str = "std_msgs/msg/Float64";
const WRENCH: &str = "geometry_msgs/msg/WrenchStamped";

/// One decoded torque sample: (time ns, value).
fn torque(schema: &str, data: &[u8], o: &McapOpts) -> Result<Option<(u64, f64)>, String> {
    match schema {
        FLOAT64 => {
            let mut c = Cdr::new(data)?;
            Ok(Some((0, c.f64()?)))
        }
        WRENCH => {
            let mut c = Cdr::new(data)?;
            let stamp = c.header()?;
            let v: Vec<f64> = (0..6).map(|_| c.f64()).collect::<Result<_, _>>()?;
            let k = match o.tau_axis {
                Axis::X => 3,
                Axis::Y => 4,
                Axis::Z => 5,
            };
            Ok(v.get(k).map(|&x| (stamp, x)))
        }
        JOINT_STATE => {
            let js = joint_state(data)?;
            let i = js.names.iter().position(|n| *n == o.joint);
            Ok(i.and_then(|i| js.effort.get(i)).map(|&x| (js.stamp, x)))
        }
        other => Err(format!("torque topic has type `{other}`; readable: {FLOAT64}, {WRENCH}, {JOINT_STATE}")),
    }
}

/// Reads the bag's bytes. Returns the log and notes.
pub fn convert(bytes: &[u8], file: &str, o: &McapOpts) -> Result<(JointLog, Vec<String>), String> {
    let stream = ::mcap::MessageStream::new(bytes).map_err(|e| format!("{file}: not an MCAP file: {e}"))?;
    let mut states: Vec<(u64, f64, Option<f64>, Option<f64>)> = Vec::new();
    let mut taus: Vec<(u64, f64)> = Vec::new();
    let mut topics: Vec<String> = Vec::new();
    let mut joints: Vec<String> = Vec::new();
    let mut absent = 0usize;
    for (k, m) in stream.enumerate() {
        let m = m.map_err(|e| format!("{file}: message {}: {e}", k + 1))?;
        let topic = &m.channel.topic;
        if !topics.contains(topic) {
            topics.push(topic.clone());
        }
        let schema = m.channel.schema.as_ref().map_or("", |s| s.name.as_str());
        let is_state = *topic == o.topic;
        let is_tau = o.tau_topic.as_deref() == Some(topic.as_str());
        if !is_state && !is_tau {
            continue;
        }
        if m.channel.message_encoding != "cdr" {
            return Err(format!("{file}: topic `{topic}` is encoded `{}`, not ROS 2 CDR", m.channel.message_encoding));
        }
        let at = |e: String| format!("{file}: topic `{topic}`, message {} (log time {} ns): {e}", k + 1, m.log_time);
        if is_state {
            if schema != JOINT_STATE {
                return Err(format!("{file}: topic `{topic}` has type `{schema}`, not {JOINT_STATE}"));
            }
            let js = joint_state(&m.data).map_err(at)?;
            for n in &js.names {
                if !joints.contains(n) {
                    joints.push(n.clone());
                }
            }
            let Some(i) = js.names.iter().position(|n| *n == o.joint) else {
                absent += 1;
                continue;
            };
            let Some(&q) = js.position.get(i) else {
                return Err(at(format!("no position for joint `{}`", o.joint)));
            };
            let stamp = if js.stamp == 0 { m.log_time } else { js.stamp };
            states.push((stamp, q, js.velocity.get(i).copied(), js.effort.get(i).copied()));
        } else if let Some((stamp, x)) = torque(schema, &m.data, o).map_err(at)? {
            taus.push((if stamp == 0 { m.log_time } else { stamp }, x));
        }
    }
    if states.is_empty() {
        return Err(if joints.is_empty() {
            format!("{file}: no {JOINT_STATE} on topic `{}` (topics in the bag: {})", o.topic, topics.join(", "))
        } else {
            format!("{file}: no joint `{}` on topic `{}` (its joints: {})", o.joint, o.topic, joints.join(", "))
        });
    }
    let mut notes = Vec::new();
    if absent > 0 {
        notes.push(format!("{absent} joint states without `{}`: skipped", o.joint));
    }
    states.sort_by_key(|s| s.0);
    taus.sort_by_key(|s| s.0);
    let has_qd = states.iter().all(|s| s.2.is_some());
    let has_u = states.iter().all(|s| s.3.is_some());
    if let Some(tt) = &o.tau_topic {
        if taus.is_empty() {
            return Err(format!("{file}: no torque on topic `{tt}` (topics in the bag: {})", topics.join(", ")));
        }
        if !has_u {
            return Err(format!("{file}: a torque topic needs the joint's effort in every joint state"));
        }
    }
    let mut log = JointLog {
        qd: has_qd.then(Vec::new),
        u: has_u.then(Vec::new),
        tau: has_u.then(Vec::new),
        ..JointLog::default()
    };
    let mut k = 0usize;
    let (mut early, mut repeated) = (0usize, 0usize);
    let mut t0: Option<u64> = None;
    let mut last: Option<u64> = None;
    for (stamp, q, qd, u) in states {
        while taus.get(k).is_some_and(|t| t.0 <= stamp) {
            k += 1;
        }
        let tau = match (&o.tau_topic, k.checked_sub(1).and_then(|i| taus.get(i))) {
            (None, _) => 0.0,
            (Some(_), Some(t)) => t.1,
            (Some(_), None) => {
                early += 1;
                continue;
            }
        };
        if last.is_some_and(|l| stamp <= l) {
            repeated += 1;
            continue;
        }
        last = Some(stamp);
        let base = *t0.get_or_insert(stamp);
        log.t.push((stamp - base) as f64 / 1e9);
        log.q.push(q);
        if let (Some(v), Some(x)) = (log.qd.as_mut(), qd) {
            v.push(x);
        }
        if let (Some(v), Some(x)) = (log.u.as_mut(), u) {
            v.push(x);
        }
        if let Some(v) = log.tau.as_mut() {
            v.push(tau);
        }
    }
    if early > 0 {
        notes.push(format!("{early} joint states before the first torque message: not written"));
    }
    if repeated > 0 {
        notes.push(format!("{repeated} joint states whose time did not increase: dropped"));
    }
    if has_u && o.tau_topic.is_none() {
        notes.push("no torque topic: tau = 0 (the effort is the only torque)".into());
    }
    if log.t.is_empty() {
        return Err(format!("{file}: no joint state after the first torque message"));
    }
    Ok((log, notes))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// A JointState in little-endian CDR, written by hand from the IDL layout.
    fn js(sec: i32, names: &[&str], pos: &[f64]) -> Vec<u8> {
        let mut b = vec![0u8, 1, 0, 0];
        let mut body: Vec<u8> = Vec::new();
        let align = |body: &mut Vec<u8>, n: usize| {
            while body.len() % n != 0 {
                body.push(0)
            }
        };
        let string = |body: &mut Vec<u8>, s: &str| {
            while body.len() % 4 != 0 {
                body.push(0)
            }
            body.extend((s.len() as u32 + 1).to_le_bytes());
            body.extend(s.as_bytes());
            body.push(0);
        };
        body.extend(sec.to_le_bytes());
        body.extend(5u32.to_le_bytes());
        string(&mut body, "base");
        align(&mut body, 4);
        body.extend((names.len() as u32).to_le_bytes());
        for n in names {
            string(&mut body, n);
        }
        for seq in [pos, &[], pos] {
            align(&mut body, 4);
            body.extend((seq.len() as u32).to_le_bytes());
            for x in seq {
                align(&mut body, 8);
                body.extend(x.to_le_bytes());
            }
        }
        b.extend(body);
        b
    }

    #[test]
    fn joint_state_cdr_is_read_by_name() {
        let m = js(3, &["hip", "knee"], &[0.25, -1.5]);
        let s = joint_state(&m).unwrap();
        assert_eq!(s.stamp, 3_000_000_005);
        assert_eq!(s.names, vec!["hip", "knee"]);
        assert_eq!(s.position, vec![0.25, -1.5]);
        assert!(s.velocity.is_empty());
        assert_eq!(s.effort, vec![0.25, -1.5]);
        assert!(joint_state(&m[..m.len() - 3]).is_err(), "a cut message is an error, not a short read");
    }
}
