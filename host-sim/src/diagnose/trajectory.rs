//! Trajectory mode (a log without `u`/`tau`): the model is integrated and compared with the
//! logged angle.

use super::{DiagError, Diagnosis, Options};
use crate::log::JointLog;
use crate::model_file::ModelFile;

pub fn diagnose(_log: &JointLog, _model: &ModelFile, _p: &joint_core::params::ParamSet, _o: &Options) -> Result<Diagnosis, DiagError> {
    Err(DiagError::Input("trajectory mode (a log without u and tau) is not supported yet".into()))
}
