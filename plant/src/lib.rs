//! The plant: the in-process closed loop and the plant process of the pair.
//!
//! * [`trajectory`]: the in-process simulation (the controller crate's `ClosedLoop`, with
//!   simulated sensors and the estimator when the scenario has them) and its rows,
//!   [`trajectory::SimulatedTrajectory`];
//! * [`sensors`], [`estimation`]: seeded sensor samples drawn from the true state, and the
//!   estimator that turns them into the state the law is handed;
//! * [`pair`]: the plant process of the pair over `link` (lockstep or real time), with its
//!   flight recorder; [`spawn`] starts the controller process beside it;
//! * [`status`]: the run's live figures, published for `plant_sim monitor`;
//! * [`output`], [`plot`]: `trajectory.csv`, `summary.json` and the figures of a run;
//! * [`vehicle`]: gravity, buoyancy, drag and the actuators' lag and failures, integrated with
//!   the rigid body;
//! * [`wheels`]: reaction wheels, their limits and friction, and the gyrostat they make with
//!   the body.
//!
//! It depends on no crate of the controller process: the two processes meet only on the wire.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod estimation;
pub mod failsafe;
pub mod output;
pub mod pair;
pub mod plot;
pub mod sensors;
pub mod spawn;
pub mod status;
pub mod trajectory;
pub mod tuning;
pub mod vehicle;
pub mod wheels;

/// Errors of the simulation front end, split by who is to blame (for the exit code).
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Bad input: scenario, samples file, command-line value. Exit code 2.
    #[error("{0}")]
    Input(String),
    /// The run could not complete (controller refused a state, I/O failed). Exit code 1.
    #[error("{0}")]
    Run(String),
    /// The process layer failed.
    #[error("{0}")]
    Link(#[from] link::LinkError),
    /// The controller refused the run: the two processes' settings differ. Exit code 2.
    #[error("controller_node refused the run: {0}")]
    Mismatch(Box<link::Refusal>),
    /// SIGINT or SIGTERM stopped the work (what finished was written). Exit code 130/143.
    #[error("stopped by {0}")]
    Interrupted(link::StopSignal),
}

impl From<recorder::RecorderError> for SimError {
    fn from(e: recorder::RecorderError) -> Self {
        match e {
            recorder::RecorderError::Input(m) => SimError::Input(m),
            recorder::RecorderError::Io(m) => SimError::Run(m),
        }
    }
}

impl From<scenario::ScenarioError> for SimError {
    fn from(e: scenario::ScenarioError) -> Self {
        SimError::Input(e.to_string())
    }
}

impl SimError {
    /// The process exit status for this error (`link::Exit`, shared with `controller_node`).
    pub fn exit(&self) -> link::Exit {
        match self {
            SimError::Input(_) | SimError::Mismatch(_) => link::Exit::BadInput,
            SimError::Link(link::LinkError::InvalidRunName(_)) => link::Exit::BadInput,
            SimError::Link(link::LinkError::AlreadyRunning { .. }) => link::Exit::BadInput,
            SimError::Run(_) | SimError::Link(_) => link::Exit::Failed,
            SimError::Interrupted(s) => link::Exit::Signal(*s),
        }
    }

    /// Fails with [`SimError::Interrupted`] when a stop signal has arrived.
    pub fn check(stop: &link::StopFlag) -> Result<(), SimError> {
        match stop.requested() {
            Some(s) => Err(SimError::Interrupted(s)),
            None => Ok(()),
        }
    }
}
