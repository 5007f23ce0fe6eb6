//! A CiA 301 CANopen node for the joint, sans-IO: frames and time in, frames out.
//!
//! - [`frame`]: the CAN frame type (classic and FD);
//! - `hal` (feature `embedded-can`): that frame to and from any HAL's `embedded_can::Frame`;
//! - [`od`]: the object dictionary, derived from [`crate::params::PARAMS`];
//! - [`sdo`]: abort codes and SDO frame layouts (server here, client in host-sim);
//! - [`pdo`]: the scaling of the process data;
//! - [`lss`]: the LSS slave (CiA 305), served by the node with the `lss` feature;
//! - [`node`]: the node itself — NMT, heartbeat, SDO, EMCY, PDOs, staged/committed parameters.
//!
//! We implement the subset ourselves rather than use zencan: zencan generates its object
//! dictionary from a TOML at build time, while ours must come from the one parameter table in
//! the core, with a staged/committed split and device-state checks it does not model.

pub mod frame;
#[cfg(feature = "embedded-can")]
pub mod hal;
pub mod lss;
pub mod node;
pub mod od;
pub mod outbox;
pub mod pdo;
pub mod pdo_map;
pub mod sdo;
pub mod storage;

pub use frame::CanFrame;
pub use node::{
    ControlStep, JointState, MemoryStorage, NmtState, NoStorage, Node, NodeConfig, ParamStorage, StorageError,
};
pub use sdo::Abort;
