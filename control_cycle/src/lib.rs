//! The controller's cycle without a process (docs/architecture.md, "One control cycle"):
//!
//! * [`respond`] and [`Responder`]: one answer to one plant state — the reference stepped to
//!   the state's time, the law (with its disturbance-rejection terms) through the `eqtrack-controller`
//!   crate, the command filled in. Allocation-free and generic over the scalar.
//! * [`ControllerVehicle`]: with a vehicle, the law's wrench allocated to its actuators, and
//!   with `[fault_detection]` the failure detector's cycle before it.
//! * [`Supervisor`]: with `[failsafe]`, the failsafe manager ahead of the law, and the
//!   engaged action's set-point flown in place of the reference.
//! * [`PlanIntake`] and [`streamed_reference`]: a streamed reference, the plan messages taken
//!   into its path, and the path a streamed run starts from.
//!
//! `controller_node` runs this cycle over `link`; `plant_sim replay` and the fuzz harness run
//! it again over recorded inputs, which is why it lives apart from the process.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

mod respond;
mod stream;
mod supervise;
mod vehicle;

pub use respond::{Responder, respond};
pub use stream::{PlanIntake, streamed_reference};
pub use supervise::Supervisor;
pub use vehicle::ControllerVehicle;
