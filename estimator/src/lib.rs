//! # estimator — what a board measures, turned into the state the law needs
//!
//! `#![no_std]`, no `alloc`, no `unsafe`; fixed-size nalgebra maths, generic over the scalar
//! (`f32`, `f64`), with the group maths of the `eqtrack-controller` crate. It is not part of the law:
//! on a board it runs where the sensors are read (the plant side) and hands the controller
//! `(Q̂, V̂)` (docs/maths.md, "Estimators").
//!
//! | item | what |
//! |---|---|
//! | [`triad`] | an attitude from two direction pairs |
//! | [`ComplementaryFilter`] | Mahony–Hamel–Pflimlin's explicit complementary filter with gyro bias, on SO(3) |
//! | [`EquivariantFilter`] | the equivariant filter (EqF) for attitude and gyro bias: a 6×6 covariance, gains from physical noise |
//! | [`PoseFilter`] | SE(3): the same filter for attitude (the accelerometer one more direction), and a linear Kalman filter for position and velocity |
//! | [`Settings`], [`Filter`] | a filter of either kind on either group from a scenario's numbers, one step of it as the law's `(Q̂, V̂)` |
//! | [`StateEstimate`] | an estimate as the controller's `(Q̂, V̂)`: `(SMatrix<T, N, N>, SVector<T, M>)` |
//!
//! Bad samples never make a filter panic or publish a non-finite estimate: they are skipped
//! or the previous estimate is held, and each is counted in [`Faults`].
//!
//! ## Features
//!
//! - `serde` (off by default): `Serialize` on [`Faults`] and on the health monitor's
//!   [`health::Source`] and [`health::Reason`].
//!
//! [`nalgebra`] is re-exported, so a user's vectors are this crate's, and so are
//! [`eqtrack_controller`] and its scalar bound [`Real`].
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

/// The group maths this crate builds on, and its scalar bound [`Real`] that every filter's
/// `T` meets: generic code over the filters needs no second dependency to name it.
pub use eqtrack_controller;
pub use eqtrack_controller::Real;
pub use nalgebra;

mod complementary;
pub mod eqf;
pub mod health;
mod pose;
mod settings;
mod triad;

pub use complementary::{AttitudeEstimate, ComplementaryConfig, ComplementaryFilter};
pub use eqf::{EqfConfig, EquivariantFilter};
pub use pose::{MIN_VARIANCE, PoseConfig, PoseEstimate, PoseFilter, TranslationCovariance};
pub use settings::{Filter, FilterKind, Settings, Step};
pub use triad::triad;

use nalgebra::{SMatrix, SVector};

/// At most this many direction sensors (on SE(3) the accelerometer comes on top).
pub const MAX_DIRECTIONS: usize = 4;

/// Standard gravity (m/s²); the world's gravity is `g = (0, 0, −GRAVITY)`.
pub const GRAVITY: f64 = 9.81;

/// A direction shorter than this (after a non-finite check) is skipped: it has no direction.
pub const MIN_DIRECTION_NORM: f64 = 1e-6;

/// What is wrong with a filter's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorError {
    /// A gain or guard is negative, zero where it must not be, or not finite.
    BadGain(&'static str),
    /// More world directions than [`MAX_DIRECTIONS`], or fewer than the filter needs.
    DirectionCount {
        /// Directions given.
        given: usize,
        /// The fewest accepted.
        min: usize,
        /// The most accepted.
        max: usize,
    },
    /// Not as many weights as the filter needs (one per world direction, and on SE(3) one
    /// more, last, for the accelerometer).
    WeightCount {
        /// Weights needed.
        expected: usize,
        /// Weights given.
        given: usize,
    },
    /// A world direction is zero or not finite (its index).
    BadDirection(usize),
    /// A weight is not finite and positive (its index).
    BadWeight(usize),
    /// A direction's noise is not finite and positive (its index).
    BadNoise(usize),
    /// An initial value is not finite or not a rotation.
    BadInitialState,
}

impl core::fmt::Display for EstimatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EstimatorError::BadGain(which) => write!(f, "{which} must be finite and ≥ 0"),
            EstimatorError::DirectionCount { given, min, max } => {
                write!(f, "{given} directions given; {min} to {max} accepted")
            }
            EstimatorError::WeightCount { expected, given } => {
                write!(f, "{given} weights given; {expected} expected")
            }
            EstimatorError::BadDirection(i) => write!(f, "direction {i} is zero or not finite"),
            EstimatorError::BadWeight(i) => write!(f, "weight {i} must be finite and > 0"),
            EstimatorError::BadNoise(i) => {
                write!(f, "the noise of direction {i} must be finite and > 0")
            }
            EstimatorError::BadInitialState => f.write_str("the initial state is not valid"),
        }
    }
}

/// What the filters skipped, held or clamped, counted since they started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Faults {
    /// Gyro samples with a non-finite entry: the step held the previous estimate.
    pub gyro: u64,
    /// Direction samples skipped: a non-finite entry, or shorter than
    /// [`MIN_DIRECTION_NORM`].
    pub directions: u64,
    /// SE(3): accelerometer samples not used as a direction because `| |f| − g |` exceeded
    /// the gate.
    pub accel_gated: u64,
    /// SE(3): accelerometer samples with a non-finite entry (position and velocity were
    /// predicted without acceleration).
    pub accel: u64,
    /// SE(3): position fixes with a non-finite entry (skipped).
    pub position: u64,
    /// Bias components clamped to the limit.
    pub bias_clamped: u64,
    /// Ticks whose update was not used and the previous estimate held: the period `h` was
    /// not finite and positive, or the update came out non-finite (samples finite but so
    /// large that the arithmetic overflowed).
    pub held: u64,
}

/// An estimate in the controller's form `(Q̂, V̂)` on a group of n×n matrices with an
/// m-dimensional algebra: `SO(3)` (n = m = 3) for [`AttitudeEstimate`], `SE(3)` (n = 4,
/// m = 6, twists ordered (ω, v) as `eqtrack_controller::group::Se3`) for [`PoseEstimate`].
pub trait StateEstimate<T: eqtrack_controller::Real, const N: usize, const M: usize> {
    /// `Q̂`: the estimated configuration.
    fn q_hat(&self) -> SMatrix<T, N, N>;
    /// `V̂`: the estimated body velocity.
    fn v_hat(&self) -> SVector<T, M>;
    /// `(Q̂, V̂)`.
    fn state(&self) -> (SMatrix<T, N, N>, SVector<T, M>) {
        (self.q_hat(), self.v_hat())
    }
}

/// The usable, normalised direction samples of a tick, one slot per world direction and, on
/// SE(3), the accelerometer's "up" last (`None`: skipped).
pub type Directions<T> = [Option<nalgebra::Vector3<T>>; MAX_DIRECTIONS + 1];

/// An attitude filter's configuration, as the SE(3) [`PoseFilter`] reads it.
pub trait AttitudeConfig<T: eqtrack_controller::Real>: Copy + core::fmt::Debug + PartialEq {
    /// The filter it configures.
    type Filter: AttitudeFilter<T, Config = Self>;
    /// Checks the configuration again (its public fields may have been written directly).
    fn check(self) -> Result<Self, EstimatorError>;
    /// How many directions.
    fn count(&self) -> usize;
    /// World direction `i` (zero beyond the count).
    fn world(&self, i: usize) -> nalgebra::Vector3<T>;
    /// The bias estimate it starts from.
    fn initial_bias(&self) -> nalgebra::Vector3<T>;
}

/// An attitude filter the SE(3) [`PoseFilter`] can drive: the [`ComplementaryFilter`] or the
/// [`EquivariantFilter`].
pub trait AttitudeFilter<T: eqtrack_controller::Real>: Copy + core::fmt::Debug + PartialEq {
    /// Its configuration.
    type Config: AttitudeConfig<T>;
    /// Whether the attitude it publishes at tick k runs one tick ahead of the samples, so
    /// that the one published at tick k − 1 is its estimate of `R(t_k)` (the complementary
    /// filter's step: docs/maths.md, "The complementary filter on SO(3)"); false when the
    /// one published at tick k is.
    const LEADS: bool;
    /// A filter that starts at its first step (the configuration used as it is).
    fn from_config(cfg: Self::Config) -> Self;
    /// The configuration.
    fn config(&self) -> &Self::Config;
    /// The estimate published last.
    fn estimate(&self) -> &AttitudeEstimate<T>;
    /// What it has skipped, held and clamped so far.
    fn faults(&self) -> &Faults;
    /// The counts, for a filter that drives it to add its own.
    fn faults_mut(&mut self) -> &mut Faults;
    /// One tick on samples already checked and normalised (the filter's `step` after its
    /// check of the samples).
    fn step_usable(
        &mut self,
        h: T,
        gyro: &nalgebra::Vector3<T>,
        y: &Directions<T>,
    ) -> AttitudeEstimate<T>;
    /// What the innovation gate tests tick k's directions against
    /// (docs/estimators.md, "The innovation gate and health"): the attitude the filter
    /// compares them with and, for the EqF, the attitude block of its covariance propagated
    /// to tick k; `None` before the filter has started.
    fn prior(
        &self,
        h: T,
        gyro: &nalgebra::Vector3<T>,
    ) -> Option<(nalgebra::Matrix3<T>, Option<nalgebra::Matrix3<T>>)>;
    /// Direction slot `slot`'s noise in the filter's own model (the EqF's; 0 for a filter
    /// without one).
    fn noise(&self, slot: usize) -> T;
}

macro_rules! attitude_filter {
    ($filter:ident, $config:ident, $leads:expr) => {
        impl<T: eqtrack_controller::Real> AttitudeConfig<T> for $config<T> {
            type Filter = $filter<T>;
            fn check(self) -> Result<Self, EstimatorError> {
                $config::check(self)
            }
            fn count(&self) -> usize {
                self.count
            }
            fn world(&self, i: usize) -> nalgebra::Vector3<T> {
                self.world
                    .get(i)
                    .copied()
                    .unwrap_or_else(nalgebra::Vector3::zeros)
            }
            fn initial_bias(&self) -> nalgebra::Vector3<T> {
                self.initial_bias
            }
        }

        impl<T: eqtrack_controller::Real> AttitudeFilter<T> for $filter<T> {
            type Config = $config<T>;
            const LEADS: bool = $leads;
            fn from_config(cfg: Self::Config) -> Self {
                $filter::new(cfg)
            }
            fn config(&self) -> &Self::Config {
                $filter::config(self)
            }
            fn estimate(&self) -> &AttitudeEstimate<T> {
                $filter::estimate(self)
            }
            fn faults(&self) -> &Faults {
                $filter::faults(self)
            }
            fn faults_mut(&mut self) -> &mut Faults {
                $filter::faults_mut(self)
            }
            fn step_usable(
                &mut self,
                h: T,
                gyro: &nalgebra::Vector3<T>,
                y: &Directions<T>,
            ) -> AttitudeEstimate<T> {
                $filter::step_usable(self, h, gyro, y)
            }
            fn prior(
                &self,
                h: T,
                gyro: &nalgebra::Vector3<T>,
            ) -> Option<(nalgebra::Matrix3<T>, Option<nalgebra::Matrix3<T>>)> {
                $filter::prior(self, h, gyro)
            }
            fn noise(&self, slot: usize) -> T {
                $filter::noise(self, slot)
            }
        }
    };
}

attitude_filter!(ComplementaryFilter, ComplementaryConfig, true);
attitude_filter!(EquivariantFilter, EqfConfig, false);

/// Whether every entry is finite.
fn all_finite<T: eqtrack_controller::Real, const R: usize>(v: &nalgebra::SVector<T, R>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// A sample's direction `y/|y|` and length `|y|`, or `None` when it has a non-finite entry,
/// its length overflows, or it is shorter than [`MIN_DIRECTION_NORM`].
fn direction<T: eqtrack_controller::Real>(
    y: &nalgebra::Vector3<T>,
) -> Option<(nalgebra::Vector3<T>, T)> {
    let n = eqtrack_controller::hw_sqrt::norm(y);
    (all_finite(y) && n.is_finite() && n >= eqtrack_controller::real(MIN_DIRECTION_NORM))
        .then(|| (y / n, n))
}

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
