//! # controller — equivariant tracking control on matrix Lie groups
//!
//! The mathematics of Hampsey, van Goor, Banavar and Mahony, "Exploiting Equivariance in the
//! Design of Tracking Controllers for Euler–Poincaré Systems on Matrix Lie Groups" (2024) and its
//! extension (arXiv 2511.18800), in coordinates as written out in the project's `MATH.md`.
//!
//! * `#![no_std]`, no `alloc`, no `unsafe`: fixed-size nalgebra matrices only.
//! * Generic over the scalar ([`Real`]: `f32` for a microcontroller FPU, `f64` on Linux) and over
//!   the group ([`MatrixLieGroup`]: [`So3`], [`Se3`]).
//!
//! Module map (one equation of MATH.md, one named function):
//!
//! | module | what |
//! |---|---|
//! | [`group`] | the Lie groups: `hat`, `vee`, `exp`, `log`, `Ad`, `ad`, basis |
//! | [`semidirect`] | the phase-space group `G ⋉ g*`, the actions φ and ψ, the vector field f |
//! | [`tracking`] | tracking error, error inputs, error inertia, Lyapunov function |
//! | [`law`] | the EqT law (any group), the SO(3) closed forms EqT, GT, nog, asym, the [`Controller`] |
//! | [`reference`] | the desired-trajectory generator with cosine-series feedforward |
//! | [`integrator`] | RKMK4 on the group, the rigid body |
//! | [`closed_loop`] | controller + reference + plant in one loop (simulation, firmware) |
//!
//! Quick start (the seed paper's closed loop on SO(3), 1 s of it):
//!
//! ```
//! use controller::{closed_loop::ClosedLoop, so3_seed_feedforward, Law, ControllerConfig,
//!                  So3, group::MatrixLieGroup};
//! use nalgebra::{Matrix3, Vector3};
//!
//! let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759);
//! let config = ControllerConfig {
//!     law: Law::Eqt,
//!     inertia,
//!     k: Matrix3::identity() * 0.5,
//!     kd: Matrix3::identity() * 0.5,
//!     torque_limit: None,
//! };
//! let r0 = So3::exp(&(Vector3::new(0.8, 0.6, 0.0) * (core::f64::consts::PI - 0.1)));
//! let mut sim = ClosedLoop::<f64, So3, 3, 3>::new(
//!     config, inertia, r0, Vector3::new(4.0, -3.0, 2.0),
//!     Matrix3::identity(), Vector3::zeros(), so3_seed_feedforward(),
//!     0.01, 10, 10,
//! ).unwrap();
//! let first = sim.step().unwrap();
//! for _ in 0..99 { sim.step().unwrap(); }
//! let later = sim.step().unwrap();
//! assert!(later.lyapunov < first.lyapunov);
//! assert!(later.torque.iter().all(|t| t.is_finite()));
//! ```
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod closed_loop;
pub mod error;
pub mod group;
pub mod integrator;
pub mod law;
pub mod reference;
pub mod semidirect;
pub mod tracking;
pub mod validate;

pub use error::{Error, Quantity};
pub use group::{GroupKind, MatrixLieGroup, Se3, So3};
pub use law::{Controller, ControllerConfig, Law, LawOutput};
pub use reference::{so3_seed_feedforward, AxisTorque, CosTerm, Feedforward, Reference};

/// The scalar type: a real field that is `Copy` (`f32`, `f64`).
///
/// With nalgebra's `libm-force` feature the transcendental functions are libm's on every
/// target, so host tests run the same maths as a microcontroller.
pub trait Real: nalgebra::RealField + Copy {}
impl<T: nalgebra::RealField + Copy> Real for T {}

/// Converts an `f64` constant into the scalar type.
#[inline(always)]
pub fn real<T: Real>(x: f64) -> T {
    nalgebra::convert(x)
}
