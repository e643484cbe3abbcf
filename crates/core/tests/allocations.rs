//! Allocations per scan frame do not grow with the number of returns: every per-return
//! query (nearest samples, segment searches, chain windows) works in place, and what a
//! frame allocates is its arrays (a handful per stage) and its runs' and curves' own.
//!
//! Its own test binary, with one test: the counting allocator is the whole process's,
//! and a second test running beside it would be counted too.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use isoline_core::{reconstruct_scan, LaserScan, Params, Scan};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

struct Counting;

static CALLS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        CALLS.fetch_add(1, Relaxed);
        // SAFETY: the caller's contract is passed on as it is.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        CALLS.fetch_add(1, Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A full turn of `beams` beams from the centre of a round room of radius 4 m, 1 cm
/// range noise: one run, one closed curve, from 360 to 2,000 returns.
fn round_room(beams: usize) -> Scan {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let ranges: Vec<Option<f64>> = (0..beams)
        .map(|_| Some(4.0 + noise.sample(&mut rng)))
        .collect();
    Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: 0.0,
        angle_increment: std::f64::consts::TAU / beams as f64,
        ranges: &ranges,
        range_min: 0.05,
        range_max: 10.0,
    })
    .unwrap()
}

/// Allocation calls of one frame, after a first run has built the thread pool.
fn calls(scan: &Scan) -> usize {
    let params = Params::default();
    reconstruct_scan(scan, &params).unwrap();
    let before = CALLS.load(Relaxed);
    let r = reconstruct_scan(scan, &params).unwrap();
    let n = CALLS.load(Relaxed) - before;
    assert!(r.polylines.len() == 1 && r.polylines[0].closed);
    n
}

#[test]
fn allocations_per_frame_do_not_grow_with_the_returns() {
    let few = calls(&round_room(360));
    let many = calls(&round_room(2000));
    // 1,640 more returns: one allocation per return (a query's result vector) would add
    // 1,640 or more. Arrays that grow by doubling may realloc a few more times (log2 of
    // 5.6 is under 3 each), which a quarter more allows.
    assert!(
        many <= few + few / 4,
        "{few} allocations at 360 returns, {many} at 2,000"
    );
    eprintln!("{few} allocations at 360 returns, {many} at 2,000");
}
