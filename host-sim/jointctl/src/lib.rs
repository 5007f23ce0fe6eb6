//! jointctl: the host tool for the joint boards, and the experiments that combine the other
//! host crates.
//!
//! - [`cli`]: the `jointctl` subcommands, one module each;
//! - [`sim_joint`]: simulated joints (the firmware core's CANopen node around a `host-sim`
//!   plant) on any [`joint_can::Bus`], as `jointctl sim` serves them;
//! - [`closed_loop`]: the trunk paper's assistance trials with the core in the loop;
//! - [`arm`]: the arm paper's gravity fusion on four joint nodes;
//! - [`bench`]: the withheld-effect bench: logs from the simulator with an effect the model
//!   lacks, diagnosed blind. It lives here, not in the analysis, so the diagnosis cannot import
//!   the generator it is scored on.
//!
//! What it may depend on: every host crate (`joint-formats`, `host-sim`, `joint-can`,
//! `joint-analysis`), the joint core, clap, indicatif, anyhow. Nothing depends on it.

// `!(x > 0.0)` is how this crate refuses NaN together with non-positive values; the
// `partial_cmp` form clippy suggests says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Numeric loops that index several parallel per-sample arrays with one index read better
// than the zipped and skipped iterators clippy would have instead.
#![allow(clippy::needless_range_loop)]

pub mod arm;
pub mod bench;
pub mod cli;
pub mod closed_loop;
pub mod sim_joint;
