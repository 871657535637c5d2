//! Tools over a flight recording (docs/architecture.md, "The flight recorder"), read through
//! the `recorder` crate:
//!
//! * [`replay`]: `plant_sim replay`, the controller's cycle (`control_cycle`) and the
//!   estimator run again over the recorded inputs, bit for bit, or a what-if;
//! * [`monitor`]: `plant_sim monitor`, the live view of a running pair's status board.
//!
//! The export to MCAP reads recordings through the `recorder` crate too, but lives in the
//! `export` crate, so that nothing else links the `mcap` crate.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod monitor;
pub mod replay;
