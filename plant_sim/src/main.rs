//! `plant_sim`: see the library's documentation (`plant_sim::main`), and
//! docs/simulations.md for every subcommand.
#![forbid(unsafe_code)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use std::process::ExitCode;

// Counts the heap allocations of each thread: the plant's loop thread reports its own in
// `summary.json`, to show that recording allocates nothing there.
#[global_allocator]
static GLOBAL: alloc_counter::Counting = alloc_counter::Counting;

fn main() -> ExitCode {
    plant_sim::main()
}
