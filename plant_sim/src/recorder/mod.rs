//! The flight recorder as `plant_sim` uses it (docs/architecture.md, "The flight recorder"):
//! the files themselves are the `recorder` crate's (re-exported here: [`mod@format`], [`writer`],
//! [`reader`]); this module adds the offline tools over them:
//!
//! * [`replay`]: `plant_sim replay`, the controller and the estimator over the recorded
//!   inputs, bit for bit, or a what-if;
//! * [`monitor`]: the live status board and `plant_sim monitor`.
//!
//! The export to MCAP reads recordings through the `recorder` crate too, but lives in the
//! `export` crate, so no control process links the `mcap` crate.

pub mod monitor;
pub mod replay;

pub use ::recorder::*;
pub use ::recorder::{format, reader, writer};
