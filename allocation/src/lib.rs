//! Control allocation for fully actuated vehicles (docs/maths.md, "Control allocation"):
//! from the wrench the law asks for to the commands of the actuators that must produce it —
//! the rotors of a tilted-rotor hexarotor, the thrusters of an ROV or a spacecraft.
//!
//! * [`Geometry`]: each actuator's position, axis, torque per unit thrust and bounds, turned
//!   into the effectiveness matrix `B` (a column `[p × a + c a ; a]` per actuator). A geometry
//!   that cannot produce some wrench direction is refused, naming the direction.
//! * [`Allocator`]: the prioritised bounded allocation. Within the bounds it first comes as
//!   close as it can to the torque, then, keeping that torque, to the force, then, keeping
//!   both, to the preferred command; [`Priority::None`] treats the wrench as one. An
//!   active-set method with an iteration cap; every answer is finite and within the bounds,
//!   with a [`Status`].
//! * Failures: [`Bounds::fail`] holds a failed actuator at its stuck value;
//!   [`Allocator::scaled`] scales the column of one that lost effectiveness.
//! * [`Wheel`], [`WheelSet`]: reaction wheels as columns of `B`, the gyroscopic torque
//!   their momentum puts on a turning body, and bounds that close at a wheel's top speed.
//! * [`Restoring`]: gravity and buoyancy as a body wrench, which the controller compensates
//!   and the plant integrates.
//!
//! ```
//! use eqtrack_allocation::{Allocator, Geometry, Priority, Status, presets};
//! use nalgebra::SVector;
//!
//! // a tilted-rotor hexarotor: arm 0.25 m, rotors tilted 0.5 rad, drag 0.016 m, 0..8 N
//! let rotors = presets::hexarotor(0.25, 0.5, 0.016, 8.0);
//! let geometry = Geometry::<f64, 6>::new(&rotors).unwrap();
//! let alloc = Allocator::new(geometry, &[], &[], Priority::Torque).unwrap();
//! // hover: 20 N up, no torque
//! let hover = SVector::<f64, 6>::from([0.0, 0.0, 0.0, 0.0, 0.0, 20.0]);
//! let a = alloc.allocate(&hover);
//! assert_eq!(a.status, Status::Met);
//! assert!((a.achieved - hover).amax() < 1e-9);
//! // more than the rotors can give: the torque is kept, the force given up
//! let far = SVector::<f64, 6>::from([0.0, 0.0, 1.2, 0.0, 0.0, 45.0]);
//! let b = alloc.allocate(&far);
//! assert_eq!(b.status, Status::ForceGivenUp);
//! assert!((b.achieved[2] - 1.2).abs() < 1e-9 && b.achieved[5] < 45.0);
//! ```
//!
//! `no_std`, no `alloc`, fixed capacity of [`MAX_ACTUATORS`]; generic over the scalar (`f32`
//! on a microcontroller, `f64` on Linux) and over the wrench dimension `K` (3 on SO(3), the
//! torque alone; 6 on SE(3), torque then force).
//!
//! ## Features
//!
//! - `planted-slow-path` (off by default): eqtrack's own CI only, never a vehicle: one more
//!   factorisation per active-set iteration, so that the firmware's worst-case check can be
//!   shown to catch a slow path.
//!
//! [`nalgebra`] is re-exported, so a user's wrench is this crate's type.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub use nalgebra;

mod allocator;
mod blocks;
mod control;
mod dual;
mod geometry;
pub mod presets;
mod qp;
mod reach;
mod restoring;
mod wheels;
mod zonotope;

pub use allocator::{
    Allocation, Allocator, AllocatorError, Bounds, DEFAULT_BUDGET, Priority, Reweighting, Status,
};
pub use control::{Actuation, SpanWatch, VehicleControl};
pub use geometry::{Actuator, Geometry, GeometryError, LostDirections};
pub use restoring::Restoring;
pub use wheels::{MAX_WHEELS, Momentum, Wheel, WheelSet};

/// The most actuators a geometry may have.
pub const MAX_ACTUATORS: usize = 12;

/// A vector over the actuators (entries past the geometry's count are 0).
pub type Commands<T> = nalgebra::SVector<T, MAX_ACTUATORS>;

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
