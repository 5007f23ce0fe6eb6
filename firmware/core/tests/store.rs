//! The parameter store on a simulated NOR flash: power cut at every byte of a save sequence
//! (erase included), bit flips and foreign data, format versions and migration, exact round
//! trips, and the documented record format checked byte by byte.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::params::{check, ParamId, ParamSet, RawParams, PARAMS, PARAM_COUNT};
use joint_core::safety::Faults;
use joint_core::store::{
    crc32, name_id, GeometryError, LayoutError, LoadError, SaveError, SaveProgress, SlotState, Store, FORMAT_VERSION,
    HEADER_LEN, PAYLOAD_LEN, RECORD_LEN,
};
use joint_core::table::{AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};
use proptest::prelude::*;

const PAGE: usize = 2048;
const REGION: usize = 4 * PAGE; // what memory.x reserves on the G431
/// One record slot: half the region.
const SLOT: usize = REGION / 2;

// The shared NOR-flash double (power cuts, scrambled pages): the core's `mock-flash` feature.
use joint_core::store::mock::{MemFlash as MockFlash, MemFlashError as MockError};

/// A blank region of the G431's size.
fn blank() -> MockFlash {
    MockFlash::blank(REGION)
}

/// A valid set that differs with `seed`: scalars moved inside their ranges and a 2-D gravity
/// table with σ and fusion on.
fn sample(seed: u32) -> ParamSet {
    let mut raw = RawParams::defaults();
    let f = seed as f32;
    raw.set(ParamId::FrictionA, 0.01 * f);
    raw.set(ParamId::FrictionC, 0.5 + 0.1 * f);
    raw.set(ParamId::WeightAmplitude, -3.25 - f);
    raw.set(ParamId::WeightPhi, 0.125 * f);
    raw.set(ParamId::Fraction, 0.7);
    raw.set(ParamId::TableSigmaModel, 0.5);
    raw.set(ParamId::HeartbeatTimeout, 0.25 + 0.001 * f);
    let t = &mut raw.table;
    t.n_axes = 2;
    t.axis_source = [0, 1, 0, 0];
    t.points = [5, 4, 0, 0];
    for i in 0..5 {
        t.grid[0][i] = -1.0 + 0.5 * i as f32;
    }
    for i in 0..4 {
        t.grid[1][i] = -0.3 + 0.2 * i as f32 + 0.001 * f;
    }
    for c in 0..20 {
        t.torque[c] = (c as f32 - 7.0) * 0.37 + f;
        t.sigma[c] = 0.1 + 0.01 * c as f32;
    }
    t.has_sigma = true;
    check(&raw).expect("sample set is valid")
}

/// The largest table there is: 16 × CELLS_MAX/16 cells, every array slot non-zero.
fn full_table_set() -> ParamSet {
    let mut raw = sample(3).raw().clone();
    let t = &mut raw.table;
    t.n_axes = 2;
    t.points = [16, (CELLS_MAX / 16) as u8, 0, 0];
    for a in 0..AXES_MAX {
        for i in 0..AXIS_POINTS_MAX {
            t.grid[a][i] = (a * 100 + i) as f32 * 0.01 - 1.0;
        }
    }
    for c in 0..CELLS_MAX {
        t.torque[c] = c as f32 * -0.011 + 3.0;
        t.sigma[c] = 0.05 + c as f32 * 0.001;
    }
    check(&raw).expect("full table is valid")
}

fn store(flash: MockFlash) -> Store<MockFlash> {
    Store::new(flash).expect("region fits")
}

/// Flash after saving `sets` in order (no cuts).
fn flash_with(sets: &[ParamSet]) -> MockFlash {
    let mut s = store(blank());
    for set in sets {
        s.save_blocking(set).expect("save");
    }
    s.into_flash()
}

/// Boot on `mem` and load.
fn boot(mem: &[u8]) -> Result<joint_core::store::Loaded, LoadError<MockError>> {
    store(MockFlash::from_mem(mem.to_vec())).load()
}

fn loaded_raw(mem: &[u8]) -> RawParams {
    boot(mem).expect("load").params.raw().clone()
}

// --- the documented format, re-implemented independently ---------------------------------

fn push_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// Version-1 payload per the module doc, with a chosen entry list and table dimensions.
fn payload_v1(entries: &[(u32, f32)], raw: &RawParams, dims: (usize, usize, usize)) -> Vec<u8> {
    let (a_max, m_max, c_max) = dims;
    let t = &raw.table;
    let mut p = Vec::new();
    p.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    p.extend_from_slice(&8u16.to_le_bytes());
    p.extend_from_slice(&[0; 4]);
    for &(id, v) in entries {
        p.extend_from_slice(&id.to_le_bytes());
        push_f32(&mut p, v);
    }
    p.extend_from_slice(&[t.n_axes, t.has_sigma as u8, a_max as u8, m_max as u8]);
    p.extend_from_slice(&(c_max as u16).to_le_bytes());
    p.extend_from_slice(&[0, 0]);
    for a in 0..a_max {
        p.push(t.axis_source.get(a).copied().unwrap_or(0));
    }
    for a in 0..a_max {
        p.push(t.points.get(a).copied().unwrap_or(0));
    }
    for a in 0..a_max {
        for i in 0..m_max {
            push_f32(&mut p, t.grid.get(a).and_then(|r| r.get(i)).copied().unwrap_or(0.0));
        }
    }
    for c in 0..c_max {
        push_f32(&mut p, t.torque.get(c).copied().unwrap_or(0.0));
    }
    for c in 0..c_max {
        push_f32(&mut p, t.sigma.get(c).copied().unwrap_or(0.0));
    }
    p
}

fn entries_of(raw: &RawParams) -> Vec<(u32, f32)> {
    PARAMS.iter().zip(raw.values.iter()).map(|(d, &v)| (crc32(d.name.as_bytes()), v)).collect()
}

/// A whole record (header + payload, padded to 8 with 0xFF) per the module doc.
fn record(seq: u32, version: u16, payload: &[u8]) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(b"JPRM");
    h.extend_from_slice(&version.to_le_bytes());
    h.extend_from_slice(&24u16.to_le_bytes());
    h.extend_from_slice(&seq.to_le_bytes());
    h.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    let mut crc_in = payload.to_vec();
    crc_in.extend_from_slice(&h);
    h.extend_from_slice(&crc32(&crc_in).to_le_bytes());
    h.extend_from_slice(&[0; 4]);
    h.extend_from_slice(payload);
    while h.len() % 8 != 0 {
        h.push(0xFF);
    }
    h
}

/// A region with `rec` in slot `slot` (the other slot as in `mem`).
fn put(mem: &mut [u8], slot: usize, rec: &[u8]) {
    let base = slot * SLOT;
    mem[base..base + SLOT].fill(0xFF);
    mem[base..base + rec.len()].copy_from_slice(rec);
}

// --- tests --------------------------------------------------------------------------------

#[test]
fn crc32_is_iso_hdlc() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
    assert_eq!(crc32(b"The quick brown fox jumps over the lazy dog"), 0x414F_A339);
}

#[test]
fn geometry() {
    // 24-byte header, 8 bytes of counts, 8 bytes per scalar parameter, then the table: 16 bytes
    // of shape, the grid, and torque and sigma per cell.
    use joint_core::table::{AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};
    let table = 16 + 4 * AXES_MAX * AXIS_POINTS_MAX + 8 * CELLS_MAX;
    let expected = 24 + 8 + 8 * joint_core::params::PARAM_COUNT + table;
    assert_eq!(HEADER_LEN + PAYLOAD_LEN, expected);
    assert_eq!(RECORD_LEN, expected);
    let s = store(blank());
    assert_eq!(s.used_len() as usize, REGION);
    assert_eq!(s.ops_per_save() as usize, expected.div_ceil(PAGE) + expected / 8);
    // a slot holds the longest record: model block and communication block included
    let slot_pages = joint_core::store::RECORD_MAX_LEN.div_ceil(PAGE);
    assert_eq!(
        Store::new(MockFlash::from_mem(vec![0xFF; 2 * slot_pages * PAGE - PAGE])).err(),
        Some(GeometryError::RegionTooSmall {
            need: (2 * slot_pages * PAGE) as u32,
            have: (2 * slot_pages * PAGE - PAGE) as u32
        })
    );
}

#[test]
fn parameter_names_have_distinct_ids() {
    let mut ids: Vec<u32> = PARAMS.iter().map(|d| name_id(d.name)).collect();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), PARAM_COUNT);
}

#[test]
fn blank_region_loads_nothing_and_is_not_a_fault() {
    let mut s = store(blank());
    let e = s.load().unwrap_err();
    assert_eq!(e, LoadError::Blank);
    assert_eq!(e.fault(), Faults::NONE);
    let (set, f) = store(blank()).load_or_defaults();
    assert_eq!(set, ParamSet::defaults());
    assert_eq!(f, Faults::NONE);
}

#[test]
fn round_trip_alternates_slots_and_survives_reboot() {
    let sets = [sample(1), sample(2), sample(3), full_table_set()];
    let mut s = store(blank());
    for (k, set) in sets.iter().enumerate() {
        let (slot, seq) = s.save_blocking(set).expect("save");
        assert_eq!((slot as usize, seq), (k % 2, k as u32 + 1));
    }
    let mem = s.into_flash().mem;
    let l = boot(&mem).expect("load");
    assert_eq!(l.params, sets[3], "exact, bit for bit, full table included");
    assert_eq!((l.info.slot, l.info.seq, l.info.version), (1, 4, FORMAT_VERSION));
    assert_eq!(l.info.other, SlotState::Valid { seq: 3, version: 1 });
    assert_eq!((l.info.defaulted, l.info.unknown, l.info.table_migrated), (0, 0, false));
    assert_eq!(l.info.fault(), Faults::NONE);
}

#[test]
fn four_axis_table_round_trips() {
    let mut raw = sample(9).raw().clone();
    let t = &mut raw.table;
    t.n_axes = 4;
    t.axis_source = [0, 1, 2, 3];
    t.points = [4, 4, 4, 2];
    for a in 0..4 {
        for i in 0..4 {
            t.grid[a][i] = i as f32 - a as f32 * 0.1;
        }
    }
    for c in 0..128 {
        t.torque[c] = c as f32 * 0.25;
        t.sigma[c] = 1.0 + c as f32;
    }
    let set = check(&raw).expect("valid");
    let mem = flash_with(std::slice::from_ref(&set)).mem;
    assert_eq!(loaded_raw(&mem), raw);
}

#[test]
fn record_bytes_match_the_documented_format() {
    let set = sample(5);
    let mem = flash_with(std::slice::from_ref(&set)).mem;
    let want = record(1, 1, &payload_v1(&entries_of(set.raw()), set.raw(), (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX)));
    assert_eq!(want.len(), RECORD_LEN);
    assert_eq!(&mem[..RECORD_LEN], &want[..]);
    assert!(mem[RECORD_LEN..].iter().all(|&b| b == 0xFF), "rest of the region untouched");
}

/// Run one save of `new` on `initial` with the power cut after `budget` bytes; returns the
/// flash contents at the cut and whether the save reported Done.
fn cut_save(initial: &MockFlash, new: &ParamSet, budget: u64, scramble: bool) -> (Vec<u8>, bool) {
    let mut s = store(initial.clone().with_cut(budget, scramble));
    let mut done = false;
    match s.begin_save(new) {
        Ok(()) => loop {
            match s.poll(new) {
                Ok(SaveProgress::Done { .. }) => {
                    done = true;
                    break;
                }
                Ok(SaveProgress::Working { .. }) => {}
                Ok(SaveProgress::Idle) => panic!("went idle without finishing"),
                Err(SaveError::Flash(MockError::PowerCut)) => break,
                Err(e) => panic!("unexpected save error {e:?}"),
            }
        },
        Err(e) => panic!("begin_save failed: {e:?}"),
    }
    (s.into_flash().mem, done)
}

/// For every byte of the save sequence: cut there, reboot, load. The result must be exactly
/// the old set (or, if there was none, no set) before the final byte and the new set after
/// it; and a save after the reboot must work and load.
fn power_cut_sweep(history: &[ParamSet], new: &ParamSet, scramble: bool) -> u64 {
    let initial = flash_with(history);
    // Dry run: how many bytes does the whole save erase and program?
    let mut dry = store(initial.clone());
    dry.save_blocking(new).expect("save");
    let total = dry.into_flash().used - initial.used;
    // the pages the record covers are erased, then every byte of it is programmed
    assert_eq!(total, (RECORD_LEN.div_ceil(PAGE) * PAGE) as u64 + RECORD_LEN as u64);

    let old = history.last();
    let after = sample(77);
    for n in 0..=total {
        let (mem, done) = cut_save(&initial, new, n, scramble);
        assert_eq!(done, n == total, "cut {n}");
        let got = boot(&mem);
        match (n == total, old, &got) {
            (true, _, Ok(l)) => assert_eq!(&l.params, new, "cut {n}: new set"),
            (false, Some(o), Ok(l)) => {
                assert_eq!(&l.params, o, "cut {n}: must be the old set");
                // A cut save leaves an uncommitted (or blank) slot: not a fault, unless the
                // cut hit the commit double-word after the magic.
                let commit_start = total - 8;
                if n < commit_start + 4 {
                    assert_eq!(l.info.fault(), Faults::NONE, "cut {n}: {:?}", l.info.other);
                }
            }
            (false, None, Err(LoadError::Blank)) | (false, None, Err(LoadError::Corrupt { .. })) => {}
            (_, _, r) => panic!("cut {n} of {total}: unexpected {r:?}"),
        }
        // Recovery: the next save on this board must succeed and win.
        {
            let mut s = store(MockFlash::from_mem(mem));
            let _ = s.load();
            s.save_blocking(&after).expect("save after reboot");
            assert_eq!(loaded_raw(&s.into_flash().mem), *after.raw(), "cut {n}: recovery save");
        }
    }
    total + 1
}

#[test]
fn power_cut_at_every_byte_first_save() {
    let n = power_cut_sweep(&[], &sample(1), false);
    println!("{n} cut points");
}

#[test]
fn power_cut_at_every_byte_second_save() {
    power_cut_sweep(&[sample(1)], &sample(2), false);
}

#[test]
fn power_cut_at_every_byte_overwriting_the_older_slot() {
    power_cut_sweep(&[sample(1), sample(2)], &full_table_set(), false);
}

#[test]
fn power_cut_at_every_byte_with_garbage_left_by_a_cut_erase() {
    power_cut_sweep(&[sample(1), sample(2)], &sample(3), true);
    power_cut_sweep(&[], &sample(3), true);
}

#[test]
fn repeated_cuts_never_lose_the_last_committed_set() {
    // Cut the same save again and again at growing points (the board keeps losing power while
    // saving), then let it finish: the committed set is the old one until the very end.
    let mut mem = flash_with(&[sample(1)]).mem;
    for n in (0..(RECORD_LEN.div_ceil(PAGE) * PAGE + RECORD_LEN - 1) as u64).step_by(613) {
        let (m, done) = cut_save(&MockFlash::from_mem(mem.clone()), &sample(2), n, n % 2 == 0);
        assert!(!done);
        mem = m;
        assert_eq!(loaded_raw(&mem), *sample(1).raw());
    }
    let mut s = store(MockFlash::from_mem(mem));
    s.load().expect("old set");
    s.save_blocking(&sample(2)).expect("save");
    assert_eq!(loaded_raw(&s.into_flash().mem), *sample(2).raw());
}

#[test]
fn every_single_bit_flip_in_the_newest_record_is_detected() {
    let mem = flash_with(&[sample(1), sample(2)]).mem; // sample(2) in slot B
    let mut checked = 0;
    for byte in SLOT..SLOT + RECORD_LEN {
        for bit in 0..8 {
            let mut m = mem.clone();
            m[byte] ^= 1 << bit;
            let l = boot(&m).expect("older set still loads");
            assert_eq!(l.params, sample(1), "flip at {byte}.{bit}");
            assert!(matches!(l.info.other, SlotState::Damaged | SlotState::Uncommitted));
            if byte >= SLOT + 4 {
                assert_eq!(l.info.fault(), Faults::PARAMS_CORRUPT, "flip at {byte}.{bit}");
            }
            checked += 1;
        }
    }
    assert_eq!(checked, RECORD_LEN * 8);
}

#[test]
fn damage_in_both_slots_is_corrupt() {
    let mut mem = flash_with(&[sample(1), sample(2)]).mem;
    mem[100] ^= 0x10;
    mem[SLOT + RECORD_LEN / 2] ^= 0x01;
    let e = boot(&mem).unwrap_err();
    assert_eq!(e, LoadError::Corrupt { a: SlotState::Damaged, b: SlotState::Damaged });
    assert_eq!(e.fault(), Faults::PARAMS_CORRUPT);
    let (set, f) = store(MockFlash::from_mem(mem)).load_or_defaults();
    assert_eq!((set, f), (ParamSet::defaults(), Faults::PARAMS_CORRUPT));
}

#[test]
fn foreign_data_is_detected() {
    // Random bytes (e.g. an old application image that overlapped the region).
    let mut x: u32 = 0x1234_5678;
    let noise: Vec<u8> = (0..REGION)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect();
    let e = boot(&noise).unwrap_err();
    assert_eq!(e, LoadError::Corrupt { a: SlotState::Uncommitted, b: SlotState::Uncommitted });
    // All zeros.
    assert!(matches!(boot(&vec![0; REGION]), Err(LoadError::Corrupt { .. })));
    // Our magic in front of foreign bytes, and a header whose length points past the slot.
    let mut m = noise.clone();
    m[..4].copy_from_slice(b"JPRM");
    m[SLOT..SLOT + 4].copy_from_slice(b"JPRM");
    m[SLOT + 6..SLOT + 8].copy_from_slice(&24u16.to_le_bytes());
    m[SLOT + 12..SLOT + 16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert_eq!(boot(&m).unwrap_err(), LoadError::Corrupt { a: SlotState::Damaged, b: SlotState::Damaged });
    // One good record beside garbage loads and reports the garbage.
    let mut m = flash_with(&[sample(4)]).mem;
    m[SLOT..].copy_from_slice(&noise[SLOT..]);
    let l = boot(&m).expect("good slot");
    assert_eq!(l.params, sample(4));
    assert_eq!(l.info.other, SlotState::Uncommitted);
}

#[test]
fn newer_format_is_refused_and_kept() {
    let set = sample(6);
    let mut mem = flash_with(&[sample(5)]).mem;
    let payload = payload_v1(&entries_of(set.raw()), set.raw(), (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX));
    let v2 = record(7, 2, &payload);
    put(&mut mem, 1, &v2);
    let e = boot(&mem).unwrap_err();
    assert_eq!(e, LoadError::UnsupportedVersion { found: 2, supported: 1, seq: 7 });
    assert_eq!(e.fault(), Faults::PARAMS_VERSION);
    // Saving from this firmware overwrites the *other* slot; the newer record stays intact.
    let mut s = store(MockFlash::from_mem(mem));
    let _ = s.load();
    assert_eq!(s.save_blocking(&sample(8)), Ok((0, 8)));
    let mem = s.into_flash().mem;
    assert_eq!(&mem[SLOT..SLOT + v2.len()], &v2[..]);
    assert_eq!(loaded_raw(&mem), *sample(8).raw());
    // Version 0 is not a format at all.
    let mut m = flash_with(&[]).mem;
    put(&mut m, 0, &record(1, 0, &payload));
    assert!(matches!(boot(&m), Err(LoadError::UnsupportedVersion { found: 0, .. })));
}

#[test]
fn added_removed_and_reordered_parameters_migrate_by_name() {
    let mut raw = sample(2).raw().clone();
    raw.set(ParamId::PosKd, 33.0);
    let set = check(&raw).expect("valid");
    let mut entries = entries_of(set.raw());
    entries.reverse();
    // A firmware that did not know `controller_pos_kd` yet, and had a parameter we dropped.
    let kd = name_id("controller_pos_kd");
    entries.retain(|&(id, _)| id != kd);
    entries.insert(3, (name_id("legacy_gain"), 42.0));
    let mut mem = flash_with(&[]).mem;
    put(&mut mem, 0, &record(3, 1, &payload_v1(&entries, set.raw(), (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX))));
    let l = boot(&mem).expect("migrates");
    let mut want = set.raw().clone();
    want.set(ParamId::PosKd, ParamId::PosKd.desc().default);
    assert_eq!(*l.params.raw(), want);
    assert_eq!((l.info.defaulted, l.info.unknown, l.info.table_migrated), (1, 1, false));
}

#[test]
fn table_from_other_compile_time_limits_is_copied_when_it_fits() {
    // Written by a build with AXES_MAX 2, AXIS_POINTS_MAX 8, CELLS_MAX 64.
    let set = sample(4);
    let mut mem = flash_with(&[]).mem;
    put(&mut mem, 1, &record(9, 1, &payload_v1(&entries_of(set.raw()), set.raw(), (2, 8, 64))));
    let l = boot(&mem).expect("fits");
    assert_eq!(l.params, set, "used part identical, unused entries zero as in the sample");
    assert!(l.info.table_migrated);
    // Written by a build with 20 points per axis and 400 cells, using 20 points: cannot be
    // represented here, so refused rather than cut short.
    let mut raw = set.raw().clone();
    raw.table.points = [20, 4, 0, 0];
    let p = payload_v1(&entries_of(&raw), &raw, (4, 20, 400));
    let mut m = flash_with(&[]).mem;
    put(&mut m, 0, &record(2, 1, &p));
    let e = boot(&m).unwrap_err();
    assert_eq!(e, LoadError::Layout { error: LayoutError::TableTooLarge { n_axes: 2, points: 20, cells: 80 }, seq: 2 });
    assert_eq!(e.fault(), Faults::PARAMS_VERSION);
}

#[test]
fn malformed_payloads_with_a_good_crc_are_refused() {
    let set = sample(1);
    let dims = (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX);
    let good = payload_v1(&entries_of(set.raw()), set.raw(), dims);
    let t_off = 8 + 8 * PARAM_COUNT;
    let cases: Vec<(Vec<u8>, LayoutError)> = vec![
        (
            {
                let mut p = good.clone();
                p[2] = 12;
                p
            },
            LayoutError::EntrySize { found: 12 },
        ),
        (
            {
                let mut p = good.clone();
                p[t_off + 1] = 2;
                p
            },
            LayoutError::BadFlag { value: 2 },
        ),
        (
            {
                let mut p = good.clone();
                p.truncate(p.len() - 4);
                p
            },
            LayoutError::Length { expected: good.len() as u32, found: good.len() as u32 - 4 },
        ),
        (
            {
                let mut p = good.clone();
                p[t_off] = 5;
                p
            },
            LayoutError::TableInconsistent,
        ),
        (
            {
                let mut p = good.clone();
                p[..2].copy_from_slice(&400u16.to_le_bytes());
                p
            },
            LayoutError::Truncated { len: good.len() as u32 },
        ),
        (
            {
                let mut e = entries_of(set.raw());
                e.push(e[4]);
                payload_v1(&e, set.raw(), dims)
            },
            LayoutError::DuplicateParam { entry: PARAM_COUNT as u16 },
        ),
    ];
    for (p, want) in cases {
        let mut m = flash_with(&[]).mem;
        put(&mut m, 0, &record(5, 1, &p));
        assert_eq!(boot(&m).unwrap_err(), LoadError::Layout { error: want, seq: 5 });
    }
}

#[test]
fn stored_values_that_fail_check_give_defaults_and_a_fault() {
    let set = sample(1);
    let mut raw = set.raw().clone();
    raw.set(ParamId::Fraction, 2.0);
    let mut m = flash_with(&[]).mem;
    put(&mut m, 0, &record(5, 1, &payload_v1(&entries_of(&raw), &raw, (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX))));
    let e = boot(&m).unwrap_err();
    assert!(matches!(e, LoadError::Rejected { seq: 5, error } if error.param() == Some(ParamId::Fraction)), "{e:?}");
    let (s, f) = store(MockFlash::from_mem(m)).load_or_defaults();
    assert_eq!((s, f), (ParamSet::defaults(), Faults::PARAMS_REJECTED));
}

#[test]
fn a_set_changed_during_the_save_is_never_committed() {
    let mem = flash_with(&[sample(1)]).mem;
    let mut s = store(MockFlash::from_mem(mem));
    s.begin_save(&sample(2)).expect("begin");
    // 2 erases and 8 programs: the scalars that differ between the sets are still to come.
    for _ in 0..10 {
        s.poll(&sample(2)).expect("poll");
    }
    let r = loop {
        match s.poll(&sample(3)) {
            Ok(SaveProgress::Working { .. }) => {}
            other => break other,
        }
    };
    assert_eq!(r, Err(SaveError::SourceChanged));
    assert!(!s.is_saving());
    assert_eq!(loaded_raw(&s.into_flash().mem), *sample(1).raw());
}

#[test]
fn begin_save_restarts_and_progress_is_reported() {
    // two page erases plus one 8-byte write per record unit
    let ops = (RECORD_LEN.div_ceil(PAGE) + RECORD_LEN / 8) as u16;
    let mut s = store(flash_with(&[sample(1)]));
    s.load().expect("load");
    s.begin_save(&sample(2)).expect("begin");
    assert_eq!(s.poll(&sample(2)), Ok(SaveProgress::Working { done: 1, total: ops }));
    // A newer set arrives mid-save: start over with it.
    s.begin_save(&sample(3)).expect("restart");
    let mut polls = 0;
    loop {
        polls += 1;
        match s.poll(&sample(3)).expect("poll") {
            SaveProgress::Done { slot, seq } => {
                assert_eq!((slot, seq), (1, 2));
                break;
            }
            SaveProgress::Working { done, total } => assert_eq!((done, total), (polls, ops)),
            SaveProgress::Idle => panic!("idle"),
        }
    }
    assert_eq!(polls, ops, "one flash operation per poll");
    assert_eq!(s.poll(&sample(3)), Ok(SaveProgress::Idle));
    assert_eq!(loaded_raw(&s.into_flash().mem), *sample(3).raw());
}

#[test]
fn sequence_numbers_compare_across_wrap_around() {
    let set_a = sample(1);
    let set_b = sample(2);
    let dims = (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX);
    let mut m = flash_with(&[]).mem;
    put(&mut m, 0, &record(u32::MAX, 1, &payload_v1(&entries_of(set_a.raw()), set_a.raw(), dims)));
    put(&mut m, 1, &record(0, 1, &payload_v1(&entries_of(set_b.raw()), set_b.raw(), dims)));
    let l = boot(&m).expect("load");
    assert_eq!((l.params, l.info.seq), (set_b, 0));
}

fn arb_set() -> impl Strategy<Value = ParamSet> {
    (proptest::collection::vec(0.0f32..=1.0, PARAM_COUNT), 1u8..=2, 2u8..=16, 2u8..=16, any::<bool>(), any::<u64>())
        .prop_filter_map("valid set", |(fr, n_axes, p0, p1, sigma, seed)| {
            let mut raw = RawParams::defaults();
            for (k, d) in PARAMS.iter().enumerate() {
                raw.values[k] = d.min + (d.max - d.min) * fr[k];
            }
            raw.set(ParamId::TableSigmaModel, 0.0);
            let t = &mut raw.table;
            t.n_axes = n_axes;
            t.points = [p0, if n_axes == 2 { p1 } else { 0 }, 0, 0];
            t.axis_source = [0, 2, 0, 0];
            let mut x = seed | 1;
            let mut rnd = || {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 40) as f32 / (1u64 << 24) as f32
            };
            for a in 0..AXES_MAX {
                let mut g = -2.0;
                for i in 0..AXIS_POINTS_MAX {
                    g += 0.01 + rnd();
                    t.grid[a][i] = g;
                }
            }
            for c in 0..CELLS_MAX {
                t.torque[c] = (rnd() - 0.5) * 100.0;
                t.sigma[c] = 0.001 + rnd();
            }
            t.has_sigma = sigma;
            check(&raw).ok()
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any valid set comes back exactly, from either slot.
    #[test]
    fn any_valid_set_round_trips(a in arb_set(), b in arb_set()) {
        let mut s = store(blank());
        s.save_blocking(&a).unwrap();
        let mem = s.into_flash().mem;
        prop_assert_eq!(&boot(&mem).unwrap().params, &a);
        let mut s = store(MockFlash::from_mem(mem));
        s.save_blocking(&b).unwrap();
        prop_assert_eq!(&boot(&s.into_flash().mem).unwrap().params, &b);
    }

    /// A sequence of saves with random power cuts: after each reboot the store holds the last
    /// set whose save completed, never anything else.
    #[test]
    fn random_cut_sequences_keep_the_last_completed_set(
        cuts in proptest::collection::vec((0u64..7000, any::<bool>()), 1..12)
    ) {
        let mut mem = blank().mem;
        let mut committed: Option<ParamSet> = None;
        for (k, (cut, scramble)) in cuts.into_iter().enumerate() {
            let new = sample(k as u32 + 10);
            let (m, done) = cut_save(&MockFlash::from_mem(mem), &new, cut, scramble);
            mem = m;
            if done {
                committed = Some(new);
            }
            match (&committed, boot(&mem)) {
                (Some(c), Ok(l)) => prop_assert_eq!(&l.params, c),
                (None, Err(LoadError::Blank | LoadError::Corrupt { .. })) => {}
                (c, r) => prop_assert!(false, "expected {:?}, got {:?}", c.is_some(), r),
            }
        }
    }
}

/// The generic window the boards hand the store: offsets from the window's start, nothing
/// outside it read, erased or programmed, and a store over it finds what it saved.
#[test]
fn a_region_is_a_window_of_a_larger_flash() {
    use joint_core::store::{NorFlash, ReadNorFlash, Region, RegionError};
    // a 16-page "chip" whose last four pages hold the parameters, as memory.x has them
    let mut chip = MockFlash::blank(16 * PAGE);
    chip.mem[..12 * PAGE].fill(0x5A); // "code"
    let mut r = Region::new(chip, 12 * PAGE as u32, REGION as u32);
    assert_eq!(r.capacity(), REGION);
    assert_eq!(r.window(), (12 * PAGE as u32, REGION as u32));
    let mut b = [0u8; 8];
    assert_eq!(r.read(REGION as u32 - 4, &mut b), Err(RegionError::OutOfBounds));
    assert_eq!(r.erase(0, REGION as u32 + PAGE as u32), Err(RegionError::OutOfBounds));
    assert_eq!(r.write(REGION as u32, &[0; 8]), Err(RegionError::OutOfBounds));
    r.write(8, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    let chip = r.into_inner();
    assert_eq!(&chip.mem[12 * PAGE + 8..12 * PAGE + 16], &[1, 2, 3, 4, 5, 6, 7, 8]);
    assert!(chip.mem[..12 * PAGE].iter().all(|&x| x == 0x5A), "outside the window untouched");
    // the store over the window
    let mut chip = chip;
    chip.mem[12 * PAGE..].fill(0xFF);
    let mut s = Store::new(Region::new(chip, 12 * PAGE as u32, REGION as u32)).unwrap();
    s.save_blocking(&sample(3)).unwrap();
    let chip = s.into_flash().into_inner();
    assert!(chip.mem[..12 * PAGE].iter().all(|&x| x == 0x5A));
    let mut s = Store::new(Region::new(MockFlash::from_mem(chip.mem), 12 * PAGE as u32, REGION as u32)).unwrap();
    assert_eq!(s.load().unwrap().params.raw(), sample(3).raw());
}

/// The communication block (the node's LSS configuration and PDO mappings) rides with the set:
/// read back as written, kept by a later save that does not change it, outside the set's CRC,
/// documented byte for byte, and a power cut anywhere in a save boots the old set with the old
/// block or the new set with the new one, never a mix.
#[test]
fn the_communication_block_rides_with_the_set_and_never_mixes() {
    use joint_core::store::COMM_MAX;
    let block_a: Vec<u8> = (0..459u32).map(|i| (i * 7 + 3) as u8).collect();
    let block_b: Vec<u8> = vec![1, 0b01, 21, 0];
    let mut s = store(blank());
    s.set_comm(&block_a).unwrap();
    s.save_blocking(&sample(1)).unwrap();
    assert!(s.set_comm(&vec![0; COMM_MAX + 1]).is_err(), "longer than COMM_MAX is refused");
    let mem = s.into_flash().mem;
    let mut r = store(MockFlash::from_mem(mem.clone()));
    assert_eq!(r.load().unwrap().params.raw(), sample(1).raw());
    assert_eq!(r.comm(), &block_a[..]);
    // the block sits after the set's payload: kind 1, reserved, u16 length, the bytes
    let set_len = joint_core::store::PAYLOAD_LEN;
    let p = HEADER_LEN + set_len;
    assert_eq!(&mem[p..p + 4], &[1, 0, (459 & 0xFF) as u8, (459 >> 8) as u8]);
    assert_eq!(&mem[p + 4..p + 4 + 459], &block_a[..]);
    assert_eq!(u32::from_le_bytes(mem[12..16].try_into().unwrap()) as usize, set_len + 4 + 459);
    // a later save without set_comm keeps the block (the set changed, the mappings did not)
    r.save_blocking(&sample(2)).unwrap();
    let mut r = store(MockFlash::from_mem(r.into_flash().mem));
    assert_eq!(r.load().unwrap().params.raw(), sample(2).raw());
    assert_eq!(r.comm(), &block_a[..]);
    let plain = flash_with(&[sample(2)]).mem;
    let with_block = {
        let mut s = store(blank());
        s.set_comm(&block_a).unwrap();
        s.save_blocking(&sample(2)).unwrap();
        s.into_flash().mem
    };
    // the set's bytes (what the set's CRC, its name on the bus, is over) are the same, block or not
    assert_eq!(&plain[24..24 + set_len], &with_block[24..24 + set_len]);
    drop(r);

    // power cut at every 16th byte of a save that changes both
    let old = {
        let mut s = store(blank());
        s.set_comm(&block_a).unwrap();
        s.save_blocking(&sample(3)).unwrap();
        s.into_flash().mem
    };
    let (mut saw_old, mut saw_new) = (false, false);
    for cut in (0..8 * PAGE as u64).step_by(16) {
        let mut s = store(MockFlash::from_mem(old.clone()).with_cut(cut, true));
        s.load().unwrap();
        s.set_comm(&block_b).unwrap();
        let done = s.save_blocking(&sample(4)).is_ok();
        let mut r = store(MockFlash::from_mem(s.into_flash().mem));
        let l = r.load().expect("an intact record survives every cut");
        if l.params.raw() == sample(4).raw() {
            assert_eq!(r.comm(), &block_b[..], "cut {cut}: new set with the old block");
            saw_new = true;
        } else {
            assert_eq!(l.params.raw(), sample(3).raw(), "cut {cut}");
            assert_eq!(r.comm(), &block_a[..], "cut {cut}: old set with the new block");
            assert!(!done, "cut {cut}: a completed save must load");
            saw_old = true;
        }
    }
    assert!(saw_old && saw_new);
}
