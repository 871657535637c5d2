//! # link — the process layer of eqtrack
//!
//! Everything a plant process or a controller process needs to talk to the other, and nothing
//! of the mathematics: one [`Transport`] trait with two implementations (iceoryx2 shared
//! memory, the product, and a Unix-datagram-socket baseline for benchmarks), and the two
//! handles a user writes a process against:
//!
//! * [`PlantEndpoint`] — open a run by name, publish a state, wait for the command of that
//!   state with a deadline (the command, or a typed miss), shut the run down;
//! * [`ControllerEndpoint`] — open a run by name, wait for a state, publish a command, learn
//!   that the plant is gone.
//!
//! Beside them: the plant's [`DeadlinePolicy`] (fresh → held → safe mode after N misses →
//! recovery; a pure state machine) and the real-time [`clock`]. The wire contract itself
//! (messages, checks, encoding) is the `ipc_types` crate; the architecture is described in
//! docs/architecture.md.
//!
//! A plant for a board, in outline (the whole example is `examples/example_plant.rs`):
//!
//! ```no_run
//! use eqtrack_controller::GroupKind;
//! use link::{Decision, DeadlinePolicy, PlantEndpointConfig, PlantEndpoint, clock};
//! use nalgebra::{Matrix3, Vector3};
//!
//! let period = 0.001;
//! let mut plant = PlantEndpoint::open(PlantEndpointConfig::new("board1", GroupKind::So3, period))?;
//! let mut policy = DeadlinePolicy::new(3);
//! let t0 = clock::monotonic_ns();
//! let mut torque = Vector3::<f64>::zeros(); // what the motors apply
//! for k in 0..1000u64 {
//!     let (q, v) = (Matrix3::<f64>::identity(), Vector3::<f64>::zeros()); // read the sensors
//!     plant.publish(k, &q, &v, &torque)?;
//!     let deadline = t0 + (k + 1) * 1_000_000;
//!     let got = plant.wait_command(k, deadline);
//!     let step = policy.step(k, deadline, got.as_ref().ok().map(|c| c.arrival()));
//!     torque = match (step.decision, &got) {
//!         (Decision::Fresh, Ok(cmd)) => cmd.torque(),
//!         _ => torque, // hold the last torque (or apply the safe-mode torque)
//!     };
//!     // drive the motors with `torque`
//!     clock::sleep_until(deadline);
//! }
//! plant.shutdown();
//! # Ok::<(), link::LinkError>(())
//! ```
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod clock;
pub mod controller_side;
pub mod deadline;
pub mod iceoryx2;
mod invalid;
pub mod notify;
pub mod params;
pub mod plan;
pub mod plant_side;
pub mod process;
pub mod rt;
pub mod serial;
pub mod status;
pub mod transport;
pub mod uds;
pub mod watch;
pub mod wire;

pub use controller_side::{ControllerEndpoint, ControllerEndpointConfig, Incoming};
pub use deadline::{Arrival, DeadlinePolicy, Decision, Step, Transition};
pub use invalid::InvalidMessage;
pub use plant_side::{Command, NoCommand, PlantEndpoint, PlantEndpointConfig, Refusal};
pub use process::{Exit, StopFlag, StopSignal, log_line, process_alive, signal_process};
pub use transport::{Message, Transport, open};

use std::fmt;

/// Which side of a run a process is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// Publishes states, receives commands.
    Plant,
    /// Receives states, publishes commands.
    Controller,
}

impl Role {
    /// The other side.
    pub fn peer(self) -> Role {
        match self {
            Role::Plant => Role::Controller,
            Role::Controller => Role::Plant,
        }
    }

    /// `plant` or `controller`.
    pub fn name(self) -> &'static str {
        match self {
            Role::Plant => "plant",
            Role::Controller => "controller",
        }
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How the two processes exchange messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum TransportKind {
    /// iceoryx2 shared memory (the product).
    #[default]
    Iceoryx2,
    /// Unix datagram sockets (the benchmark baseline).
    Uds,
}

impl TransportKind {
    /// `iceoryx2` or `uds`.
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Iceoryx2 => "iceoryx2",
            TransportKind::Uds => "uds",
        }
    }
}

impl fmt::Display for TransportKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How a waiting side waits for the other's message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Wake {
    /// Busy polling: the lowest latency, a core per waiting process.
    Spin,
    /// The waiting process sleeps and is woken by the other's notification.
    #[default]
    Event,
}

impl Wake {
    /// `spin` or `event`.
    pub fn name(self) -> &'static str {
        match self {
            Wake::Spin => "spin",
            Wake::Event => "event",
        }
    }
}

impl fmt::Display for Wake {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why the process layer could not do what was asked.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The run name cannot name services.
    #[error("invalid run name `{0}` (1-64 of A-Z a-z 0-9 _ -)")]
    InvalidRunName(String),
    /// Another live process already holds this side of the run.
    #[error("a {role} for run `{run}` is already running: choose another --name")]
    AlreadyRunning {
        /// The side.
        role: Role,
        /// The run.
        run: String,
    },
    /// An iceoryx2 call failed.
    #[error("iceoryx2: {what}: {detail}")]
    Iceoryx2 {
        /// What was being done.
        what: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// Every writer slot of a board is held (by running or crashed processes of the run).
    #[error(
        "{service}: all {slots} writer slots are taken (held by running or crashed processes of this run); end both processes or use another run name"
    )]
    SlotsTaken {
        /// The service.
        service: String,
        /// Its slots.
        slots: u32,
    },
    /// A socket operation failed.
    #[error("{path}: {source}")]
    Io {
        /// The socket's path.
        path: std::path::PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The run's parameter service could not be reached or answered nothing.
    #[error("{0}")]
    Param(String),
    /// The serial link to a processor-in-the-loop firmware failed.
    #[error("serial link: {what}: {source}")]
    Serial {
        /// What was being done.
        what: String,
        /// The error.
        source: std::io::Error,
    },
}

impl LinkError {
    pub(crate) fn iceoryx2(what: impl Into<String>, detail: impl fmt::Debug) -> LinkError {
        LinkError::Iceoryx2 {
            what: what.into(),
            detail: format!("{detail:?}"),
        }
    }
}

/// Checks a run name (the services and sockets of a run derive from it).
pub fn check_run_name(run: &str) -> Result<ipc_types::ServiceNames, LinkError> {
    ipc_types::service_names(run).ok_or_else(|| LinkError::InvalidRunName(run.to_owned()))
}
