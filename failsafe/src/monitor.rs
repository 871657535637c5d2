//! The manager with what it measures itself (docs/failsafe.md, "Causes"): the tracking error
//! against its limits, armed only once the error has been within them, and the state machine
//! stepped with the other causes' flags. The in-process simulation, the pair's controller and
//! the firmware run this one, so they raise the same causes on the same ticks.

use crate::{Action, Cause, Config, Inputs, Mode, State, Transition};
use eqtrack_controller::Real;

/// The flags of the causes the caller measures: all but `tracking`, which the monitor
/// measures itself.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Flags {
    /// A state lost on the way to the controller (a gap in the states it answers), or a
    /// command the plant did not apply (it came after its deadline).
    pub link: bool,
    /// The estimator's health is not `healthy`.
    pub estimator: bool,
    /// The actuators no longer span every wrench.
    pub actuators: bool,
}

/// The tracking limits (`None`: no limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits<T> {
    /// `tracking_limit_attitude` (rad).
    pub attitude: Option<T>,
    /// `tracking_limit_position` (m).
    pub position: Option<T>,
}

/// The manager and its tracking measurement between ticks. Allocation-free, no clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Monitor<T> {
    config: Config,
    limits: Limits<T>,
    state: State,
    /// Whether the tracking error has been within its limits since the start or the last
    /// transition: only then does passing a limit raise `tracking`.
    armed: bool,
    /// The errors (rad, m) of the tick that first raised `tracking`, and how many ticks had
    /// run before it.
    tripped: Option<(u64, T, T)>,
    ticks: u64,
}

impl<T: Real> Monitor<T> {
    /// A monitor in the nominal state.
    pub fn new(config: Config, limits: Limits<T>) -> Self {
        Monitor {
            config,
            limits,
            state: State::default(),
            armed: false,
            tripped: None,
            ticks: 0,
        }
    }

    /// One tick: `tracking`'s flag from the tracking `errors` (attitude rad, position m)
    /// against the limits (an error that is not a number is beyond), the manager stepped with
    /// it and the caller's `flags`. A run that starts beyond a limit, or rejoins a reference
    /// beyond it after a transition, is not a runaway until its error has once been within.
    /// Returns the transition, if any.
    pub fn tick(&mut self, (angle, distance): (T, T), flags: Flags) -> Option<Transition> {
        let beyond = |limit: Option<T>, x: T| {
            limit.is_some_and(|l| {
                matches!(x.partial_cmp(&l), Some(core::cmp::Ordering::Greater) | None)
            })
        };
        let within =
            !(beyond(self.limits.attitude, angle) || beyond(self.limits.position, distance));
        self.armed |= within;
        let tracking = self.armed && !within;
        if tracking && self.tripped.is_none() {
            self.tripped = Some((self.ticks, angle, distance));
        }
        let inputs = Inputs {
            link: flags.link,
            estimator: flags.estimator,
            actuators: flags.actuators,
            tracking,
        };
        let (next, transition) = crate::step(&self.config, &self.state, &inputs);
        self.state = next;
        self.ticks += 1;
        if transition.is_some() {
            self.armed = false;
        }
        transition
    }

    /// The manager's state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Whether the engaged action disarms (every actuator to its minimum).
    pub fn disarmed(&self) -> bool {
        matches!(
            self.state.mode(),
            Mode::Engaged {
                action: Action::Disarm,
                ..
            }
        )
    }

    /// When `tracking` was raised (it latches, so the run ends in its action, or under a more
    /// severe one): the tick (counted from 0) its error first passed a limit, and the errors
    /// then (rad, m). Such a run exits non-zero.
    pub fn runaway(&self) -> Option<(u64, T, T)> {
        self.tripped.filter(|_| self.state.raised(Cause::Tracking))
    }
}

/// A scalar whose bits can be compared: `f32`, `f64`.
pub trait Bits: Copy {
    /// The IEEE 754 bits (an `f32`'s widened).
    fn bits(self) -> u64;
}

impl Bits for f32 {
    fn bits(self) -> u64 {
        u64::from(self.to_bits())
    }
}

impl Bits for f64 {
    fn bits(self) -> u64 {
        self.to_bits()
    }
}

/// Whether a state's `applied` wrench is, bit for bit, the one the controller's answer before
/// it counted as applied (`sent`, paired entry by entry with `applied`; `None`: no answer
/// yet). A command that reaches the plant after its deadline is not applied: the plant holds
/// the one before it, or flies its safe mode, and reports that wrench instead
/// (docs/failsafe.md, "Causes"), which raises `link` and tells the failure detector the
/// residual's window has a gap. A held command equal bit for bit to the late one is not told
/// apart, and changes nothing the law believes.
pub fn applied_as_sent<T: Bits>(sent: Option<&[T]>, applied: &[T]) -> bool {
    sent.is_some_and(|s| s.iter().zip(applied).all(|(x, y)| x.bits() == y.bits()))
}

/// Whether an allocation fell short of its torque (docs/failsafe.md, "Causes"): its status
/// says the torque could not be met within the bounds (`eqtrack_allocation::Status` code 1), and the
/// torque it could not give, `|τ_demand − τ_achieved|`, exceeds `limit`
/// (`actuators_residual`; `None`: never). One of the `actuators` cause's two conditions, read
/// from the allocation before the tick.
pub fn torque_short<T: Real>(status: u8, residual: T, limit: Option<T>) -> bool {
    limit.is_some_and(|l| status == 1 && residual > l)
}
