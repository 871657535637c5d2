//! The studies over the in-process simulation (`plant::trajectory`), each a `plant_sim`
//! subcommand that writes its CSV and figures:
//!
//! * [`montecarlo`]: the extended paper's Monte Carlo comparison of the laws;
//! * [`estimator_study`]: the laws flown on estimated states, estimator against truth;
//! * [`frames`]: where EqT forms its error (`error_frame`) on SE(3), with the world moved;
//! * [`moved`]: a flight and the same flight with the world moved, column by column;
//! * [`noise`]: the laws under sensor noise;
//! * [`rejection`]: the disturbance-rejection terms against a disturbance;
//! * [`reference`](mod@reference): the desired trajectory sampled for inspection, before it
//!   is flown.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod estimator_study;
pub mod frames;
pub mod montecarlo;
pub mod moved;
pub mod noise;
pub mod reference;
pub mod rejection;
pub mod shard;

/// The inertia of the body a run integrates: the rigid body's, or with reaction wheels the
/// body with them free (`Scenario::total_inertia`; docs/maths.md, "Reaction wheels").
pub(crate) fn study_inertia(s: &scenario::Scenario) -> Vec<f64> {
    match &s.vehicle {
        Some(v) if !v.wheels.is_empty() => s.total_inertia(),
        _ => s.plant_inertia.clone(),
    }
}
