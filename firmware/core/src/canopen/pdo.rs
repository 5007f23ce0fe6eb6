//! Scaling of the process data: every PDO value is a 16-bit integer with a fixed unit, chosen
//! so a joint's whole state fits one classic CAN frame (TPDO1 = 8 bytes) at a resolution
//! finer than the sensors'.
//!
//! | value | type | LSB | range |
//! |---|---|---|---|
//! | q, other joints' angles | i16 | 1e-4 rad (0.0057°) | ±3.2767 rad |
//! | q̇ | i16 | 1e-3 rad/s | ±32.767 rad/s |
//! | q̈ | i16 | 1e-2 rad/s² | ±327.67 rad/s² |
//! | τ (commanded, measured), assist command | i16 | 1e-2 N·m | ±327.67 N·m |
//! | temperature | i16 | 1e-2 °C | ±327.67 °C |
//! | faults | u16 | bit field of `safety::Faults` | |
//! | gain | u16 | 1/1000 of the safety layer's output gain | 0..=1000 |
//!
//! Values beyond the range saturate; NaN is sent as 0 (the fault bits then say why).
//!
//! TPDO1 (COB-ID 0x180 + node): `q, q̇, τ_cmd, faults`; TPDO2 (0x280 + node):
//! `q̈, τ_measured, temperature, gain`, all little-endian, at the event timer of 0x1800/0x1801
//! sub 5 (ms) while operational.

use crate::math;

pub const Q_LSB: f32 = 1.0e-4;
pub const QD_LSB: f32 = 1.0e-3;
pub const QDD_LSB: f32 = 1.0e-2;
pub const TAU_LSB: f32 = 1.0e-2;
pub const TEMP_LSB: f32 = 1.0e-2;

/// `x` in units of `lsb`, rounded to nearest, saturated to `±32767`; NaN → 0.
pub fn to_i16(x: f32, lsb: f32) -> i16 {
    let v = math::floor(x / lsb + 0.5);
    // `as` saturates and maps NaN to 0; clamp keeps -32768 free (symmetric range).
    math::clamp(v, -32767.0, 32767.0) as i16
}

/// The value of a scaled integer.
pub fn from_i16(v: i16, lsb: f32) -> f32 {
    f32::from(v) * lsb
}

/// TPDO1 decoded.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tpdo1 {
    pub q: f32,
    pub qd: f32,
    pub tau_cmd: f32,
    pub faults: u16,
}

/// TPDO2 decoded.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tpdo2 {
    pub qdd: f32,
    pub tau_measured: f32,
    pub temperature: f32,
    pub gain: f32,
}

fn word(d: &[u8], i: usize) -> Option<[u8; 2]> {
    Some([*d.get(i)?, *d.get(i + 1)?])
}

impl Tpdo1 {
    /// Decode an 8-byte TPDO1 payload; `None` if shorter.
    pub fn decode(d: &[u8]) -> Option<Tpdo1> {
        Some(Tpdo1 {
            q: from_i16(i16::from_le_bytes(word(d, 0)?), Q_LSB),
            qd: from_i16(i16::from_le_bytes(word(d, 2)?), QD_LSB),
            tau_cmd: from_i16(i16::from_le_bytes(word(d, 4)?), TAU_LSB),
            faults: u16::from_le_bytes(word(d, 6)?),
        })
    }
}

impl Tpdo2 {
    /// Decode an 8-byte TPDO2 payload; `None` if shorter.
    pub fn decode(d: &[u8]) -> Option<Tpdo2> {
        Some(Tpdo2 {
            qdd: from_i16(i16::from_le_bytes(word(d, 0)?), QDD_LSB),
            tau_measured: from_i16(i16::from_le_bytes(word(d, 2)?), TAU_LSB),
            temperature: from_i16(i16::from_le_bytes(word(d, 4)?), TEMP_LSB),
            gain: f32::from(u16::from_le_bytes(word(d, 6)?)) / 1000.0,
        })
    }
}
