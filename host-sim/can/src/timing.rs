//! Bit-level length of CAN frames, bit stuffing included, for bus-load and latency figures.
//!
//! Classic CAN (ISO 11898-1), base format data frame: SOF, 11-bit id, RTR, IDE, r0, 4-bit DLC,
//! 8·n data bits and the 15-bit CRC are subject to bit stuffing (after five equal bits a
//! complementary bit is inserted, and the stuff bit itself starts the next run); CRC delimiter,
//! ACK slot and delimiter, 7-bit EOF and the 3-bit intermission are not. [`classic_bits`]
//! builds the real bit sequence (CRC-15 computed) and counts the stuff bits it needs;
//! [`classic_bits_worst`] is the textbook bound `47 + 8n + ⌊(34 + 8n − 1)/4⌋`.
//!
//! CAN FD (ISO 11898-1:2015), base format with bit-rate switch: the arbitration phase (SOF, id,
//! RRS, IDE, FDF, res, BRS) and the tail (CRC delimiter, ACK, EOF, intermission) run at the
//! nominal rate; ESI, DLC, data, stuff count and CRC (17 bits up to 16 data bytes, 21 above) at
//! the data rate. The CRC field has fixed stuff bits (one every four bits plus one before the
//! stuff count), so only header and data are dynamically stuffed: counted on the real bits for
//! [`fd_time_ns`], bounded by one stuff bit per four bits for the worst case. The bit-rate
//! switch happens at the sample points of BRS and CRC delimiter; we count those bits whole at
//! the nominal rate, a slight over-estimate (< 1 nominal bit per frame).
//!
//! The FD field layout (ISO 11898-1:2015 §10.4.2, fig. 21/22), base format:
//!
//! | field | bits | rate (BRS = 1) | stuffing |
//! |---|---|---|---|
//! | SOF, identifier, RRS, IDE, FDF, res, BRS | 1 + 11 + 5 = 17 | nominal | dynamic |
//! | ESI, DLC, data | 1 + 4 + 8n | data | dynamic |
//! | stuff count (3-bit Gray + parity) | 4 | data | fixed: 1 before it |
//! | CRC | 17 (n ≤ 16) or 21 | data | fixed: 1 after every 4 bits |
//! | CRC delimiter, ACK slot, ACK delimiter, EOF, intermission | 1 + 1 + 1 + 7 + 3 | nominal | none |
//!
//! So a frame without dynamic stuff bits is 30 nominal bits and `5 + 8n + 4 + 17 + 6` (CRC-17)
//! or `5 + 8n + 4 + 21 + 7` (CRC-21) data bits. Without BRS every bit runs at the nominal rate.

/// Bits after the stuffed part: CRC delimiter 1, ACK slot 1, ACK delimiter 1, EOF 7, IFS 3.
const CLASSIC_TAIL: u32 = 13;

/// CRC-15/CAN over a bit sequence.
fn crc15(bits: &[bool]) -> u16 {
    let mut crc: u16 = 0;
    for &b in bits {
        let nxt = b ^ ((crc >> 14) & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if nxt {
            crc ^= 0x4599;
        }
    }
    crc
}

fn push_bits(v: &mut Vec<bool>, value: u32, n: u32) {
    for i in (0..n).rev() {
        v.push((value >> i) & 1 == 1);
    }
}

/// Stuff bits a bit sequence needs (runs of five equal bits; a stuff bit starts a new run).
pub fn stuff_count(bits: &[bool]) -> u32 {
    let mut count = 0;
    let mut run = 0;
    let mut last = None;
    for &b in bits {
        if Some(b) == last {
            run += 1;
        } else {
            run = 1;
            last = Some(b);
        }
        if run == 5 {
            count += 1;
            // the stuff bit is the complement and begins a run of one
            last = Some(!b);
            run = 1;
        }
    }
    count
}

/// The unstuffed bits of a classic base-format data frame from SOF through the CRC.
fn classic_stuffed_region(id: u16, data: &[u8]) -> Vec<bool> {
    let mut v = Vec::with_capacity(34 + 8 * data.len() + 15);
    v.push(false); // SOF (dominant)
    push_bits(&mut v, u32::from(id & 0x7FF), 11);
    v.push(false); // RTR (data frame)
    v.push(false); // IDE (base format)
    v.push(false); // r0
    push_bits(&mut v, data.len().min(8) as u32, 4);
    for &b in data.iter().take(8) {
        push_bits(&mut v, u32::from(b), 8);
    }
    let crc = crc15(&v);
    push_bits(&mut v, u32::from(crc), 15);
    v
}

/// Bits on the wire of a classic data frame with this id and payload, intermission included.
pub fn classic_bits(id: u16, data: &[u8]) -> u32 {
    let v = classic_stuffed_region(id, data);
    v.len() as u32 + stuff_count(&v) + CLASSIC_TAIL
}

/// Worst-case bits of a classic data frame with `n` data bytes, intermission included.
pub fn classic_bits_worst(n: usize) -> u32 {
    let n = n.min(8) as u32;
    47 + 8 * n + (34 + 8 * n - 1) / 4
}

use joint_core::canopen::CanFrame;

/// Valid CAN FD payload sizes.
pub const FD_SIZES: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// The smallest FD payload size that holds `n` bytes (frames are padded up to it).
pub fn fd_size(n: usize) -> usize {
    FD_SIZES.iter().copied().find(|&s| s >= n).unwrap_or(64)
}

fn fd_dlc(size: usize) -> u32 {
    FD_SIZES.iter().position(|&s| s == size).unwrap_or(15) as u32
}

/// Nominal-phase and data-phase bits of an FD frame with bit-rate switch: (nominal, data).
/// `worst`: bound the dynamic stuffing instead of counting it.
pub fn fd_bits(id: u16, data: &[u8], worst: bool) -> (u32, u32) {
    fd_bits_brs(id, data, true, worst)
}

/// [`fd_bits`] with the BRS bit as given (it is one of the stuffed bits; without BRS the
/// caller times both parts at the nominal rate).
pub fn fd_bits_brs(id: u16, data: &[u8], brs: bool, worst: bool) -> (u32, u32) {
    let size = fd_size(data.len());
    let mut arb = Vec::with_capacity(17);
    arb.push(false); // SOF
    push_bits(&mut arb, u32::from(id & 0x7FF), 11);
    arb.extend([false, false, true, false, brs]); // RRS, IDE, FDF (recessive), res, BRS
    let mut dat = Vec::with_capacity(5 + 8 * size);
    dat.push(false); // ESI (error active)
    push_bits(&mut dat, fd_dlc(size), 4);
    for i in 0..size {
        push_bits(&mut dat, u32::from(data.get(i).copied().unwrap_or(0)), 8);
    }
    let (s_arb, s_dat) = if worst {
        ((arb.len() as u32 - 1) / 4, (dat.len() as u32).div_ceil(4))
    } else {
        // Count stuffing over the whole dynamic region: runs continue across the BRS point.
        let mut all = arb.clone();
        all.extend_from_slice(&dat);
        let total = stuff_count(&all);
        let a = stuff_count(&arb);
        (a, total - a)
    };
    let crc_len: u32 = if size <= 16 { 17 } else { 21 };
    // stuff count field: 3-bit gray count + parity; fixed stuff bits: one before the stuff
    // count and one after every 4 bits of stuff count + CRC.
    let fixed = 1 + (4 + crc_len) / 4;
    let nominal = arb.len() as u32 + s_arb + CLASSIC_TAIL;
    let data_bits = dat.len() as u32 + s_dat + 4 + crc_len + fixed;
    (nominal, data_bits)
}

/// Bits of a frame as the node makes it, classic or FD: (at the nominal rate, at the data
/// rate); an FD frame without BRS has all its bits at the nominal rate.
pub fn frame_bits(f: &CanFrame) -> (u32, u32) {
    if !f.is_fd() {
        return (classic_bits(f.id(), f.data()), 0);
    }
    let (n, d) = fd_bits_brs(f.id(), f.data(), f.brs(), false);
    if f.brs() {
        (n, d)
    } else {
        (n + d, 0)
    }
}

/// Time on the wire of a frame, ns, intermission included: the data phase of an FD frame with
/// BRS at `data_rate`, everything else at `nominal`.
pub fn frame_time_ns(f: &CanFrame, nominal: u32, data_rate: u32) -> u64 {
    let (n, d) = frame_bits(f);
    u64::from(n) * 1_000_000_000 / u64::from(nominal.max(1))
        + u64::from(d) * 1_000_000_000 / u64::from(data_rate.max(1))
}

/// Time on the wire of a classic frame, ns.
pub fn classic_time_ns(id: u16, data: &[u8], bitrate: u32) -> u64 {
    u64::from(classic_bits(id, data)) * 1_000_000_000 / u64::from(bitrate.max(1))
}

/// Time on the wire of an FD frame with bit-rate switch, ns.
pub fn fd_time_ns(id: u16, data: &[u8], nominal: u32, data_rate: u32, worst: bool) -> u64 {
    let (n, d) = fd_bits(id, data, worst);
    u64::from(n) * 1_000_000_000 / u64::from(nominal.max(1))
        + u64::from(d) * 1_000_000_000 / u64::from(data_rate.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worst_case_matches_the_textbook_bound() {
        // Davis et al. 2007: 135 bits for 8 bytes, 55 for 0 bytes (intermission included).
        assert_eq!(classic_bits_worst(8), 135);
        assert_eq!(classic_bits_worst(0), 55);
        for n in 0..=8 {
            for id in [0u16, 0x7FF, 0x555, 0x185, 0x605] {
                for pattern in [0x00u8, 0xFF, 0x55, 0x0F] {
                    let d = vec![pattern; n];
                    let b = classic_bits(id, &d);
                    assert!(b <= classic_bits_worst(n), "id {id:03X} n {n} pattern {pattern:02X}: {b}");
                    assert!(b >= 47 + 8 * n as u32, "at least the unstuffed length");
                }
            }
        }
    }

    #[test]
    fn stuffing_counts_runs_of_five() {
        assert_eq!(stuff_count(&[false; 5]), 1);
        assert_eq!(stuff_count(&[false; 4]), 0);
        // 00000 [1] 0000: the stuff bit starts a run, four more zeros need no second one ...
        assert_eq!(stuff_count(&[false; 9]), 1);
        // ... a fifth does
        assert_eq!(stuff_count(&[false; 10]), 2);
        assert_eq!(stuff_count(&[true, false, true, false, true]), 0);
    }

    #[test]
    fn crc15_known_value() {
        // All-zero frame id 0, dlc 0: CRC of 19 zero bits is 0; so the frame has long zero
        // runs and needs many stuff bits.
        let v = classic_stuffed_region(0, &[]);
        assert_eq!(v.len(), 34);
        assert_eq!(crc15(&v[..19]), 0);
        assert!(classic_bits(0, &[]) > 47);
    }

    /// Hand count (ISO 11898-1:2015 field layout, module doc): id 0x555 and 0x55 bytes
    /// alternate, so no dynamic stuff bit is due (the longest run is the DLC's trailing zeros
    /// into the first data bit: 4).
    #[test]
    fn fd_frame_lengths_match_hand_counts() {
        // 8 bytes (DLC 1000, CRC-17): nominal 17 + 13 = 30; data 1 + 4 + 64 + 4 + 17 + 6 = 96
        let f8 = CanFrame::new_fd(0x555, &[0x55; 8], true).unwrap();
        assert_eq!(frame_bits(&f8), (30, 96));
        // 1/5 Mbit/s: 30 µs + 96 × 0.2 µs = 49.2 µs
        assert_eq!(frame_time_ns(&f8, 1_000_000, 5_000_000), 49_200);
        // 16 bytes (DLC 1010): still CRC-17: data 1 + 4 + 128 + 4 + 17 + 6 = 160
        let f16 = CanFrame::new_fd(0x555, &[0x55; 16], true).unwrap();
        assert_eq!(frame_bits(&f16), (30, 160));
        // 32 bytes (DLC 1101, CRC-21): data 1 + 4 + 256 + 4 + 21 + 7 = 293 → 30 + 58.6 µs
        let f32b = CanFrame::new_fd(0x555, &[0x55; 32], true).unwrap();
        assert_eq!(frame_bits(&f32b), (30, 293));
        assert_eq!(frame_time_ns(&f32b, 1_000_000, 5_000_000), 88_600);
        // 64 bytes (DLC 1111): data 1 + 4 + 512 + 4 + 21 + 7 = 549 → 30 + 109.8 µs: six joints
        // at 1 kHz would need 83.9 % of the bus for these frames alone
        let f64b = CanFrame::new_fd(0x555, &[0x55; 64], true).unwrap();
        assert_eq!(frame_bits(&f64b), (30, 549));
        assert_eq!(frame_time_ns(&f64b, 1_000_000, 5_000_000), 139_800);
        // without BRS every bit at the nominal rate (BRS dominant: 0,1,0,0,1,0,0 has no run of 5)
        let slow = CanFrame::new_fd(0x555, &[0x55; 8], false).unwrap();
        assert_eq!(frame_bits(&slow), (126, 0));
        // a classic frame: 0x555, 8 × 0x55: 47 + 64 = 111 bits plus its stuff bits
        let c = CanFrame::new(0x555, &[0x55; 8]).unwrap();
        assert_eq!(frame_bits(&c), (classic_bits(0x555, &[0x55; 8]), 0));
        assert!(classic_bits(0x555, &[0x55; 8]) >= 111);
    }

    /// Dynamic stuffing in the FD data phase: eight 0x00 bytes after DLC 1000 are a run of
    /// 3 + 64 zeros: a stuff bit (a one) after every fifth zero; each starts a run of its own,
    /// so the next is due five zeros later.
    #[test]
    fn fd_dynamic_stuffing_is_counted_in_the_data_phase() {
        let z = CanFrame::new_fd(0x555, &[0; 8], true).unwrap();
        let (n, d) = frame_bits(&z);
        assert_eq!(n, 30, "the arbitration bits alternate");
        // run of 67 zeros: ⌊67 / 5⌋ = 13 stuff bits
        assert_eq!(d, 96 + 13);
    }

    #[test]
    fn fd_switching_saves_time_for_long_payloads() {
        let d = [0xA5u8; 64];
        let classic_8 = classic_time_ns(0x185, &d[..8], 1_000_000);
        let fd_64 = fd_time_ns(0x185, &d, 1_000_000, 5_000_000, true);
        // 8 times the payload in less than 3 times the time
        assert!(fd_64 < 3 * classic_8, "{fd_64} vs {classic_8}");
        assert_eq!(fd_size(9), 12);
        assert_eq!(fd_size(17), 20);
    }
}
