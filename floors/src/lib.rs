//! The loop benchmark and the floors it is measured against
//! (docs/architecture.md, "The floors"):
//!
//! * [`bench_loop`]: `plant_sim bench-loop`, the round trip of the real pair (the `plant`
//!   crate's plant process and `controller_node`) over each transport and wake-up mode;
//! * [`os_floor`]: the runners of the floors, `cyclictest` (the operating system's) and this
//!   crate's `transport_floor` binary (the least two processes can do over iceoryx2).
//!
//! The `transport_floor` binary itself uses nothing of the project but the message layout.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod bench_loop;
pub mod os_floor;
