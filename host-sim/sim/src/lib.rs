//! host-sim: the same joint core under std, around a simulated joint.
//!
//! - [`plant`] and [`effects`]: the simulated joint ("truth", f64) with the unmodelled effects
//!   and its sensors;
//! - [`scenario`] and [`sim`]: operator/load scenarios and the virtual-time loop that runs the
//!   firmware core's control step against the plant and writes a joint log.
//!
//! What it may depend on: the joint core (the controller under test, bit for bit the
//! firmware's), `joint-formats` (it reads plant/model files and writes joint logs), serde/toml,
//! rand. What it must not: the analysis (a simulator that imported the diagnosis could shape
//! its truth after the candidates), the CAN stack, a CLI framework. The simulated joint on a
//! CAN bus and the experiments live in `jointctl`, which combines this crate with the others.

// `!(x > 0.0)` is how this crate refuses NaN together with non-positive values; the
// `partial_cmp` form clippy suggests says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Numeric loops that index several parallel per-sample arrays with one index read better
// than the zipped and skipped iterators clippy would have instead.
#![allow(clippy::needless_range_loop)]

pub mod effects;
pub mod plant;
pub mod scenario;
pub mod sim;
