//! joint-analysis: from a joint log and a model to what the data say about the joint.
//!
//! - [`identify`]: the papers' identification procedures (friction from constant-velocity
//!   plateaus, weight from static poses, inertia and offset from motion, the elastic joint's
//!   free oscillation, gravity tables) and the whole-log regression;
//! - [`plausible`]: the physics gate every model passes before it is written or pushed;
//! - [`diagnose`]: the sim-to-real gap: where it lies, which effect of the vocabulary (spec §3)
//!   causes it, how far it shrinks, scored on held-out data.
//!
//! The file formats it reads and writes are `joint-formats`, re-exported here ([`log`],
//! [`model_file`], [`import`], [`predict`]) so a user of the analysis needs this one crate.
//!
//! What it may depend on: the joint core (the model is evaluated by the firmware's own
//! f32 code), `joint-formats`, serde/serde_json, thiserror. What it must not: the simulator or
//! its effect code (the diagnosis's candidates own their shapes, so a bench drawn from the plant
//! can catch a shape they do not know), the CAN stack, serial ports, a CLI framework. The
//! withheld-effect benches that generate logs live outside this crate, where it cannot import
//! them. `scripts/test.sh` checks these rules with `cargo tree`.

// `!(x > 0.0)` is how this crate refuses NaN together with non-positive values; the
// `partial_cmp` form clippy suggests says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Numeric loops that index several parallel per-sample arrays with one index read better
// than the zipped and skipped iterators clippy would have instead.
#![allow(clippy::needless_range_loop)]

pub mod diagnose;
pub mod identify;
pub mod plausible;
pub mod plot;
pub mod prep;

pub use joint_formats::{import, log, model_file, predict};
