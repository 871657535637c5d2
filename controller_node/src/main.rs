//! `controller_node [--scenario FILE | --builtin NAME] [--name RUN]`
//!
//! The controller process of the pair. Start it by hand (as on a target board) or let
//! `plant_sim run` spawn it. Exit codes: 0 the plant ended the run, 1 the plant is gone or IPC
//! failed, 2 bad input.

use clap::Parser;
use controller_node::{Fault, NodeError, Options, Stop, Transport, run};
use scenario::Scenario;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Counts every heap allocation of the process, so the loop can prove it allocates nothing.
struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: every call is forwarded unchanged to the system allocator, which upholds the
// GlobalAlloc contract; the counter is a relaxed atomic increment with no other effect.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same layout contract as our caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same layout contract as our caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: ptr was allocated by System with this layout (all our allocations are).
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: ptr was allocated by System with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[derive(Parser)]
#[command(
    name = "controller_node",
    version,
    about = "Equivariant tracking control: the controller process"
)]
struct Cli {
    /// Scenario file (TOML).
    #[arg(long, value_name = "FILE", conflicts_with = "builtin")]
    scenario: Option<PathBuf>,
    /// Built-in scenario: seed, montecarlo, se3_circle (default seed).
    #[arg(long, value_name = "NAME")]
    builtin: Option<String>,
    /// Override the scenario's law.
    #[arg(long, value_name = "L")]
    law: Option<String>,
    /// Run name: pairs with different names never see each other's messages.
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Seconds of silence after which the plant counts as gone.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    silence_timeout: f64,
    /// Seconds to wait for the first state.
    #[arg(long, value_name = "S", default_value_t = 30.0)]
    startup_timeout: f64,
    /// Transport: iceoryx2 (default) or uds (the Unix-socket baseline of `plant_sim bench-loop`).
    #[arg(long, value_name = "T", default_value = "iceoryx2", value_parser = ["iceoryx2", "uds"])]
    transport: String,
    /// Test builds only (feature `fault-injection`): publish a NaN torque instead of command
    /// K, to test the plant's own checks. Release builds have no such flag.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K", hide = true)]
    fault_nan_torque: Option<u64>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let load = || -> Result<Scenario, String> {
        let s = match (&cli.scenario, &cli.builtin) {
            (Some(p), _) => Scenario::from_file(p),
            (None, Some(n)) => Scenario::builtin(n),
            (None, None) => Scenario::builtin("seed"),
        }
        .map_err(|e| e.to_string())?;
        match &cli.law {
            Some(l) => s.with_law(l).map_err(|e| e.to_string()),
            None => Ok(s),
        }
    };
    let scenario = match load() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("controller_node: error: {e}");
            return ExitCode::from(2);
        }
    };
    for (name, v) in [
        ("--silence-timeout", cli.silence_timeout),
        ("--startup-timeout", cli.startup_timeout),
    ] {
        if !(v.is_finite() && v > 0.0) {
            eprintln!(
                "controller_node: error: {name}: must be a positive number of seconds, got {v}"
            );
            return ExitCode::from(2);
        }
    }
    let opts = Options {
        scenario,
        run: cli.name.clone(),
        startup_timeout: Duration::from_secs_f64(cli.startup_timeout),
        silence_timeout: Duration::from_secs_f64(cli.silence_timeout),
        #[cfg(feature = "fault-injection")]
        fault: cli.fault_nan_torque.map(Fault::NanTorque),
        #[cfg(not(feature = "fault-injection"))]
        fault: None::<Fault>,
        transport: if cli.transport == "uds" {
            Transport::Uds
        } else {
            Transport::Iceoryx2
        },
    };
    match run(&opts, &|| ALLOCATIONS.load(Ordering::Relaxed)) {
        Ok(report) => {
            let rejected: u64 = report.rejected.iter().sum();
            let allocs = match report.allocations_after_startup {
                Some((a, c)) => format!("heap allocations after start-up: {a} in {c} cycles"),
                None => {
                    "heap allocations after start-up: not measured (fewer than 2 cycles)".to_owned()
                }
            };
            let (code, why) = match &report.stop {
                Stop::Shutdown => (0, "the plant ended the run".to_owned()),
                Stop::PlantGone => (
                    1,
                    format!(
                        "the plant of run `{}` is gone (its node is dead or removed)",
                        cli.name
                    ),
                ),
                Stop::Silence(d) => (
                    1,
                    format!("no state from the plant for {:.2} s", d.as_secs_f64()),
                ),
                Stop::NoPlant(d) => (
                    1,
                    format!(
                        "no plant appeared on run `{}` within {:.0} s",
                        cli.name,
                        d.as_secs_f64()
                    ),
                ),
            };
            eprintln!(
                "controller_node: exiting: {why}; {} commands, {rejected} states rejected, {} refused; {allocs}",
                report.cycles, report.refused
            );
            ExitCode::from(code)
        }
        Err(e) => {
            eprintln!("controller_node: error: {e}");
            ExitCode::from(match e {
                NodeError::Input(_) => 2,
                NodeError::Ipc(_) => 1,
            })
        }
    }
}
