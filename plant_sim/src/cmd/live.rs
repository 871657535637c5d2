//! `plant_sim live`: runs `eqtrack-live` on a running pair.

use clap::Args;
use link::StopFlag;
use plant::SimError;
use std::time::Duration;

#[derive(Args)]
pub(crate) struct LiveArgs {
    /// The run to serve (as given to `plant_sim run --name`).
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// The address to listen on (IP:PORT). Anything but a loopback address lets anyone on
    /// the network read the vehicle's state.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8765")]
    listen: String,
    /// Seconds to wait for the run to start.
    #[arg(long, value_name = "S", default_value = "30")]
    wait: String,
}

/// Runs `eqtrack-live` (beside this binary) with the same arguments, passes a SIGINT or
/// SIGTERM on to it, and returns its exit status.
pub(crate) fn live_cmd(args: LiveArgs, stop: &StopFlag) -> Result<(), SimError> {
    let exe = std::env::current_exe()
        .map_err(|e| SimError::Run(format!("cannot locate plant_sim: {e}")))?;
    let path = exe.with_file_name("eqtrack-live");
    if !path.exists() {
        return Err(SimError::Run(format!(
            "{} not found: build it (cargo build --release --workspace)",
            path.display()
        )));
    }
    let mut child = std::process::Command::new(&path)
        .args([
            "--name",
            &args.name,
            "--listen",
            &args.listen,
            "--wait",
            &args.wait,
        ])
        .spawn()
        .map_err(|e| SimError::Run(format!("cannot start {}: {e}", path.display())))?;
    let mut passed_on = false;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) => {}
            Err(e) => return Err(SimError::Run(format!("eqtrack-live: {e}"))),
        }
        if let (Some(sig), false) = (stop.requested(), passed_on) {
            // a Ctrl-C in a terminal reaches both; a kill of this process only this one
            link::signal_process(child.id(), sig);
            passed_on = true;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    match status.code() {
        Some(0) => Ok(()),
        Some(2) => Err(SimError::Input(
            "eqtrack-live refused its input (above)".to_owned(),
        )),
        Some(130) => Err(SimError::Interrupted(link::StopSignal::Int)),
        Some(143) => Err(SimError::Interrupted(link::StopSignal::Term)),
        _ => Err(SimError::Run(format!("eqtrack-live: {status}"))),
    }
}
