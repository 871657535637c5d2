//! `plant_sim monitor`: the live view of a run.

use clap::Args;
use link::StopFlag;
use plant::SimError;
use scenario::cli::positive_seconds;
use std::time::Duration;

#[derive(Args)]
pub(crate) struct MonitorArgs {
    /// The run to watch (as given to `plant_sim run --name`).
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Seconds to wait for the run to start.
    #[arg(long, value_name = "S", default_value = "30", value_parser = positive_seconds)]
    wait: Duration,
    /// One line per second on stdout instead of the terminal view.
    #[arg(long)]
    plain: bool,
}

pub(crate) fn monitor_cmd(args: MonitorArgs, stop: &StopFlag) -> Result<(), SimError> {
    use flight_tools::monitor::{MonitorEnd, MonitorOptions, monitor};
    let end = monitor(&MonitorOptions {
        run: args.name.clone(),
        wait: args.wait,
        plain: args.plain,
        stop: stop.clone(),
    })?;
    match end {
        MonitorEnd::RunEnded | MonitorEnd::Quit => Ok(()),
        MonitorEnd::PlantGone => Err(SimError::Run(format!(
            "the plant of run `{}` is gone without ending the run",
            args.name
        ))),
    }
}
