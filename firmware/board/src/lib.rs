//! The hardware-free half of the joint-board firmware.
//!
//! The board binary (`src/main.rs`, thumbv7em-none-eabihf only) is embassy tasks that move
//! bytes: a ticker, the timers, FDCAN, the flash. What those tasks decide lives here so it
//! builds and is unit-tested on the PC: the encoder and torque-output traits and the
//! quadrature unwrapping ([`io`]), one tick of the control loop around the core's CANopen
//! node ([`control_loop`]), the CAN frame plumbing (HAL ⇄ node frames, outbox, bus health;
//! [`can_link`]) and the node's parameter storage, a handoff to the flash-owning task
//! ([`storage`]).
#![cfg_attr(not(test), no_std)]

pub mod can_link;
pub mod control_loop;
pub mod io;
pub mod storage;
