//! The control loop's tick is the core's ([`joint_core::control_loop`]): one loop for the
//! boards, the closed-loop experiments and another firmware on the core. Re-exported here for
//! the board's tasks.

pub use joint_core::control_loop::{ControlLoop, TickOutput};
