//! Typed errors: no panics, no NaN torques.

use crate::law::Law;
use core::fmt;

/// The quantity an [`Error`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// The model inertia `I` (m×m).
    Inertia,
    /// The potential weight `K` (n×n).
    PotentialGain,
    /// The damping gain `K_d` (m×m).
    DampingGain,
    /// The per-axis torque limit.
    TorqueLimit,
    /// The measured state `(Q, V)`.
    State,
    /// The desired trajectory `(Q_d, p_d)` or its initial value.
    Reference,
    /// The feedforward torque description.
    Feedforward,
    /// The torque computed by the law.
    Torque,
    /// A disturbance torque.
    Disturbance,
    /// The control period or a step length.
    Period,
    /// A number of integration substeps.
    Substeps,
    /// The disturbance observer's gain `L`.
    ObserverGain,
    /// The disturbance observer's clamp.
    ObserverLimit,
    /// The integral gain `K_I`.
    IntegralGain,
    /// The integral's weight `c` of the configuration error.
    IntegralWeight,
    /// The clamp of the integral's torque.
    IntegralLimit,
    /// The torque the plant applied over the last period.
    AppliedTorque,
    /// The reaction wheels' speeds a state carries (one per wheel of the vehicle).
    WheelSpeeds,
}

impl Quantity {
    /// A short human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Inertia => "inertia",
            Quantity::PotentialGain => "potential gain K",
            Quantity::DampingGain => "damping gain K_d",
            Quantity::TorqueLimit => "torque limit",
            Quantity::State => "state",
            Quantity::Reference => "reference",
            Quantity::Feedforward => "feedforward torque",
            Quantity::Torque => "torque",
            Quantity::Disturbance => "disturbance",
            Quantity::Period => "period",
            Quantity::Substeps => "substeps",
            Quantity::ObserverGain => "disturbance observer gain L",
            Quantity::ObserverLimit => "disturbance observer limit",
            Quantity::IntegralGain => "integral gain K_I",
            Quantity::IntegralWeight => "integral weight c",
            Quantity::IntegralLimit => "integral limit",
            Quantity::AppliedTorque => "applied torque",
            Quantity::WheelSpeeds => "wheel speeds",
        }
    }
}

/// Everything that can go wrong in the controller crate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// A number is NaN or infinite.
    NonFinite(Quantity),
    /// A matrix that must be symmetric is not.
    NotSymmetric(Quantity),
    /// A matrix that must be positive definite is not.
    NotPositiveDefinite(Quantity),
    /// A number that must be strictly positive is not (limit, period, substeps).
    NotPositive(Quantity),
    /// A slice had the wrong number of entries.
    WrongShape {
        /// What was being read.
        quantity: Quantity,
        /// The number of entries accepted (for gains: 1 or this).
        expected: usize,
        /// The number of entries given.
        found: usize,
    },
    /// The law is not defined on the group (GT, nog, asym exist for SO(3) only).
    LawNotDefined {
        /// The law asked for.
        law: Law,
        /// The group it was asked of ([`MatrixLieGroup::NAME`](crate::MatrixLieGroup::NAME)).
        group: &'static str,
    },
    /// A feature that works in world axes (the disturbance observer with
    /// `frame = World`) was asked of a group without an attitude
    /// ([`MatrixLieGroup::attitude`](crate::MatrixLieGroup::attitude) is `None`).
    NoAttitude {
        /// The group's name.
        group: &'static str,
    },
    /// A feedforward axis holds more cosine terms than the fixed capacity.
    TooManyTerms {
        /// The axis index.
        axis: usize,
        /// The capacity per axis.
        capacity: usize,
    },
    /// A path's times do not increase strictly (at waypoint or segment `index`).
    NotIncreasing {
        /// The first offending waypoint (or segment) index.
        index: usize,
    },
    /// A path holds more segments than its fixed capacity.
    TooManySegments {
        /// The capacity.
        capacity: usize,
    },
    /// A path through waypoints was given a non-zero velocity at its first or last waypoint
    /// (it is held at rest before the first and after the last).
    NotAtRest {
        /// The waypoint index.
        index: usize,
    },
    /// A leg built through waypoints does not reach its end waypoint in floating point (its
    /// numbers — a huge velocity, position or time — leave too few digits).
    MissesWaypoint {
        /// The waypoint index.
        index: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NonFinite(q) => write!(f, "{} contains a non-finite number", q.name()),
            Error::NotSymmetric(q) => write!(f, "{} is not symmetric", q.name()),
            Error::NotPositiveDefinite(q) => write!(f, "{} is not positive definite", q.name()),
            Error::NotPositive(q) => write!(f, "{} must be strictly positive", q.name()),
            Error::WrongShape {
                quantity,
                expected,
                found,
            } => write!(
                f,
                "{} has {} entries, expected {}",
                quantity.name(),
                found,
                expected
            ),
            Error::LawNotDefined { law, group } => write!(
                f,
                "law {} is not defined for group {} (only eqt is defined on every group)",
                law.name(),
                group
            ),
            Error::NoAttitude { group } => write!(
                f,
                "the observer's world frame needs an attitude, and group {group} has none \
                 (its MatrixLieGroup::attitude is None): use frame = body"
            ),
            Error::TooManyTerms { axis, capacity } => write!(
                f,
                "feedforward axis {} has more than {} cosine terms",
                axis, capacity
            ),
            Error::NotIncreasing { index } => write!(
                f,
                "path times must increase strictly; waypoint {index} is not later than the one before"
            ),
            Error::TooManySegments { capacity } => write!(
                f,
                "a path holds at most {capacity} segments ({} waypoints)",
                capacity + 1
            ),
            Error::NotAtRest { index } => write!(
                f,
                "a path starts and ends at rest: the velocity given at waypoint {index} must be zero"
            ),
            Error::MissesWaypoint { index } => write!(
                f,
                "the leg to waypoint {index} does not reach it in floating point: its velocities, positions or times are too large for the numbers to keep their digits"
            ),
        }
    }
}

impl core::error::Error for Error {}
