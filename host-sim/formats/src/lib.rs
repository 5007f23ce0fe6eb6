//! joint-formats: the files users, joints and tools exchange (spec `shared/spec/formats.md`).
//!
//! - [`log`]: the joint-log CSV (spec §1), strict reader and writer;
//! - [`model_file`]: the model TOML (spec §2) ⇄ the core's parameters;
//! - [`import`]: converters from published data sets' files to joint logs;
//! - [`predict`]: the model's disturbance on a log and the residual against it;
//! - [`output`]: how every tool writes its outputs (never over an input, atomically for
//!   regular files, in place for devices, report folders as a whole).
//!
//! What it may depend on: the joint core (the parameter table the model file is checked
//! against, the control law the prediction runs), serde/toml and thiserror. What it must not:
//! the simulator, the CAN stack, the analysis, a CLI framework. Everything that reads or writes
//! these files (the simulator, the analysis, `jointctl`, a user's own tool) builds on this crate,
//! so the formats have one reader and one writer.

// `!(x > 0.0)` is how the readers refuse NaN together with non-positive values; the
// `partial_cmp` form clippy suggests says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Numeric loops that index several parallel per-sample arrays with one index read better
// than the zipped and skipped iterators clippy would have instead.
#![allow(clippy::needless_range_loop)]

pub mod import;
pub mod log;
pub mod model_file;
pub mod output;
pub mod predict;
pub mod vocab;
