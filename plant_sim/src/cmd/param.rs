//! `plant_sim param`: read or change a gain of a running pair, as
//! docs/live.md, "Tuning a running pair" describes.

use clap::{Args, Subcommand};
use plant::SimError;
use scenario::cli::positive_seconds;
use std::time::Duration;

#[derive(Args)]
pub(crate) struct ParamArgs {
    /// The run (as given to `plant_sim run --name`; it must run with `--tunable`).
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Seconds to wait for the plant's answer (a change is answered once it is in force).
    #[arg(long, value_name = "S", default_value = "10", value_parser = positive_seconds)]
    timeout: Duration,
    #[command(subcommand)]
    op: ParamOp,
}

#[derive(Subcommand)]
enum ParamOp {
    /// Print the value in force of KEY (a scenario key such as `controller.kd`, or `kp`,
    /// `kd`).
    Get {
        /// The key.
        key: String,
    },
    /// Set KEY to VALUE (a number, `NaN`, or a TOML value such as `[[1.0, 0.0, 0.0], ...]`),
    /// checked as the scenario file's key is checked, in force from the next cycle for
    /// everything it touches; prints the cycle it took effect at.
    Set {
        /// The key.
        key: String,
        /// The value.
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
}

pub(crate) fn param_cmd(args: ParamArgs) -> Result<(), SimError> {
    let (op, key, value) = match &args.op {
        ParamOp::Get { key } => (link::params::param_op::GET, key.as_str(), ""),
        ParamOp::Set { key, value } => (link::params::param_op::SET, key.as_str(), value.as_str()),
    };
    let answer = link::params::ask(&args.name, op, key, value, args.timeout)
        .map_err(|e| SimError::Run(e.to_string()))?;
    if !answer.ok {
        return Err(SimError::Input(format!("refused: {}", answer.text)));
    }
    println!("{}", answer.text);
    Ok(())
}
