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
    let size = fd_size(data.len());
    let mut arb = Vec::with_capacity(17);
    arb.push(false); // SOF
    push_bits(&mut arb, u32::from(id & 0x7FF), 11);
    arb.extend([false, false, true, false, true]); // RRS, IDE, FDF, res, BRS
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
