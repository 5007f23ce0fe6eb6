//! The model evaluated on a log: the disturbance the model file predicts at every sample, the
//! residual against the logged `u − tau`, and its RMS. One definition for the simulator's run
//! summary, identification, diagnosis and the tests, computed by the core's own f32
//! `control::disturbance`, so a residual here is what the joint itself would see.

use joint_core::control;
use joint_core::params::ParamSet;

use crate::log::JointLog;

/// The model's predicted disturbance at every sample of a torque-mode log (needs qd and qdd).
/// `other_columns` names the log columns feeding `others` (see `ModelFile::other_columns`).
pub fn predicted(log: &JointLog, p: &ParamSet, other_columns: &[String]) -> Option<Vec<f64>> {
    let (qd, qdd) = (log.qd.as_ref()?, log.qdd.as_ref()?);
    let others: Vec<&[f64]> = other_columns.iter().map(|n| log.other(n)).collect::<Option<Vec<_>>>()?;
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
                f64::from(control::disturbance(p, q, v, a, &o))
            })
            .collect(),
    )
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
