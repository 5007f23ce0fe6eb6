//! The hardware-free half of the joint-board firmware.
//!
//! The board binary (`src/main.rs`, thumbv7em-none-eabihf only) is embassy tasks that move
//! bytes: a ticker, the timers, FDCAN, the flash. What those tasks decide lives here so it
//! builds and is unit-tested on the PC: the encoder and torque-output traits and the
//! quadrature unwrapping ([`io`]), one tick of the control loop around the core's
//! controller and safety layer ([`control_loop`]), and the CAN frame plumbing
//! (heartbeats, bus health; [`can_link`]).
#![cfg_attr(not(test), no_std)]

pub mod can_link;
pub mod control_loop;
pub mod io;
