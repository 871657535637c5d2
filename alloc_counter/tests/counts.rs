//! The allocator installed in a test binary: it counts what allocates, per thread and per
//! process, and nothing else.

use alloc_counter::{Counting, process_allocations, thread_allocations};
use std::hint::black_box;

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn allocations_are_counted_per_thread_and_per_process_and_arithmetic_is_not() {
    let (t0, p0) = (thread_allocations(), process_allocations());
    let mut x = 0u64;
    for i in 0..1000u64 {
        x = black_box(x.wrapping_mul(31).wrapping_add(i));
    }
    assert_eq!(
        thread_allocations(),
        t0,
        "arithmetic allocates nothing ({x})"
    );
    let v: Vec<u64> = black_box(Vec::with_capacity(16));
    let mut w = black_box(v);
    w.extend(0..100); // a reallocation
    assert_eq!(thread_allocations() - t0, 2);
    assert!(process_allocations() - p0 >= 2);
    // another thread's allocations are its own (exactly its one vector), and the process's
    let p1 = process_allocations();
    let theirs = std::thread::spawn(|| {
        let start = thread_allocations();
        black_box(vec![1u8; 64]);
        thread_allocations() - start
    })
    .join()
    .unwrap();
    assert_eq!(theirs, 1);
    assert!(process_allocations() - p1 >= 1);
    drop(w);
}
