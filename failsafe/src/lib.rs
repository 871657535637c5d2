//! The failsafe manager (docs/failsafe.md): one pure state machine,
//! `(state, inputs) → (state, transition)`, with no clock, I/O or allocation inside, so that
//! it runs wherever the controller runs, a microcontroller included.
//!
//! * **Causes.** Four: the link (a state lost on the way to the controller), the estimator (its health not
//!   `healthy`), the actuators (a failure found, or a wrench the allocation cannot produce)
//!   and the tracking (an error beyond its limit). The caller turns its measurements into one
//!   flag per cause each tick.
//! * **Actions.** Each cause the configuration names has an action: `warn`, `hold`, `damp`,
//!   `descend`, `surface` or `disarm`. A cause without one is ignored.
//! * **Rules.**
//!   - A cause is raised on the first tick its flag is set: a failsafe acts at once.
//!   - It clears when its flag has stayed down for `clear_ticks` ticks in a row
//!     (hysteresis), unless it latches. `tracking` latches, and so does any cause whose action
//!     is `disarm`: a run that diverged is not resumed, and a disarmed vehicle is not re-armed
//!     by software.
//!   - Of the raised causes, the one with the most severe action is engaged:
//!     `disarm` > `descend` = `surface` > `damp` > `hold` > `warn`. A tie goes to the cause
//!     already engaged, else to the one named first in [`Cause::ALL`] (link, estimator,
//!     actuators, tracking): an equal cause does not take over (a hold keeps its pose).
//!   - When every raised cause has cleared, the vehicle is back to nominal.
//! * **Transitions.** Every change of the engaged cause or action is returned, for the caller
//!   to record.
//! * **Set-points.** [`setpoint::Supervised`] flies the engaged action in place of the
//!   reference (docs/failsafe.md, "What each action flies").
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod monitor;
pub mod setpoint;
pub mod thrust_axis;

/// What raises a failsafe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cause {
    /// A state lost on the way to the controller (a gap in the states it answers).
    Link,
    /// The estimator's health is not `healthy`.
    Estimator,
    /// An actuator failure found, or a demanded wrench the allocation cannot produce.
    Actuators,
    /// The tracking error beyond its limit.
    Tracking,
}

impl Cause {
    /// Every cause, in the order that breaks a tie of severity.
    pub const ALL: [Cause; 4] = [
        Cause::Link,
        Cause::Estimator,
        Cause::Actuators,
        Cause::Tracking,
    ];

    /// The configuration's and the summary's name.
    pub fn name(self) -> &'static str {
        match self {
            Cause::Link => "link",
            Cause::Estimator => "estimator",
            Cause::Actuators => "actuators",
            Cause::Tracking => "tracking",
        }
    }

    /// The cause of a name.
    pub fn parse(name: &str) -> Option<Cause> {
        Cause::ALL.into_iter().find(|c| c.name() == name)
    }

    fn index(self) -> usize {
        self as usize
    }

    /// Its code on the wire: 1 link, 2 estimator, 3 actuators, 4 tracking.
    pub fn code(self) -> u32 {
        self as u32 + 1
    }
}

/// What the vehicle does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Report it, and fly on.
    Warn,
    /// Hold a set-point at the pose where it engaged.
    Hold,
    /// The damping-only safe mode, `τ = −K_d V`.
    Damp,
    /// Come down at the configured rate (vehicles with gravity).
    Descend,
    /// Rise at the configured rate with no horizontal effort (buoyant vehicles).
    Surface,
    /// Every actuator to its minimum.
    Disarm,
}

impl Action {
    /// Every action.
    pub const ALL: [Action; 6] = [
        Action::Warn,
        Action::Hold,
        Action::Damp,
        Action::Descend,
        Action::Surface,
        Action::Disarm,
    ];

    /// The configuration's and the summary's name.
    pub fn name(self) -> &'static str {
        match self {
            Action::Warn => "warn",
            Action::Hold => "hold",
            Action::Damp => "damp",
            Action::Descend => "descend",
            Action::Surface => "surface",
            Action::Disarm => "disarm",
        }
    }

    /// The action of a name.
    pub fn parse(name: &str) -> Option<Action> {
        Action::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Its code on the wire and in `trajectory.csv`'s `failsafe` column: 1 `warn`, 2 `hold`,
    /// 3 `damp`, 4 `descend`, 5 `surface`, 6 `disarm` (0 is nominal).
    pub fn code(self) -> u32 {
        self as u32 + 1
    }

    /// How severe: `warn` 0, `hold` 1, `damp` 2, `descend` and `surface` 3, `disarm` 4.
    pub fn severity(self) -> u8 {
        match self {
            Action::Warn => 0,
            Action::Hold => 1,
            Action::Damp => 2,
            Action::Descend | Action::Surface => 3,
            Action::Disarm => 4,
        }
    }
}

/// The manager's configuration: an action per cause (`None`: the cause is ignored) and the
/// hysteresis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// The action of each cause, indexed as [`Cause::ALL`].
    pub actions: [Option<Action>; 4],
    /// Ticks a cause's flag must stay down before it clears (at least 1).
    pub clear_ticks: u32,
}

impl Config {
    /// The action `cause` engages, if any.
    pub fn action(&self, cause: Cause) -> Option<Action> {
        self.actions[cause.index()]
    }

    /// Whether `cause`, once raised, never clears: `tracking`, and a cause that disarms.
    pub fn latches(&self, cause: Cause) -> bool {
        cause == Cause::Tracking || self.action(cause) == Some(Action::Disarm)
    }
}

/// The flags of one tick, one per cause.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Inputs {
    /// A state lost on the way to the controller (a gap in the states it answers).
    pub link: bool,
    /// The estimator is not healthy.
    pub estimator: bool,
    /// An actuator failure, or a wrench the allocation cannot produce.
    pub actuators: bool,
    /// The tracking error beyond its limit.
    pub tracking: bool,
}

impl Inputs {
    fn flag(&self, cause: Cause) -> bool {
        match cause {
            Cause::Link => self.link,
            Cause::Estimator => self.estimator,
            Cause::Actuators => self.actuators,
            Cause::Tracking => self.tracking,
        }
    }
}

/// What the vehicle is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Flying its reference.
    Nominal,
    /// A failsafe engaged by `cause`.
    Engaged {
        /// The cause.
        cause: Cause,
        /// Its action.
        action: Action,
    },
}

impl Mode {
    /// The engaged action (`None`: nominal).
    pub fn action(self) -> Option<Action> {
        match self {
            Mode::Nominal => None,
            Mode::Engaged { action, .. } => Some(action),
        }
    }

    /// The engaged cause (`None`: nominal).
    pub fn cause(self) -> Option<Cause> {
        match self {
            Mode::Nominal => None,
            Mode::Engaged { cause, .. } => Some(cause),
        }
    }
}

/// The manager's state between ticks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct State {
    mode: Mode,
    raised: [bool; 4],
    /// Ticks each raised cause's flag has been down.
    down: [u32; 4],
}

impl Default for State {
    fn default() -> Self {
        State {
            mode: Mode::Nominal,
            raised: [false; 4],
            down: [0; 4],
        }
    }
}

impl State {
    /// The state as one word (the command's `failsafe` field, docs/wire.md): the engaged
    /// action's code in bits 0–3 (0: nominal), its cause's code in bits 4–7, and one bit per
    /// raised cause from bit 8 on, in the order of [`Cause::ALL`].
    pub fn word(&self) -> u32 {
        let (action, cause) = match self.mode {
            Mode::Nominal => (0, 0),
            Mode::Engaged { cause, action } => (action.code(), cause.code()),
        };
        let raised = Cause::ALL
            .iter()
            .filter(|c| self.raised[c.index()])
            .fold(0, |w, c| w | 1 << (8 + c.index()));
        action | cause << 4 | raised
    }

    /// What a word says: the mode and the raised causes (`None`: not a word [`State::word`]
    /// writes — a code out of range, an action without its cause or the reverse, the engaged
    /// cause not raised, or a bit above the raised causes').
    pub fn read_word(word: u32) -> Option<(Mode, [bool; 4])> {
        if word >> 12 != 0 {
            return None;
        }
        let raised: [bool; 4] = core::array::from_fn(|i| word & 1 << (8 + i) != 0);
        let code = |c: u32| c.checked_sub(1).map(|i| i as usize);
        let mode = match (code(word & 0xf), code(word >> 4 & 0xf)) {
            (None, None) => Mode::Nominal,
            (Some(a), Some(c)) => Mode::Engaged {
                action: *Action::ALL.get(a)?,
                cause: *Cause::ALL.get(c).filter(|c| raised[c.index()])?,
            },
            _ => return None,
        };
        Some((mode, raised))
    }

    /// What the vehicle is doing.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Whether `cause` is raised.
    pub fn raised(&self, cause: Cause) -> bool {
        self.raised[cause.index()]
    }
}

/// A change of what the vehicle does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transition {
    /// Before.
    pub from: Mode,
    /// After.
    pub to: Mode,
}

/// One tick (docs/failsafe.md): raises the causes whose flags are set (and that have an
/// action), clears those whose flags have been down `clear_ticks` ticks unless they latch,
/// and engages the most severe; returns the new state and the transition, if the mode changed.
pub fn step(cfg: &Config, state: &State, inputs: &Inputs) -> (State, Option<Transition>) {
    let mut next = *state;
    let hold = cfg.clear_ticks.max(1);
    for cause in Cause::ALL {
        let i = cause.index();
        if cfg.action(cause).is_none() {
            next.raised[i] = false;
            continue;
        }
        if inputs.flag(cause) {
            next.raised[i] = true;
            next.down[i] = 0;
        } else if next.raised[i] && !cfg.latches(cause) {
            next.down[i] = next.down[i].saturating_add(1);
            if next.down[i] >= hold {
                next.raised[i] = false;
                next.down[i] = 0;
            }
        }
    }
    // the engaged cause keeps its place against a cause of equal severity
    let mut engaged: Option<(Cause, Action)> = match state.mode {
        Mode::Engaged { cause, action } if next.raised[cause.index()] => Some((cause, action)),
        _ => None,
    };
    for cause in Cause::ALL {
        if let (true, Some(action)) = (next.raised[cause.index()], cfg.action(cause))
            && engaged.is_none_or(|(_, a)| action.severity() > a.severity())
        {
            engaged = Some((cause, action));
        }
    }
    next.mode = match engaged {
        None => Mode::Nominal,
        Some((cause, action)) => Mode::Engaged { cause, action },
    };
    let transition = (next.mode != state.mode).then_some(Transition {
        from: state.mode,
        to: next.mode,
    });
    (next, transition)
}

#[cfg(test)]
mod tests;
