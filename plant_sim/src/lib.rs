//! `plant_sim`: the command line over the plant, the studies, the flight tools and the loop
//! benchmark. One module per subcommand (`src/cmd/`), each with its arguments and its
//! handler; [`main`] parses the command line and runs one. The binary is a thin `main`
//! over it that installs the counting allocator.
//!
//! ```text
//! plant_sim                                  # = plant_sim sim --builtin seed
//! plant_sim sim [--scenario FILE | --builtin NAME] [--law L] [--out DIR]
//! plant_sim montecarlo [--scenario FILE] [--runs N] [--seed S] [--laws eqt,gt,nog,asym]
//!                      [--samples FILE] [--threads N] [--out DIR]
//!                      [--estimators truth,complementary,eqf] [--initial-error RAD]
//! plant_sim frames [--scenario FILE] [--runs N] [--seed S] [--frames reference,world,recentred]
//!                  [--duration S] [--threads N] [--world-radius M] [--world-turn RAD] [--out DIR]
//! plant_sim run [--scenario FILE | --builtin NAME] [--mode lockstep|realtime] [--rate-hz F]
//!               [--wake spin|event] [--no-spawn] [--name RUN] [--out DIR] [--no-record]
//! plant_sim replay OUT_DIR [--law L] [--scenario FILE] [--kp X[,X...]] [--kd X[,X...]]
//! plant_sim noise [--scenario FILE] [--gyro-noise LIST] [--runs N] [--out DIR]
//! plant_sim rejection [--scenario FILE | --builtin NAME] [--ki X] [--c X] [--gain X]
//!                     [--runs N] [--magnitude X] [--seed S] [--out DIR]
//! plant_sim monitor [--name RUN] [--plain]
//! plant_sim live [--name RUN] [--listen ADDR] [--wait S]
//! plant_sim bench-loop [--rates LIST] [--duration S] [--cyclictest PATH]
//! plant_sim reference [--scenario FILE | --builtin NAME] [--out DIR] [--strict] [--compare-paths]
//! plant_sim export OUT_DIR [--format mcap|jsonl] [--out FILE] [--compress]
//! ```
//! Exit codes: 0 done, 2 bad input (with a message naming the key and what is wrong),
//! 1 the run could not complete.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]
// The subcommands' doc comments are the command line's help text (clap): private, and not
// API documentation (`[sensors]` there names a scenario table).

use clap::{Parser, Subcommand};
use link::StopFlag;
use std::process::ExitCode;

mod cmd;

use cmd::live;
use cmd::{
    bench_loop, export, frames, monitor, montecarlo, moved, noise, param, pil, reference,
    rejection, replay, run, sim,
};

#[derive(Parser)]
#[command(
    name = "plant_sim",
    version,
    about = "Equivariant tracking control: plant and simulator"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run the closed loop in one process; write trajectory.csv, summary.json, figure.png/.svg.
    Sim(sim::SimArgs),
    /// The extended paper's Monte Carlo study over the four laws.
    Montecarlo(montecarlo::McArgs),
    /// Where EqT forms its error on SE(3): the error frames (reference, world, recentred)
    /// flown from the same random starts in a world moved up to 10 km and turned about z
    /// (frames.csv, table.md, a figure).
    Frames(frames::FramesArgs),
    /// A scenario moved with the world: turned by --heading about z and shifted by --offset,
    /// with its waypoint file, world directions and world disturbances; with --check, flown
    /// beside the original and compared column by column (docs/invariance.md).
    Move(moved::MoveArgs),
    /// What sensor noise costs: truth-fed against filter-fed control over gyro noise levels,
    /// with and without the gyro bias, over seeded runs (a scenario with [sensors]).
    Noise(noise::NoiseArgs),
    /// What the disturbance-rejection terms buy: the scenario (default
    /// scenarios/reject_so3.toml) flown with the plain law, the geometric integral and the
    /// momentum observer side by side (rejection.csv, table.md, a figure); with --runs N, a
    /// Monte Carlo over random constant body disturbances.
    Rejection(rejection::RejectionArgs),
    /// The plant process of the pair: talks to controller_node over iceoryx2.
    Run(run::RunArgs),
    /// Round trip of the real loop: iceoryx2 busy-poll, iceoryx2 event, Unix-socket baseline.
    BenchLoop(bench_loop::BenchLoopArgs),
    /// The scenario's desired trajectory sampled at its control period: reference.csv and a
    /// figure (check a manoeuvre before flying it).
    Reference(reference::ReferenceArgs),
    /// Export a run's flight recording (OUT_DIR/messages.log) to MCAP for Foxglove,
    /// PlotJuggler or Rerun: OUT_DIR/run.mcap. Offline; runs `eqtrack-export` from this
    /// binary's directory (the plant process itself never links an MCAP writer).
    Export(export::ExportArgs),
    /// Run the controller in-process over a recorded run's states (OUT_DIR/messages.log) and
    /// compare every command with the recorded one, bit for bit: exit 0 when all are
    /// identical, 1 naming the first that differs. With --law, --scenario, --kp or --kd: a
    /// what-if, written to replay.csv and a figure (exit 0).
    Replay(replay::ReplayArgs),
    /// Watch a running pair live in the terminal: rate, round trip, misses, safe mode, the
    /// Lyapunov value. Read-only; exits when the run ends, or on q or Ctrl-C.
    Monitor(monitor::MonitorArgs),
    /// Serve a running pair to Foxglove as it flies: its state, command and status over the
    /// Foxglove WebSocket protocol (ws://127.0.0.1:8765 by default). Read-only; runs
    /// `eqtrack-live` from this binary's directory (the pair never links WebSocket code) and
    /// exits when the run ends.
    Live(live::LiveArgs),
    /// Read or change a gain of a running pair started with `plant_sim run --tunable`:
    /// `param --name RUN get KEY`, `param --name RUN set KEY VALUE` (checked as the scenario
    /// key is; in force from the next cycle; recorded for replay).
    Param(param::ParamArgs),
    /// Write the processor-in-the-loop firmware's configuration for a scenario (the bytes
    /// scripts/pil.sh builds the firmware with), and print the identity it will greet with.
    PilConfig(pil::PilConfigArgs),
}

/// Parses the command line and runs its subcommand (`sim` with the seed scenario when none
/// is given); the exit code says how it went (0 done, 2 bad input, 1 the run could not
/// complete, 130/143 stopped by a signal).
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let stop = match StopFlag::install() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: cannot handle signals: {e}");
            return link::Exit::Failed.into();
        }
    };
    let result = match cli.command {
        None => sim::sim(sim::SimArgs::default(), &stop),
        Some(Command::Sim(a)) => sim::sim(a, &stop),
        Some(Command::Montecarlo(a)) => montecarlo::montecarlo_cmd(a, &stop),
        Some(Command::Frames(a)) => frames::frames_cmd(a, &stop),
        Some(Command::Move(a)) => moved::move_cmd(a, &stop),
        Some(Command::Noise(a)) => noise::noise_cmd(a),
        Some(Command::Rejection(a)) => rejection::rejection_cmd(a),
        Some(Command::Run(a)) => run::run_cmd(a, &stop),
        Some(Command::BenchLoop(a)) => bench_loop::bench_loop_cmd(a, &stop),
        Some(Command::Reference(a)) => reference::reference_cmd(a),
        Some(Command::Export(a)) => export::export_cmd(a),
        Some(Command::Replay(a)) => replay::replay_cmd(a),
        Some(Command::Monitor(a)) => monitor::monitor_cmd(a, &stop),
        Some(Command::Live(a)) => live::live_cmd(a, &stop),
        Some(Command::Param(a)) => param::param_cmd(a),
        Some(Command::PilConfig(a)) => pil::pil_config_cmd(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit().into()
        }
    }
}
