//! host-sim: the PC side of the joint.
//!
//! - [`log`]: the joint-log CSV (spec §1), strict reader and writer;
//! - [`model_file`]: the model TOML (spec §2) ⇄ the core's parameters;
//! - [`plant`] and [`effects`]: the simulated joint ("truth", f64) with the unmodelled effects;
//! - [`scenario`] and [`sim`]: operator/load scenarios and the virtual-time loop that runs the
//!   firmware core's control step against the plant;
//! - [`cli`]: the `jointctl` subcommands, one module each.

// `!(x > 0.0)` is how this crate refuses NaN together with non-positive values; the
// `partial_cmp` form clippy suggests says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Numeric loops that index several parallel per-sample arrays with one index read better
// than the zipped and skipped iterators clippy would have instead.
#![allow(clippy::needless_range_loop)]

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
