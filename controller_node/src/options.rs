//! What the controller process is asked to do ([`Options`]), why it stopped ([`Stop`], [`Report`]) and its errors.
use ipc_types::PlanInvalid;
use link::{LinkError, Refusal, StopFlag, StopSignal, TransportKind};
use scenario::Scenario;
use std::time::Duration;

/// A fault to inject, for tests of the plant's own checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// At step k, publish a command with a NaN torque instead of the right one.
    NanTorque(u64),
    /// At the first step at or after k, the loop hangs for good (a watchdog must restart
    /// the process).
    HangAt(u64),
    /// [`Fault::HangAt`], with a side thread that keeps telling the service manager's
    /// watchdog that all is well: the mistake the watchdog tests must catch.
    HangWithSideNotifier(u64),
}

/// Where the desired trajectory comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ReferenceMode {
    /// The scenario's own reference (feedforward series, waypoints or set-point).
    #[default]
    Scenario,
    /// Pieces streamed by a planner process on the run's `plan` service; until the first
    /// arrive, and whenever none covers `t_k`, the last pose given is held.
    Stream,
}

/// How to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// The scenario (law, gains, model inertia, reference).
    pub scenario: Scenario,
    /// Where the reference comes from.
    pub reference: ReferenceMode,
    /// The run name (service names derive from it).
    pub run: String,
    /// The transport.
    pub transport: TransportKind,
    /// A control period to insist on (s); `None`: follow the plant's.
    pub period: Option<f64>,
    /// How long to wait for the first state.
    pub startup_timeout: Duration,
    /// Silence after which the plant counts as gone.
    pub silence_timeout: Duration,
    /// A fault to inject (tests only).
    pub fault: Option<Fault>,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}

/// Why the node stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// The plant announced the end of the run.
    Shutdown,
    /// The plant's process is gone.
    PlantGone,
    /// No state within the silence timeout.
    Silence(Duration),
    /// No first state within the start-up timeout.
    NoPlant(Duration),
    /// SIGINT or SIGTERM.
    Signal(StopSignal),
    /// The plant's settings differ from the controller's (the plant was told).
    Mismatch(Refusal),
}

/// What the node did.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Why it stopped.
    pub stop: Stop,
    /// Commands published.
    pub cycles: u64,
    /// Rejected states per [`ipc_types::Invalid`] kind.
    pub rejected: [u64; ipc_types::Invalid::KINDS],
    /// States the law refused (non-finite state), no command published.
    pub refused: u64,
    /// With `--reference stream`: plan messages refused per [`ipc_types::PlanInvalid`] kind
    /// (its discriminant), e.g. for a segment shorter than the control period.
    pub plans_refused: [u64; PlanInvalid::KINDS],
    /// Heap allocations counted between the end of the first cycle and the moment the node
    /// stopped (`None` if fewer than two cycles ran), and the cycles they span.
    pub allocations_after_startup: Option<(u64, u64)>,
}

/// Failures that prevent running.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The scenario cannot build a controller or a reference.
    #[error("scenario `{scenario}`: {source}")]
    Scenario {
        /// Its name.
        scenario: String,
        /// What is wrong.
        source: eqtrack_controller::Error,
    },
    /// The process layer failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The service manager's notification environment is bad, or its socket unreachable.
    #[error("service manager: {0}")]
    Notify(#[from] link::notify::NotifyError),
    /// The scenario's vehicle does not make an allocator.
    #[error("scenario `{scenario}`: {what}")]
    Vehicle {
        /// Its name.
        scenario: String,
        /// What is wrong.
        what: String,
    },
}

impl NodeError {
    /// The exit code class.
    pub fn exit(&self) -> link::Exit {
        match self {
            NodeError::Scenario { .. }
            | NodeError::Vehicle { .. }
            | NodeError::Notify(_)
            | NodeError::Link(LinkError::InvalidRunName(_)) => link::Exit::BadInput,
            NodeError::Link(_) => link::Exit::Failed,
        }
    }
}
