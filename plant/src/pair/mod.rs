//! `plant_sim run`: the plant process of the pair, written against `link`'s
//! [`PlantEndpoint`](link::PlantEndpoint) like any plant (docs/architecture.md, "One control cycle").
//!
//! * **lockstep**: the plant publishes state k and waits for command k before integrating
//!   `[t_k, t_{k+1})`; the result equals `plant_sim sim` bit for bit.
//! * **realtime**: tick k+1 comes at `t0 + (k+1)/F` on CLOCK_MONOTONIC
//!   ([`link::clock::sleep_until`]); command k must arrive before it. What is applied is the
//!   [`DeadlinePolicy`](link::DeadlinePolicy)'s decision: the command, the held torque, or the safe-mode torque
//!   (`eqtrack_controller::law::safe_mode_torque`) after `miss_limit` consecutive misses.
//!
//! SIGINT/SIGTERM stop the loop at the next cycle; the cycles that ran are written and the
//! summary says `"interrupted": true` (docs/architecture.md, "Stopping a run").

use crate::SimError;
use crate::output::ensure_dir;
use crate::spawn::Spawned;
use crate::trajectory::SimulatedTrajectory;
use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use std::time::{Duration, Instant};

mod cycle;
mod options;
mod plant_run;
mod summary;
mod vehicle;

pub use options::{Mode, PairOptions, SerialController, StateFault};
use plant_run::PlantRun;
use summary::Stats;
pub use summary::{LOCKSTEP_NOTE, PairSummary, Percentiles, Realtime};

fn log(msg: std::fmt::Arguments) {
    link::log_line(format_args!("plant_sim: {msg}"));
}

/// Runs the pair; returns the trajectory and the summary (also written to `out`). An
/// interrupted run is written too, and returned with `interrupted: true`.
pub fn run_pair(opts: &PairOptions) -> Result<(SimulatedTrajectory, PairSummary), SimError> {
    if opts.mode == Mode::Realtime
        && !(opts.rate_hz.is_finite() && opts.rate_hz > 0.0 && opts.rate_hz <= 100_000.0)
    {
        return Err(SimError::Input(format!(
            "--rate-hz: must be in (0, 100000], got {}",
            opts.rate_hz
        )));
    }
    if opts.miss_limit == 0 {
        return Err(SimError::Input(
            "--miss-limit: must be at least 1".to_owned(),
        ));
    }
    link::check_run_name(&opts.run)?;
    opts.scenario.group.dispatch(Pair(opts))
}

struct Pair<'a>(&'a PairOptions);

impl OnGroup for Pair<'_> {
    type Output = Result<(SimulatedTrajectory, PairSummary), SimError>;
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        run_group::<G, N, M>(self.0)
    }
}

fn run_group<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    opts: &PairOptions,
) -> Result<(SimulatedTrajectory, PairSummary), SimError> {
    let mut run = PlantRun::<G, N, M>::new(opts)?;
    ensure_dir(&opts.out)?;
    if opts.record {
        run.start_recorder()?;
    }
    run.start_tuning()?;
    let mut child = Spawned::start(opts)?;
    run.rt.plant = opts.rt.apply();
    for line in run.rt.plant.lines() {
        log(format_args!("real-time settings: {line}"));
    }
    if let Err(e) = run.notifier.ready() {
        log(format_args!("service manager: cannot notify READY=1: {e}"));
    }
    let first = run.connect(&mut child)?;
    // the controller wrote its report before it started its transport, so before it answered
    if let Some(path) = child.rt_report() {
        match link::rt::RtReport::read_json(path) {
            Ok(r) => {
                for line in r.lines() {
                    log(format_args!("controller's real-time settings: {line}"));
                }
                run.rt.controller = Some(r);
            }
            Err(e) => log(format_args!(
                "warning: the controller's real-time report is missing ({e})"
            )),
        }
    }
    let started = Instant::now();
    let mut pending = Some(first);
    let mut interrupted = None;
    let mut allocations = None;
    for k in 0..=run.steps {
        run.ping();
        run.cycle(k, pending.take(), &mut child)?;
        if k == run.steps {
            break;
        }
        if let Some(sig) = opts.stop.requested() {
            log(format_args!(
                "{sig} at t = {:.3} s: stopping the run, writing what ran",
                k as f64 * run.s.control_period
            ));
            interrupted = Some(sig);
            break;
        }
        run.advance(k)?;
        if k == 0 {
            // The first state published to the connected controller makes iceoryx2's notifier
            // connect to its listener (87 allocations, once): the count starts after it, as
            // the controller's starts after its first cycle.
            allocations = opts.thread_allocations.map(|count| (count, count()));
        }
    }
    let loop_allocations = allocations.map(|(count, at_start)| count() - at_start);
    run.live_status_end();
    run.param_changes = run.tuning.take().map(crate::tuning::Tuning::finish);
    let wall = started.elapsed();
    let (rejected, late) = (run.ep.invalid_commands(), run.ep.late_commands());
    // The run is over: tell the controller, then reap it.
    let _ = run.notifier.stopping();
    run.ep.shutdown();
    let controller_exit = child.finish(Duration::from_secs(3));
    let out = run.write(
        interrupted,
        controller_exit,
        rejected,
        late,
        loop_allocations,
    )?;
    log(format_args!(
        "{} cycles in {:.3} s of wall time",
        out.1.cycles,
        wall.as_secs_f64()
    ));
    Ok(out)
}
