//! `controller_node [--scenario FILE | --builtin NAME] [--name RUN]`
//!
//! The controller process of the pair. Start it by hand (as on a target board) or let
//! `plant_sim run` spawn it. Exit codes (shared with `plant_sim`, `link::Exit`): 0 the plant
//! ended the run or SIGINT/SIGTERM asked the node to leave, 1 the plant is gone or IPC
//! failed, 2 bad input or a configuration mismatch with the plant.
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use clap::Parser;
use controller_node::{Fault, Options, ReferenceMode, Report, Stop, run};
use eqtrack_controller::Law;
use link::{Exit, StopFlag, TransportKind};
use scenario::cli::{ScenarioSource, law_parser, positive_seconds};
use std::process::ExitCode;
use std::time::Duration;

// Counts every heap allocation of the process, so the loop can prove it allocates nothing.
#[global_allocator]
static GLOBAL: alloc_counter::Counting = alloc_counter::Counting;

#[derive(Parser)]
#[command(
    name = "controller_node",
    version,
    about = "Equivariant tracking control: the controller process"
)]
struct Cli {
    #[command(flatten)]
    source: ScenarioSource,
    /// Override the scenario's law.
    #[arg(long, value_name = "L", value_parser = law_parser())]
    law: Option<Law>,
    /// Where the desired trajectory comes from: the scenario's own reference, or pieces a
    /// planner process streams on the run's `plan` service (see the `planner` example). A
    /// streamed reference holds the scenario's initial reference pose until pieces arrive,
    /// and the last pose given whenever the stream runs dry.
    #[arg(long, value_enum, value_name = "FROM", default_value_t = ReferenceMode::Scenario)]
    reference: ReferenceMode,
    /// Run name: pairs with different names never see each other's messages.
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Insist on this control rate (Hz): a plant running at another one is refused. By
    /// default the controller follows the plant's period.
    #[arg(long, value_name = "F")]
    rate_hz: Option<f64>,
    /// Seconds of silence after which the plant counts as gone.
    #[arg(long, value_name = "S", default_value = "1", value_parser = positive_seconds)]
    silence_timeout: Duration,
    /// Seconds to wait for the first state.
    #[arg(long, value_name = "S", default_value = "30", value_parser = positive_seconds)]
    startup_timeout: Duration,
    #[command(flatten)]
    rt: link::rt::RtSettings,
    /// Write what the real-time settings did (applied, refused with the OS's reason, the
    /// scheduler and CPUs read back, the pid) as JSON to FILE, before the run starts.
    /// `plant_sim run` passes it to the controller it starts and records the report in its
    /// summary.
    #[arg(long, value_name = "FILE")]
    rt_report: Option<std::path::PathBuf>,
    /// Transport: iceoryx2, or uds (the Unix-socket baseline of `plant_sim bench-loop`).
    #[arg(long, value_enum, default_value_t = TransportKind::Iceoryx2)]
    transport: TransportKind,
    /// Test builds only (feature `fault-injection`): publish a NaN torque instead of command
    /// K, to test the plant's own checks. Release builds have no such flag.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K", hide = true)]
    fault_nan_torque: Option<u64>,
    /// Test builds only (feature `fault-injection`): the loop hangs for good at the first state at or after K (a
    /// service manager's watchdog must restart the process).
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K", hide = true)]
    fault_hang_at: Option<u64>,
    /// Test builds only: with `--fault-hang-at`, a side thread keeps pinging the watchdog
    /// (the mistake the watchdog tests must catch).
    #[cfg(feature = "fault-injection")]
    #[arg(long, hide = true, requires = "fault_hang_at")]
    fault_side_notifier: bool,
}

fn fail(exit: Exit, msg: std::fmt::Arguments) -> ExitCode {
    link::log_line(format_args!("controller_node: error: {msg}"));
    exit.into()
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let stop = match StopFlag::install() {
        Ok(s) => s,
        Err(e) => return fail(Exit::Failed, format_args!("cannot handle signals: {e}")),
    };
    let scenario = match cli.source.load("seed").and_then(|s| match cli.law {
        Some(l) => s.with_law(l),
        None => Ok(s),
    }) {
        Ok(s) => s,
        Err(e) => return fail(Exit::BadInput, format_args!("{e}")),
    };
    let period = match cli.rate_hz {
        None => None,
        Some(f) if f.is_finite() && f > 0.0 && f <= 100_000.0 => Some(1.0 / f),
        Some(f) => {
            return fail(
                Exit::BadInput,
                format_args!("--rate-hz: must be in (0, 100000], got {f}"),
            );
        }
    };
    // before the transport starts any thread, so all of them inherit the settings
    let rt = cli.rt.apply();
    for line in rt.lines() {
        link::log_line(format_args!("controller_node: real-time settings: {line}"));
    }
    if let Some(path) = &cli.rt_report
        && let Err(e) = rt.write_json(path)
    {
        link::log_line(format_args!(
            "controller_node: warning: cannot write the real-time report to {}: {e}",
            path.display()
        ));
    }
    let opts = Options {
        scenario,
        reference: cli.reference,
        run: cli.name.clone(),
        transport: cli.transport,
        period,
        startup_timeout: cli.startup_timeout,
        silence_timeout: cli.silence_timeout,
        #[cfg(feature = "fault-injection")]
        fault: match (
            cli.fault_nan_torque,
            cli.fault_hang_at,
            cli.fault_side_notifier,
        ) {
            (Some(k), _, _) => Some(Fault::NanTorque(k)),
            (None, Some(k), false) => Some(Fault::HangAt(k)),
            (None, Some(k), true) => Some(Fault::HangWithSideNotifier(k)),
            (None, None, _) => None,
        },
        #[cfg(not(feature = "fault-injection"))]
        fault: None::<Fault>,
        stop,
    };
    match run(&opts, &alloc_counter::process_allocations) {
        Ok(report) => finish(&report, &cli.name),
        Err(e) => fail(e.exit(), format_args!("{e}")),
    }
}

/// Prints why the node stopped and what it did; the exit code.
fn finish(report: &Report, run: &str) -> ExitCode {
    let (exit, why) = match &report.stop {
        Stop::Shutdown => (Exit::Done, "the plant ended the run".to_owned()),
        Stop::Signal(s) => (Exit::Done, format!("{s} received, leaving the run")),
        Stop::PlantGone => (
            Exit::Failed,
            format!("the plant of run `{run}` is gone (its process has exited)"),
        ),
        Stop::Silence(d) => (
            Exit::Failed,
            format!("no state from the plant for {:.2} s", d.as_secs_f64()),
        ),
        Stop::NoPlant(d) => (
            Exit::Failed,
            format!(
                "no plant appeared on run `{run}` within {:.0} s",
                d.as_secs_f64()
            ),
        ),
        Stop::Mismatch(r) => (Exit::BadInput, format!("refused the run: {r}")),
    };
    let rejected: u64 = report.rejected.iter().sum();
    let allocs = match report.allocations_after_startup {
        Some((a, c)) => format!("heap allocations after start-up: {a} in {c} cycles"),
        None => "heap allocations after start-up: not measured (fewer than 2 cycles)".to_owned(),
    };
    let plans: u64 = report.plans_refused.iter().sum();
    let short = report.plans_refused[ipc_types::PlanInvalid::ShortLeg as usize];
    link::log_line(format_args!(
        "controller_node: exiting: {why}; {} commands, {rejected} states rejected, {} refused, {plans} plan messages refused ({short} with a segment shorter than the control period); {allocs}",
        report.cycles, report.refused
    ));
    exit.into()
}
