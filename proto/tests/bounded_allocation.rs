//! A length prefix of 4 GiB must not allocate 4 GiB: measured with a counting
//! allocator, so the claim is checked, not assumed.

// A global allocator cannot be written without `unsafe`; it only forwards to
// the system allocator and records the largest request.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use ickon_proto::msg::control::{Burst, Schedule};
use ickon_proto::msg::robot::UltrasoundArrivals;

struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const ONE_MIB: usize = 1 << 20;

#[test]
fn huge_length_prefixes_allocate_at_most_a_mebibyte() {
    let mut string_4gib = vec![0x00, 0x01, 0x00, 0x00];
    string_4gib.extend_from_slice(&u32::MAX.to_le_bytes());
    string_4gib.extend_from_slice(&[b'a'; 64]);

    let mut seq_4g = vec![0x00, 0x01, 0x00, 0x00];
    seq_4g.extend_from_slice(&1u64.to_le_bytes());
    seq_4g.extend_from_slice(&u32::MAX.to_le_bytes());
    seq_4g.extend_from_slice(&[0u8; 64]);

    let mut schedule_4g = vec![0x00, 0x01, 0x00, 0x00];
    schedule_4g.extend_from_slice(&1u32.to_le_bytes()); // version
    schedule_4g.extend_from_slice(&[0, 0, 0, 0]); // padding to 8
    schedule_4g.extend_from_slice(&0u64.to_le_bytes()); // effective_cycle
    schedule_4g.extend_from_slice(&1i64.to_le_bytes()); // cycle_period
    schedule_4g.extend_from_slice(&1i64.to_le_bytes()); // slot_length
    schedule_4g.extend_from_slice(&u32::MAX.to_le_bytes()); // emissions
    schedule_4g.extend_from_slice(&[0u8; 64]);

    LARGEST.store(0, Ordering::Relaxed);
    assert!(ickon_proto::decode::<Burst>(&string_4gib).is_err());
    assert!(ickon_proto::decode::<UltrasoundArrivals>(&seq_4g).is_err());
    assert!(ickon_proto::decode::<Schedule>(&schedule_4g).is_err());
    let largest = LARGEST.load(Ordering::Relaxed);
    assert!(
        largest <= ONE_MIB,
        "decoding a bogus length prefix allocated {largest} bytes"
    );
}
