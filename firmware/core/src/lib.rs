//! The hardware-free joint core.
//!
//! Everything that decides a torque lives here: the compensation models of the trunk-joint,
//! elastic-joint and arm-gravity papers, the one parameter table with its validation, and the
//! control step. The crate is `no_std`, allocation-free and never panics on input, so the same
//! code runs in the STM32G431 firmware, in host-sim, under QEMU and in fuzzers.
//!
//! Floating-point functions come from `libm` through [`math`], never from std's float
//! methods: with std linked those would silently win on the PC and host-sim would compute
//! other numbers than the chip.
#![no_std]
#![forbid(unsafe_code)]

pub mod canopen;
pub mod control;
pub mod control_loop;
pub mod fixed;
pub mod fixed_gravity;
pub mod math;
pub mod model;
pub mod params;
pub mod safety;
pub mod series;
pub mod store;
pub mod table;
pub mod vectors;
