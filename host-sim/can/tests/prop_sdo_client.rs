//! Bounded property version of the fuzz target `sdo_client` (`fuzz/fuzz_targets/`, run long by
//! `scripts/fuzz-all.sh`): the host's SDO client against a node that answers anything — frames
//! on the SDO response id and on others, any payload, any delay, or silence. Every operation
//! ends (a value or an error), nothing panics, and an upload stays within its bound. A response
//! that announces a 4 GiB upload used to reserve 4 GiB before the first segment.
#![allow(clippy::unwrap_used, clippy::panic)]

use std::time::Duration;

use joint_can::master::{Master, SdoError};
use joint_can::script_bus::ScriptBus;
use joint_can::transfer;
use joint_core::canopen::CanFrame;
use proptest::prelude::*;

const NODE: u8 = 5;

/// The system allocator, recording the largest single request (so a test can see what the
/// client reserved, whether or not the machine would have granted it).
struct Largest;

static LARGEST: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

unsafe impl std::alloc::GlobalAlloc for Largest {
    unsafe fn alloc(&self, l: std::alloc::Layout) -> *mut u8 {
        LARGEST.fetch_max(l.size(), std::sync::atomic::Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator
        unsafe { std::alloc::System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: std::alloc::Layout) {
        // SAFETY: `p` came from `alloc` above with this layout
        unsafe { std::alloc::System.dealloc(p, l) }
    }
}

#[global_allocator]
static ALLOC: Largest = Largest;

fn master(frames: Vec<(u64, u16, Vec<u8>)>) -> Master {
    let frames: Vec<(u64, CanFrame)> =
        frames.into_iter().filter_map(|(dt, id, d)| CanFrame::new(id, &d).map(|f| (dt, f))).collect();
    let mut m = Master::new(Box::new(ScriptBus::new(frames)));
    m.sdo_timeout = Duration::from_millis(5);
    m
}

/// Mostly SDO responses from the node, with upload/download command bytes likely.
fn frame() -> impl Strategy<Value = (u64, u16, Vec<u8>)> {
    let id = prop_oneof![6 => Just(0x580 + u16::from(NODE)), 1 => Just(0x705u16), 1 => 0u16..0x800];
    let first = prop_oneof![
        any::<u8>(),
        prop::sample::select(vec![0x41u8, 0x43, 0x4F, 0x60, 0x00, 0x10, 0x01, 0x11, 0x80, 0x20, 0x30])
    ];
    (0u64..3000, id, first, prop::collection::vec(any::<u8>(), 0..8)).prop_map(|(dt, id, b0, rest)| {
        let mut d = vec![b0];
        d.extend(rest);
        d.truncate(8);
        (dt, id, d)
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn the_sdo_client_ends_on_any_answers(frames in prop::collection::vec(frame(), 0..60), ops in any::<u8>(), len in 0usize..40) {
        let mut m = master(frames);
        for k in 0..4u16 {
            match (ops >> (2 * k)) & 3 {
                0 => {
                    if let Ok(v) = m.read(NODE, 0x2000 + k, 0) {
                        prop_assert!(v.len() <= (1 << 20) + 7);
                    }
                }
                1 => {
                    let payload: Vec<u8> = (0..len).map(|i| i as u8).collect();
                    let _ = m.write(NODE, 0x2100, 1, &payload);
                }
                2 => {
                    let _ = transfer::pull(&mut m, NODE);
                }
                _ => {
                    let _ = m.read_string(NODE, 0x1008, 0);
                }
            }
        }
    }
}

/// An initiate-upload response announcing 0xFFFF_FFFF bytes, then one short last segment: the
/// client reads it and reports the size mismatch, having reserved at most 64 KiB up front (the
/// largest allocation of this whole test binary is checked; the property test beside it
/// reserves at most the same 64 KiB).
#[test]
fn an_absurd_announced_size_is_an_error_not_an_allocation() {
    let r = 0x580 + u16::from(NODE);
    let mut m = master(vec![
        (10, r, vec![0x41, 0x00, 0x20, 0x00, 0xFF, 0xFF, 0xFF, 0xFF]),
        (10, r, vec![0x0B, 1, 2, 0, 0, 0, 0, 0]),
    ]);
    match m.read(NODE, 0x2000, 0) {
        Err(SdoError::Protocol { what, .. }) => assert!(what.contains("differs from the announced size"), "{what}"),
        other => panic!("{other:?}"),
    }
    let largest = LARGEST.load(std::sync::atomic::Ordering::Relaxed);
    assert!(largest <= 1 << 20, "the client reserved {largest} bytes for an upload it had not received");
}
