//! The controller's cycle as the processor-in-the-loop firmware runs it (docs/pil.md): all
//! `f32`, `no_std`, no `alloc`. A [`Cycle`] is built from a [`Config`] (the scenario's
//! controller settings, cast to `f32` once on the host and carried as postcard bytes), and
//! turns each frame received on the serial line into the frame to send back:
//!
//! - `Hello` (the plant's identity): compared with its own; equal, it answers `Hello` and
//!   starts the run over (reference at `t = 0`, rejection terms cleared); different, it
//!   answers `Refused` with the mismatch bits, as the iceoryx2 pair's controller does.
//! - `State` (k, `t_k`, `Q`, `V`, the wrench applied): the reference stepped to k, the law
//!   (docs/maths.md, "The EqT law") with its rejection terms
//!   (docs/maths.md, "Disturbance rejection"), and a `Command` with the wrench, `L` and the
//!   terms. Before a handshake it answers the first state with its `Hello` instead (a
//!   controller that has just reset asks to be greeted) and the next ones with nothing.
//! - `Bye`: the run is over; it waits for the next `Hello`.
//!
//! The firmware wraps this with its UART and its interrupts; `plant_sim sim
//! --controller-scalar f32` wraps it in process. Both run these lines, so a processor-in-the-
//! loop run equals the in-process `f32` simulation bit for bit.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod config;
mod engine;
mod onboard;
mod watch;

pub use config::{
    Axis, Config, ConfigError, Failsafe, Integral, MAX_CONFIG, Observer, Series, Term,
};
pub use onboard::{Detector, Estimator, Failure, Gate, Momentum, Thruster, Vehicle, Wheel};

use engine::Engine;
use eqtrack_controller::group::{Se3, So3};
use eqtrack_serial_wire::{Frame, Hello, StateFrame};

/// Why a state got no command (counted by the cycle; the plant sees a missing command and
/// applies its deadline policy).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dropped {
    /// A vector of the wrong length for the group.
    Shape,
    /// An earlier step than the reference has reached (an old or repeated state).
    Backwards,
    /// More than [`MAX_SEQ_JUMP`] steps ahead of the reference.
    Jump,
    /// The law refused it (a non-finite number).
    Law,
}

/// The most control steps one state may move the reference ahead (as the pair's check).
pub const MAX_SEQ_JUMP: u64 = 1_000_000;

/// What a cycle has counted since it started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// States answered.
    pub answered: u64,
    /// States dropped, by reason ([`Dropped`] in order).
    pub dropped: [u64; 4],
    /// Handshakes refused.
    pub refused: u64,
}

#[expect(
    clippy::large_enum_variant,
    reason = "no alloc, so no Box: a firmware holds one cycle, of the group it was built for"
)]
enum Group {
    So3(Engine<So3, 3, 3>),
    Se3(Engine<Se3, 4, 6>),
}

/// The controller's side of the serial link.
pub struct Cycle {
    identity: Hello,
    /// The identity's control period (s) in `f32`, rounded once.
    period: f32,
    group: Group,
    greeted: bool,
    /// A `Hello` was sent unasked since the last handshake (one is enough).
    asked: bool,
    counts: Counts,
}

impl Cycle {
    /// The cycle of `config` (checked: shapes, the controller's own checks).
    pub fn new(config: &Config) -> Result<Cycle, ConfigError> {
        config.origin()?;
        let group = match config.identity.group {
            1 => Group::So3(Engine::new(config)?),
            2 => Group::Se3(Engine::new(config)?),
            other => return Err(ConfigError::Group(other)),
        };
        Ok(Cycle {
            identity: config.identity.clone(),
            period: config.identity.period as f32,
            group,
            greeted: false,
            asked: false,
            counts: Counts::default(),
        })
    }

    /// The cycle of a [`Config`] in postcard bytes ([`Config::to_bytes`]).
    pub fn from_bytes(bytes: &[u8]) -> Result<Cycle, ConfigError> {
        Cycle::new(&Config::from_bytes(bytes)?)
    }

    /// This controller's identity: its `Hello`.
    pub fn hello(&self) -> Frame {
        Frame::Hello(self.identity.clone())
    }

    /// Whether a plant has greeted it with a matching identity since the last `Bye`.
    pub fn greeted(&self) -> bool {
        self.greeted
    }

    /// What it has counted.
    pub fn counts(&self) -> Counts {
        self.counts
    }

    /// The frame to send back for `frame` (`None`: nothing to send).
    pub fn on_frame(&mut self, frame: &Frame) -> Option<Frame> {
        match frame {
            Frame::Hello(plant) => {
                let mismatch = self.identity.mismatch(plant);
                if mismatch != 0 {
                    self.greeted = false;
                    self.counts.refused += 1;
                    return Some(Frame::Refused {
                        mismatch,
                        identity: self.identity.clone(),
                    });
                }
                self.greeted = true;
                self.asked = false;
                match &mut self.group {
                    Group::So3(e) => e.restart(),
                    Group::Se3(e) => e.restart(),
                }
                Some(self.hello())
            }
            // states before the handshake (a reset, a plant that skipped it): one `Hello`
            // asks to be greeted; the states queued behind that one get nothing, so the plant
            // sees one request, not a storm of them
            Frame::State(_) if !self.greeted => {
                let first = !self.asked;
                self.asked = true;
                first.then(|| self.hello())
            }
            Frame::State(state) => self.answer(state),
            Frame::Bye => {
                self.greeted = false;
                self.asked = false;
                None
            }
            Frame::Command(_) | Frame::Refused { .. } => None,
        }
    }

    fn answer(&mut self, state: &StateFrame) -> Option<Frame> {
        let period = self.period;
        let out = match &mut self.group {
            Group::So3(e) => e.answer(state, period),
            Group::Se3(e) => e.answer(state, period),
        };
        match out {
            Ok(cmd) => {
                self.counts.answered += 1;
                Some(Frame::Command(cmd))
            }
            Err(why) => {
                self.counts.dropped[why as usize] += 1;
                None
            }
        }
    }
}
