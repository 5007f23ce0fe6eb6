//! The model evaluated on a log: the disturbance the model file predicts at every sample, the
//! residual against the logged `u − tau`, and its RMS. One definition for the simulator's run
//! summary, identification, diagnosis and the tests, computed by the core's own f32
//! `control::disturbance_stateful`, so a residual here is what the joint itself would see.
//!
//! With `[presliding]` the prediction is stateful: the Dahl friction state is advanced through
//! the samples in log order, from a fresh state primed at the first sample, exactly as the
//! joint's controller carries it from a parameter commit. The numbers are the joint's to the
//! bit for samples inside the core's input limits (|q| ≤ 1e3 rad, |q̇| ≤ 1e3 rad/s,
//! |q̈| ≤ 1e6 rad/s², which the controller clamps to). A prediction on a slice of a log starts
//! its own state at the slice's first sample, so it can differ from the same samples' prediction
//! on the whole log for the first pre-sliding distance of travel.
//!
//! The measured load a load-dependent friction grows with is the log's `tau` (the load cell
//! the joint reads): 0 where the log has no `tau`, as on a joint without one.

use joint_core::control::{self, Dahl};
use joint_core::params::ParamSet;

use crate::log::JointLog;

/// The model's predicted disturbance at every sample of a torque-mode log (needs qd and qdd).
/// `other_columns` names the log columns feeding `others` (see `ModelFile::other_columns`).
pub fn predicted(log: &JointLog, p: &ParamSet, other_columns: &[String]) -> Option<Vec<f64>> {
    let (qd, qdd) = (log.qd.as_ref()?, log.qdd.as_ref()?);
    let others: Vec<&[f64]> = other_columns.iter().map(|n| log.other(n)).collect::<Option<Vec<_>>>()?;
    let mut dahl = Dahl::new();
    Some(
        (0..log.len())
            .map(|i| {
                let mut o = [0.0f32; 3];
                for (dst, col) in o.iter_mut().zip(others.iter()) {
                    *dst = col.get(i).copied().unwrap_or(0.0) as f32;
                }
                let q = log.q.get(i).copied().unwrap_or(0.0) as f32;
                let v = qd.get(i).copied().unwrap_or(0.0) as f32;
                let a = qdd.get(i).copied().unwrap_or(0.0) as f32;
                let load = log.tau.as_ref().and_then(|t| t.get(i)).copied().unwrap_or(0.0) as f32;
                // Presliding off: the stateless `control::disturbance`, bit for bit.
                f64::from(control::disturbance_stateful(p, &mut dahl, q, v, a, &o, load))
            })
            .collect(),
    )
}

/// The Dahl friction state F (N·m) at every sample of a log, as [`predicted`] carries it (all
/// zero when the model has no `[presliding]`). Needs qd, which primes the state at the first
/// sample; the angle alone moves it after that.
pub fn presliding_force(log: &JointLog, p: &ParamSet) -> Option<Vec<f64>> {
    let qd = log.qd.as_ref()?;
    if !p.terms().presliding.on {
        return Some(vec![0.0; log.len()]);
    }
    let mut dahl = Dahl::new();
    Some(log.q.iter().zip(qd).map(|(&q, &v)| f64::from(dahl.update(p, q as f32, v as f32))).collect())
}

/// `d − prediction` per sample of a torque-mode log, `None` without u/tau/qd/qdd.
pub fn residual(log: &JointLog, p: &ParamSet, other_columns: &[String]) -> Option<Vec<f64>> {
    let (u, tau) = (log.u.as_ref()?, log.tau.as_ref()?);
    let pred = predicted(log, p, other_columns)?;
    Some(u.iter().zip(tau).zip(pred).map(|((u, t), m)| u - t - m).collect())
}

pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}
