//! The plant process and the simulation front end.
//!
//! * [`trajectory`]: the in-process closed loop (controller crate's `ClosedLoop`) and its rows;
//! * [`output`]: `trajectory.csv` and `summary.json`;
//! * [`plot`]: the figures (PNG and SVG);
//! * [`montecarlo`]: the extended paper's Monte Carlo study.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod bench_loop;
pub mod montecarlo;
pub mod output;
pub mod pair;
pub mod plot;
pub mod trajectory;

/// Errors of the simulation front end, split by who is to blame (for the exit code).
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Bad input: scenario, samples file, command-line value. Exit code 2.
    #[error("{0}")]
    Input(String),
    /// The run could not complete (controller refused a state, I/O failed). Exit code 1.
    #[error("{0}")]
    Run(String),
}

impl From<scenario::ScenarioError> for SimError {
    fn from(e: scenario::ScenarioError) -> Self {
        SimError::Input(e.to_string())
    }
}

impl SimError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            SimError::Input(_) => 2,
            SimError::Run(_) => 1,
        }
    }
}
