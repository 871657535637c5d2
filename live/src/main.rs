//! `eqtrack-live`: a running pair served to Foxglove over the Foxglove WebSocket protocol
//! (what `plant_sim live` runs; docs/live.md).
//!
//! ```text
//! eqtrack-live --name RUN [--listen ADDR] [--wait S] [--max-clients N] [--queue N]
//! ```
//!
//! Exit codes as the other binaries': 0 the run ended, 1 the run's plant is gone without
//! ending it, no run came within `--wait`, or the address cannot be listened on; 2 bad input;
//! 130/143 stopped by SIGINT/SIGTERM.
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use clap::Parser;
use link::{Exit, StopFlag};
use live::poller::RunEnd;
use live::{LiveError, Options, Outcome};
use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "eqtrack-live",
    version,
    about = "Serves a running pair's state, command and status to Foxglove (Foxglove WebSocket protocol)"
)]
struct Cli {
    /// The run to serve (as given to `plant_sim run --name`).
    #[arg(long, value_name = "RUN", default_value = "eqtrack", value_parser = run_name)]
    name: String,
    /// The address to listen on. Anything but a loopback address lets anyone on the network
    /// read the vehicle's state.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8765", value_parser = listen_addr)]
    listen: SocketAddr,
    /// Seconds to wait for the run to start.
    #[arg(long, value_name = "S", default_value = "30", value_parser = seconds)]
    wait: Duration,
    /// Clients served at once (more are refused with HTTP 503).
    #[arg(long, value_name = "N", default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=64))]
    max_clients: u16,
    /// Each client's queue, in messages: a client further behind loses messages (counted
    /// and reported), the run never waits.
    #[arg(long, value_name = "N", default_value_t = live::DEFAULT_QUEUE as u32, value_parser = clap::value_parser!(u32).range(1..=65536))]
    queue: u32,
}

fn run_name(s: &str) -> Result<String, String> {
    if ipc_types::valid_run_name(s) {
        Ok(s.to_owned())
    } else {
        Err("a run name is 1 to 64 characters of A-Z, a-z, 0-9, _ and -".to_owned())
    }
}

/// `IP:PORT` (`[::1]:8765` for IPv6), or `localhost:PORT`.
fn listen_addr(s: &str) -> Result<SocketAddr, String> {
    let bad =
        || format!("expected IP:PORT, e.g. 127.0.0.1:8765, 0.0.0.0:8765 or [::1]:8765; got `{s}`");
    if let Some(port) = s.strip_prefix("localhost:") {
        let port: u16 = port.parse().map_err(|_| bad())?;
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    s.parse().map_err(|_| bad())
}

fn seconds(s: &str) -> Result<Duration, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 && x < 1e9 => Ok(Duration::from_secs_f64(x)),
        _ => Err(format!("expected a positive number of seconds, got `{s}`")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = live::yield_to_the_pair() {
        eprintln!("eqtrack-live: cannot lower its own priority ({e}); it runs as it is");
    }
    let stop = match StopFlag::install() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("eqtrack-live: error: cannot handle signals: {e}");
            return Exit::Failed.into();
        }
    };
    if !cli.listen.ip().is_loopback() {
        eprintln!(
            "eqtrack-live: WARNING: listening on {}, not a loopback address: anyone who can reach this machine on the network can connect and read the vehicle's state (there is no authentication); use 127.0.0.1 unless that is what you want",
            cli.listen
        );
    }
    let opts = Options {
        run: cli.name,
        listen: cli.listen,
        wait: cli.wait,
        max_clients: usize::from(cli.max_clients),
        queue: cli.queue as usize,
        stop,
    };
    match live::serve(&opts) {
        Ok(report) => {
            let (exit, what) = match report.outcome {
                Outcome::Run(RunEnd::Ended { cycle }) => {
                    (Exit::Done, format!("the run ended at cycle {cycle}"))
                }
                Outcome::Run(RunEnd::PlantGone { pid }) => (
                    Exit::Failed,
                    format!("the run's plant (pid {pid}) is gone without ending the run"),
                ),
                Outcome::NoRun => (
                    Exit::Failed,
                    format!(
                        "run `{}` did not start within {:.0} s (is it running, under this name?)",
                        opts.run,
                        opts.wait.as_secs_f64()
                    ),
                ),
                Outcome::Stopped(sig) => (Exit::Signal(sig), format!("stopped by {sig}")),
            };
            println!(
                "live: {what}; {} clients served, {} messages read from the boards, {} sent, {} dropped in all; {} states and {} commands replaced on the boards before the bridge read them",
                report.clients,
                report.offered,
                report.sent,
                report.dropped,
                report.replaced_states,
                report.replaced_commands
            );
            exit.into()
        }
        Err(e) => {
            eprintln!("eqtrack-live: error: {e}");
            match e {
                LiveError::Input(_) => Exit::BadInput,
                LiveError::Run(_) => Exit::Failed,
            }
            .into()
        }
    }
}
