//! `plant_sim replay`: a recording answered again, bit for bit, or a what-if.

use clap::Args;
use eqtrack_controller::Law;
use plant::SimError;
use scenario::cli::law_parser;
use std::path::PathBuf;

#[derive(Args)]
pub(crate) struct ReplayArgs {
    /// The run's output directory (holds messages.log and scenario.toml).
    #[arg(value_name = "OUT_DIR")]
    dir: PathBuf,
    /// What-if: replay with this law.
    #[arg(long, value_name = "L", value_parser = law_parser())]
    law: Option<Law>,
    /// What-if: replay with this scenario's controller (law, gains, model, reference).
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// What-if: the potential weight K: one number X (X times the identity) or the n
    /// diagonal entries, comma-separated.
    #[arg(
        long,
        value_name = "X[,X...]",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    kp: Option<Vec<f64>>,
    /// What-if: the damping K_d: one number X (X times the identity) or the m diagonal
    /// entries, comma-separated.
    #[arg(
        long,
        value_name = "X[,X...]",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    kd: Option<Vec<f64>>,
    /// Where a what-if writes replay.csv and replay.png/.svg (default: OUT_DIR).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// `plant_sim replay`: prints what the replay found; a difference outside a what-if is an
/// error (exit 1).
pub(crate) fn replay_cmd(args: ReplayArgs) -> Result<(), SimError> {
    use flight_tools::replay::{ReplayOptions, replay};
    let opts = ReplayOptions {
        dir: args.dir,
        law: args.law,
        scenario: args.scenario,
        kp: args.kp,
        kd: args.kd,
        out: args.out,
    };
    let r = replay(&opts)?;
    print_report(&r, &opts);
    match &r.first {
        Some(d) if !opts.what_if() => Err(SimError::Run(format!(
            "replay differs from the recording: {} of {} commands, first at cycle {} ({})",
            r.differing,
            r.compared,
            d.cycle,
            d.describe()
        ))),
        _ => match r
            .estimator
            .as_ref()
            .and_then(|e| e.first.as_ref().map(|d| (e, d)))
        {
            Some((e, d)) => Err(SimError::Run(format!(
                "the replayed estimator differs from the recording: {} of {} estimates, first at cycle {} ({})",
                e.differing,
                e.compared,
                d.cycle,
                d.describe()
            ))),
            None => Ok(()),
        },
    }
}

/// Prints what the replay found: notes on the log, the comparison, the first difference, the
/// streamed reference, the estimator's check, and what a what-if wrote.
fn print_report(
    r: &flight_tools::replay::ReplayReport,
    opts: &flight_tools::replay::ReplayOptions,
) {
    if r.trailing_bytes > 0 {
        println!(
            "note: the log ends {} bytes into a record (the recording was cut short, e.g. by SIGKILL): replayed up to its last whole record",
            r.trailing_bytes
        );
    }
    if r.missing > 0 {
        println!(
            "note: {} cycles are missing from the log (the recorder dropped them)",
            r.missing
        );
    }
    if !r.recorded_laws.is_empty() {
        let names: Vec<&str> = r.recorded_laws.iter().map(|l| l.name()).collect();
        println!(
            "note: the recorded commands were computed by {} (a controller started with another law than the scenario's): each state was replayed with the law its command names",
            names.join(", ")
        );
    }
    println!(
        "replayed {} cycles of {}: {} commands compared, {} differ{}",
        r.cycles,
        opts.dir.display(),
        r.compared,
        r.differing,
        if opts.what_if() { " (what-if)" } else { "" }
    );
    if let Some(d) = &r.first {
        println!(
            "first difference: cycle {} (t = {:.6} s): {}",
            d.cycle,
            d.t,
            d.describe()
        );
    }
    if let Some(n) = r.plans_taken {
        println!(
            "streamed reference: {n} recorded plan messages handed to the controller at the cycles it took them"
        );
    }
    if let Some(k) = r.detector_lost_at {
        println!(
            "failure detector, failsafe manager: run again and compared until cycle {k}, a state the log cannot say the controller saw; from there the allocator was told what the recorded commands found and the set-point flew their failsafe word, and neither was compared"
        );
    }
    if let Some(e) = &r.estimator {
        println!(
            "estimator: {} estimates checked, {} differ{}",
            e.compared,
            e.differing,
            e.stopped_at.map_or(String::new(), |k| format!(
                " (not checked from cycle {k} on: the log has a gap there)"
            ))
        );
        if let Some(d) = &e.first {
            println!(
                "first estimate difference: cycle {} (t = {:.6} s): {}",
                d.cycle,
                d.t,
                d.describe()
            );
        }
    }
    if let Some(dir) = &r.written {
        println!(
            "largest torque difference {:e}; wrote {}/{{replay.csv, replay.png, replay.svg}}",
            r.max_torque_difference,
            dir.display()
        );
    }
}
