//! A global allocator that counts, for the claim "the control loop makes no heap allocation
//! per cycle" (docs/architecture.md, "One control cycle"): both processes install it, read a
//! count at the end of their first cycle and again at the end of the run, and report the
//! difference.
//!
//! Every call is forwarded to the system allocator; each allocation, zeroed allocation and
//! reallocation adds one to two counters: the calling thread's ([`thread_allocations`]:
//! the plant's loop thread, beside its recorder thread) and the process's
//! ([`process_allocations`]: the controller, whose loop is its main thread).
//!
//! ```
//! #[global_allocator]
//! static GLOBAL: alloc_counter::Counting = alloc_counter::Counting;
//!
//! fn main() {
//!     let before = alloc_counter::thread_allocations();
//!     let v = std::hint::black_box(vec![0u8; 8]);
//!     assert_eq!(alloc_counter::thread_allocations(), before + 1);
//!     drop(v);
//! }
//! ```
//!
//! This is the project's one `unsafe` allocator code: implementing `GlobalAlloc` is an
//! `unsafe impl` by definition.
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

/// The counting allocator: install it with `#[global_allocator]`.
pub struct Counting;

static PROCESS: AtomicU64 = AtomicU64::new(0);

std::thread_local! {
    static THREAD: Cell<u64> = const { Cell::new(0) };
}

fn count_one() {
    PROCESS.fetch_add(1, Ordering::Relaxed);
    // `try_with`: a thread being torn down has no counter left (and is no control loop)
    let _ = THREAD.try_with(|c| c.set(c.get() + 1));
}

/// The calling thread's allocations so far (0 where [`Counting`] is not the global
/// allocator).
pub fn thread_allocations() -> u64 {
    THREAD.try_with(Cell::get).unwrap_or(0)
}

/// The process's allocations so far, every thread's (0 where [`Counting`] is not the global
/// allocator).
pub fn process_allocations() -> u64 {
    PROCESS.load(Ordering::Relaxed)
}

// SAFETY: every call is forwarded unchanged to the system allocator, which upholds the
// GlobalAlloc contract. Counting is a relaxed atomic increment and a const-initialised
// thread-local `Cell` with no destructor: neither allocates nor re-enters the allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same layout contract as our caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same layout contract as our caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        // SAFETY: ptr was allocated by System with this layout (every allocation here is).
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: ptr was allocated by System with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}
