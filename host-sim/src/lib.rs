//! host-sim: the PC side of the joint.
//!
//! - [`log`]: the joint-log CSV (spec §1), strict reader and writer;
//! - [`model_file`]: the model TOML (spec §2) ⇄ the core's parameters;
//! - [`plant`] and [`effects`]: the simulated joint ("truth", f64) with the unmodelled effects;
//! - [`scenario`] and [`sim`]: operator/load scenarios and the virtual-time loop that runs the
//!   firmware core's control step against the plant;
//! - [`cli`]: the `jointctl` subcommands, one module each.

pub mod arm;
pub mod can;
pub mod cli;
pub mod closed_loop;
pub mod diagnose;
pub mod effects;
pub mod identify;
pub mod log;
pub mod model_file;
pub mod plant;
pub mod scenario;
pub mod sim;
