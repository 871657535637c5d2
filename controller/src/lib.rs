//! # controller — equivariant tracking control on matrix Lie groups
//!
//! The mathematics of Hampsey, van Goor, Banavar and Mahony, "Exploiting Equivariance in the
//! Design of Tracking Controllers for Euler–Poincaré Systems on Matrix Lie Groups" (2024) and its
//! extension (arXiv 2511.18800), in coordinates as written out in the project's `docs/maths.md`.
//!
//! * `#![no_std]`, no `alloc`, no `unsafe`: fixed-size nalgebra matrices only.
//! * Generic over the scalar ([`Real`]: `f32` for a microcontroller FPU, `f64` on Linux) and over
//!   the group ([`MatrixLieGroup`]: [`So3`], [`Se3`]).
//!
//! Module map (one equation of docs/maths.md, one named function):
//!
//! | module | what |
//! |---|---|
//! | [`group`] | the Lie groups: `hat`, `vee`, `exp`, `log`, `Ad`, `ad`, basis |
//! | [`semidirect`] | the phase-space group `G ⋉ g*`, the actions φ and ψ, the vector field f |
//! | [`tracking`] | tracking error, error inputs, error inertia, Lyapunov function |
//! | [`disturbance`] | the momentum observer and the geometric integral with anti-windup |
//! | [`law`] | the EqT law (any group), the SO(3) closed forms EqT, GT, nog, asym, the [`Controller`] |
//! | [`reference`](mod@reference) | the [`Trajectory`] interface; the generator with cosine-series feedforward |
//! | [`path`] | set-points, paths through waypoints, streamed pieces |
//! | [`integrator`] | RKMK4 on the group, the rigid body |
//! | [`closed_loop`] | controller + reference + plant in one loop (simulation, firmware) |
//!
//! The example in docs/getting-started.md, "The `eqtrack-controller` crate's API" (doc-tested), shows the
//! whole loop; [`closed_loop::ClosedLoop`] is the place to start reading. docs/firmware.md,
//! "Using eqtrack in your firmware", starts from `cargo add` and ends with the law in a
//! board's loop.
//!
//! ## Features
//!
//! - `kit` (off by default): the property kit, `eqtrack_controller::kit`, which checks a
//!   group of your own and the law's error dynamics and Lyapunov function on it
//!   (docs/groups.md).
//!
//! [`nalgebra`] and [`heapless`] (the reference's feedforward series) are re-exported, so a
//! user's matrices are this crate's.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod closed_loop;
pub mod disturbance;
pub mod error;
pub mod group;
pub mod integrator;
#[cfg(any(test, feature = "kit"))]
pub mod kit;
pub mod law;
pub mod path;
pub mod reference;
pub mod semidirect;
pub mod tracking;
pub mod trig;
pub mod validate;

pub use disturbance::{Frame, IntegralConfig, ObserverConfig, Rejection, RejectionConfig};
pub use error::{Error, Quantity};
pub use group::{BuiltinGroup, GroupKind, MatrixLieGroup, Se2, Se3, So3};
pub use law::{Controller, ControllerConfig, ErrorFrame, Law, LawOutput};
pub use path::{Path, PathReference, PathSample, Segment};
pub use reference::{
    AxisTorque, CosTerm, Feedforward, Reference, Source, Trajectory, so3_seed_feedforward,
};

/// The scalar type: a real field that is `Copy` (`f32`, `f64`).
///
/// With nalgebra's `libm-force` feature the transcendental functions are libm's on every
/// target, so host tests run the same maths as a microcontroller. The cycle's square roots go
/// through [`hw_sqrt`]: the FPU's on a Cortex-M4F, the same bits as libm's.
pub trait Real: nalgebra::RealField + Copy + 'static {}
impl<T: nalgebra::RealField + Copy + 'static> Real for T {}

pub use eqtrack_hw_sqrt as hw_sqrt;
pub use heapless;
pub use nalgebra;

/// Converts an `f64` constant into the scalar type.
#[inline(always)]
pub fn real<T: Real>(x: f64) -> T {
    nalgebra::convert(x)
}

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
