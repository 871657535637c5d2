//! A trajectory planner process, written only against the public APIs of `link` (the plan
//! board), `ipc_types` (the plan message), `scenario` (the waypoint file) and `eqtrack-controller`
//! (the path): it streams a
//! scenario's path through waypoints to a `controller_node --reference stream` of the same
//! run while the pair runs — a stop path's legs or, with `path = "through"`, a through-path's.
//! A planner that decides on the fly builds its segments the same way
//! (`eqtrack_controller::path::Segment::between`, or `Segment::hermite` from the pose, body velocity
//! and acceleration at both ends) and publishes them the same way.
//!
//! ```text
//! planner --scenario scenarios/slew_so3.toml --name RUN [--horizon 2]
//! controller_node --scenario scenarios/slew_so3.toml --name RUN --reference stream
//! plant_sim run --scenario scenarios/slew_so3.toml --name RUN --no-spawn
//! ```
//!
//! It watches the plant's clock (`t` of its newest state) and keeps the pieces that end at
//! or after `t` and start by `t + horizon` published, at most `PLAN_WINDOW` per message: a
//! message goes out whenever a piece not published yet enters that window, and the
//! controller appends those it does not have. In lockstep the plant runs faster than real
//! time: give a horizon of at least the scenario's duration, on a path of at most
//! `PLAN_WINDOW` pieces, so every piece is out before the first state. It leaves when the plant ends the run or is gone, or on SIGINT/SIGTERM; a
//! planner started after one was killed takes over (exit codes as the other binaries': 0
//! done, 1 no plant or the plant is gone, 2 bad input).
#![cfg_attr(not(test), warn(clippy::too_many_lines))]
use clap::Parser;
use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use ipc_types::{PLAN_WINDOW, PlanMsg, WireSegment, flags};
use link::plan::PlanWriter;
use link::{Exit, StopFlag, process_alive};
use scenario::Scenario;
use scenario::cli::positive_seconds;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(
    name = "planner",
    version,
    about = "Streams a scenario's waypoint path to controller_node --reference stream"
)]
struct Cli {
    /// Scenario file whose `[reference] waypoints` are streamed.
    #[arg(long, value_name = "FILE")]
    scenario: PathBuf,
    /// Run name (as given to plant_sim and controller_node).
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Seconds ahead of the plant's clock to publish pieces.
    #[arg(long, value_name = "S", default_value = "2", value_parser = positive_seconds)]
    horizon: Duration,
    /// Seconds to wait for the plant's first state.
    #[arg(long, value_name = "S", default_value = "30", value_parser = positive_seconds)]
    startup_timeout: Duration,
}

fn log(msg: std::fmt::Arguments) {
    eprintln!("planner: {msg}");
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let fail = |exit: Exit, msg: String| {
        eprintln!("planner: error: {msg}");
        ExitCode::from(exit)
    };
    let stop = match StopFlag::install() {
        Ok(s) => s,
        Err(e) => return fail(Exit::Failed, format!("cannot handle signals: {e}")),
    };
    let scenario = match Scenario::from_file(&cli.scenario) {
        Ok(s) => s,
        Err(e) => return fail(Exit::BadInput, e.to_string()),
    };
    let group = scenario.group;
    match group.dispatch(Stream {
        cli: &cli,
        scenario: &scenario,
        stop,
    }) {
        Ok(()) => ExitCode::SUCCESS,
        Err((exit, msg)) => fail(exit, msg),
    }
}

struct Stream<'a> {
    cli: &'a Cli,
    scenario: &'a Scenario,
    stop: StopFlag,
}

impl OnGroup for Stream<'_> {
    type Output = Result<(), (Exit, String)>;
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let s = self.scenario;
        let bad = |msg: String| (Exit::BadInput, format!("scenario `{}`: {msg}", s.name));
        let path = match s.path::<G, N, M>() {
            Some(p) => p.map_err(|e| bad(e.to_string()))?,
            None => {
                return Err(bad(
                    "has no `[reference] waypoints`: nothing to stream".into()
                ));
            }
        };
        let pieces: Vec<WireSegment> = path.segments().map(link::wire::wire_segment).collect();
        let (Some(first), Some(last)) = (pieces.first(), pieces.last()) else {
            return Err(bad("a set-point has no pieces to stream".into()));
        };
        let mut board =
            PlanWriter::open(&self.cli.name).map_err(|e| (Exit::Failed, e.to_string()))?;
        log(format_args!(
            "run `{}`: {} pieces of `{}` (t = {} .. {} s), horizon {} s, writer slot {}",
            self.cli.name,
            pieces.len(),
            s.name,
            first.t0,
            last.t1,
            self.cli.horizon.as_secs_f64(),
            board.slot()
        ));
        stream::<G, N, M>(&mut board, &pieces, self.cli, &self.stop)
    }
}

/// Publishes the window of pieces that end at or after the plant's `t` and start by
/// `t + horizon` whenever a piece not published yet enters it, until the run ends. Pieces
/// only leaving the window are no reason to publish: the controller keeps what it has. So a
/// planner whose first window holds the whole path publishes once, and a lockstep run's
/// record does not depend on how fast the planner watched the plant's clock.
fn stream<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    board: &mut PlanWriter,
    pieces: &[WireSegment],
    cli: &Cli,
    stop: &StopFlag,
) -> Result<(), (Exit, String)> {
    let started = Instant::now();
    let mut plant_pid = None;
    // one past the last piece published
    let mut published_end = 0;
    loop {
        if let Some(sig) = stop.requested() {
            log(format_args!("{sig} received, leaving"));
            return Ok(());
        }
        let state = board.plant();
        if let Some(st) = state {
            if st.flags & flags::SHUTDOWN != 0 {
                log(format_args!("the plant ended the run"));
                return Ok(());
            }
            plant_pid = Some(st.plant_pid);
        }
        match plant_pid {
            Some(pid) if !process_alive(pid) => {
                return Err((Exit::Failed, "the plant's process is gone".into()));
            }
            None if started.elapsed() > cli.startup_timeout => {
                return Err((
                    Exit::Failed,
                    format!(
                        "no plant appeared on run `{}` within {:.0} s",
                        cli.name,
                        cli.startup_timeout.as_secs_f64()
                    ),
                ));
            }
            _ => {}
        }
        let now = state.map_or(0.0, |s| s.t);
        let from = pieces
            .iter()
            .position(|p| p.t1 >= now)
            .unwrap_or(pieces.len());
        let ahead = now + cli.horizon.as_secs_f64();
        let count = pieces[from..]
            .iter()
            .take(PLAN_WINDOW)
            .take_while(|p| p.t0 <= ahead)
            .count();
        if count > 0 && from + count > published_end {
            let mut msg = PlanMsg::new(link::wire::wire_group(G::KIND));
            msg.first_index = from as u32;
            msg.count = count as u32;
            msg.segments[..count].copy_from_slice(&pieces[from..from + count]);
            board.publish(&msg);
            log(format_args!(
                "t = {now:.3} s: published pieces {}..{} (t = {} .. {} s)",
                from,
                from + count - 1,
                pieces[from].t0,
                pieces[from + count - 1].t1
            ));
            published_end = from + count;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}
