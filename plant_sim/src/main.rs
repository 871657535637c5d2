//! `plant_sim`: the plant process and the simulation front end.
//!
//! ```text
//! plant_sim                                  # = plant_sim sim --builtin seed
//! plant_sim sim [--scenario FILE | --builtin NAME] [--law L] [--out DIR]
//! plant_sim montecarlo [--scenario FILE] [--runs N] [--seed S] [--laws eqt,gt,nog,asym]
//!                      [--samples FILE] [--threads N] [--out DIR]
//!                      [--estimators truth,complementary,eqf] [--initial-error RAD]
//! plant_sim run [--scenario FILE | --builtin NAME] [--mode lockstep|realtime] [--rate-hz F]
//!               [--wake spin|event] [--no-spawn] [--name RUN] [--out DIR] [--no-record]
//! plant_sim replay OUT_DIR [--law L] [--scenario FILE] [--kp X[,X...]] [--kd X[,X...]]
//! plant_sim monitor [--name RUN] [--plain]
//! plant_sim bench-loop [--rates LIST] [--duration S] [--cyclictest PATH]
//! plant_sim reference [--scenario FILE | --builtin NAME] [--out DIR] [--strict] [--compare-paths]
//! plant_sim export OUT_DIR [--format mcap|jsonl] [--out FILE] [--compress]
//! ```
//! Exit codes: 0 done, 2 bad input (with a message naming the key and what is wrong),
//! 1 the run could not complete.

use clap::{Args, Parser, Subcommand};
use controller::Law;
use indicatif::{ProgressBar, ProgressStyle};
use link::{StopFlag, TransportKind, Wake};
use plant_sim::SimError;
use plant_sim::montecarlo;
use plant_sim::output::{Summary, ensure_dir, write_json, write_trajectory_csv};
use plant_sim::pair::Mode;
use plant_sim::plot::trajectory_figure;
use scenario::Scenario;
use scenario::cli::{ScenarioSource, law_parser, positive_seconds};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

// Counts the heap allocations of each thread: the plant's loop thread reports its own in
// `summary.json`, to show that recording allocates nothing there.
#[global_allocator]
static GLOBAL: alloc_counter::Counting = alloc_counter::Counting;

use alloc_counter::thread_allocations;

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
    Sim(SimArgs),
    /// The extended paper's Monte Carlo study over the four laws.
    Montecarlo(McArgs),
    /// What sensor noise costs: truth-fed against filter-fed control over gyro noise levels,
    /// with and without the gyro bias, over seeded runs (a scenario with [sensors]).
    Noise(NoiseArgs),
    /// What the disturbance-rejection terms buy: the scenario (default
    /// scenarios/reject_so3.toml) flown with the plain law, the geometric integral and the
    /// momentum observer side by side (rejection.csv, table.md, a figure); with --runs N, a
    /// Monte Carlo over random constant body disturbances.
    Rejection(RejectionArgs),
    /// The plant process of the pair: talks to controller_node over iceoryx2.
    Run(RunArgs),
    /// Round trip of the real loop: iceoryx2 busy-poll, iceoryx2 event, Unix-socket baseline.
    BenchLoop(BenchLoopArgs),
    /// The scenario's desired trajectory sampled at its control period: reference.csv and a
    /// figure (check a manoeuvre before flying it).
    Reference(ReferenceArgs),
    /// Export a run's flight recording (OUT_DIR/messages.log) to MCAP for Foxglove,
    /// PlotJuggler or Rerun: OUT_DIR/run.mcap. Offline; runs `eqtrack-export` from this
    /// binary's directory (the plant process itself never links an MCAP writer).
    Export(ExportArgs),
    /// Run the controller in-process over a recorded run's states (OUT_DIR/messages.log) and
    /// compare every command with the recorded one, bit for bit: exit 0 when all are
    /// identical, 1 naming the first that differs. With --law, --scenario, --kp or --kd: a
    /// what-if, written to replay.csv and a figure (exit 0).
    Replay(ReplayArgs),
    /// Watch a running pair live in the terminal: rate, round trip, misses, safe mode, the
    /// Lyapunov value. Read-only; exits when the run ends, or on q or Ctrl-C.
    Monitor(MonitorArgs),
}

#[derive(Args)]
struct ReplayArgs {
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

#[derive(Args)]
struct MonitorArgs {
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

#[derive(Args)]
struct ReferenceArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Output directory (created if needed); default out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Exit 1 when the feedforward alone exceeds the torque limit on an axis (default: a
    /// warning, exit 0).
    #[arg(long)]
    strict: bool,
    /// Also fly the waypoints both ways (`path = "stop"` and `"through"`): paths.{png,svg}
    /// and paths.json.
    #[arg(long)]
    compare_paths: bool,
}

#[derive(Args)]
struct ExportArgs {
    /// The run's output directory (holding messages.log).
    #[arg(value_name = "OUT_DIR")]
    dir: PathBuf,
    /// `mcap` (default), or `jsonl`: one JSON object per message, the same messages.
    #[arg(long, value_name = "FORMAT", default_value = "mcap", value_parser = ["mcap", "jsonl"])]
    format: String,
    /// The output file (default: OUT_DIR/run.mcap).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// zstd-compress the MCAP chunks (eqtrack-export built with its `zstd` feature).
    #[arg(long)]
    compress: bool,
}

#[derive(Args)]
struct BenchLoopArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Loop rates to measure, comma-separated (Hz).
    #[arg(
        long,
        value_name = "LIST",
        default_value = "1000,10000",
        value_delimiter = ','
    )]
    rates: Vec<f64>,
    /// Seconds per case and rate.
    #[arg(long, value_name = "S", default_value = "5", value_parser = positive_seconds)]
    duration: Duration,
    /// Output directory; default out/bench-loop.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// The cyclictest program for the operating-system floor (Debian's rt-tests;
    /// `scripts/rt-tests.sh` fetches it and prints its path).
    #[arg(long, value_name = "PATH", default_value = "cyclictest")]
    cyclictest: PathBuf,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// lockstep: exact, waits for each command; realtime: steps on the wall clock.
    #[arg(long, value_enum, default_value_t = Mode::Realtime)]
    mode: Mode,
    /// Real-time rate; the control period becomes 1/F.
    #[arg(long, value_name = "F", default_value_t = 1000.0)]
    rate_hz: f64,
    /// How the processes wait for each other's messages: event (they sleep; robust on a
    /// shared machine) or spin (busy polling; lowest latency, needs a core per process).
    #[arg(long, value_enum, default_value_t = Wake::Event)]
    wake: Wake,
    /// Override the scenario's duration (s).
    #[arg(long, value_name = "S", value_parser = positive_seconds)]
    duration: Option<Duration>,
    /// Transport: iceoryx2, or uds (the Unix-socket baseline; spawned controllers follow).
    #[arg(long, value_enum, default_value_t = TransportKind::Iceoryx2)]
    transport: TransportKind,
    /// Do not start controller_node; wait for one started by hand.
    #[arg(long)]
    no_spawn: bool,
    /// Run name: pairs with different names run side by side.
    #[arg(long, value_name = "RUN", default_value = "eqtrack")]
    name: String,
    /// Output directory; default out/run-<RUN>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Consecutive deadline misses that start safe mode.
    #[arg(long, value_name = "N", default_value_t = 3)]
    miss_limit: u32,
    /// Do not record: no `messages.log`, no flight-recorder thread and no live status for
    /// `plant_sim monitor` (the loop then runs exactly as it would without the recorder).
    #[arg(long)]
    no_record: bool,
    /// Keep every Nth cycle in trajectory.csv (and the last one): for long runs, whose rows
    /// are otherwise all held in memory until the end.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    record_every: u64,
    #[command(flatten)]
    rt: link::rt::RtSettings,
    /// Pin the controller this command starts to these CPUs (default: `--cpu`'s list, the
    /// best choice with event wake-up; give busy-polling processes a CPU each).
    /// `--rt-priority` and `--lock-memory` apply to both processes.
    #[arg(long, value_name = "LIST", value_parser = link::rt::parse_cpu_list, conflicts_with = "no_spawn")]
    controller_cpu: Option<link::rt::CpuList>,
    /// Lockstep: seconds to wait for each command.
    #[arg(long, value_name = "S", default_value = "5", value_parser = positive_seconds)]
    lockstep_timeout: Duration,
    /// Seconds to wait for the controller (default 10, or 60 with --no-spawn).
    #[arg(long, value_name = "S", value_parser = positive_seconds)]
    connect_timeout: Option<Duration>,
    /// Test builds only (feature `fault-injection`): K:version|group|nan publishes a
    /// corrupted state instead of state K.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K:KIND", hide = true)]
    fault_state: Vec<String>,
    /// Test builds only: the spawned controller publishes a NaN torque instead of command K.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K", hide = true)]
    fault_nan_torque: Option<u64>,
    /// Test builds only: K:KIND plants a bad sensor sample at tick K (as `sim`).
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K:KIND", hide = true)]
    fault_sample: Vec<String>,
}

#[derive(Args, Default)]
struct SimArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Override the scenario's law.
    #[arg(long, value_name = "L", value_parser = law_parser())]
    law: Option<Law>,
    /// Output directory (created if needed); default out/<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Test builds only (feature `fault-injection`): K:KIND plants a bad sensor sample at
    /// tick K (gyro-nan, gyro-inf, gyro-spike, dir-nan, dir-inf, dir-zero, accel-far).
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "K:KIND", hide = true)]
    fault_sample: Vec<String>,
}

#[derive(Args)]
struct RejectionArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// The integral variant's K_I (every axis) when the scenario has no `integral`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    ki: f64,
    /// The integral variant's c (every axis) when the scenario has no `integral`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 5.0,
        allow_negative_numbers = true
    )]
    c: f64,
    /// The observer variant's gain L (1/s, every axis) when the scenario has no
    /// `disturbance_observer`.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 20.0,
        allow_negative_numbers = true
    )]
    gain: f64,
    /// Monte Carlo: this many random constant body disturbances (0: none).
    #[arg(long, value_name = "N", default_value_t = 0)]
    runs: usize,
    /// Monte Carlo: the largest disturbance magnitude (N·m); each is uniform in [0, X] in a
    /// uniformly random direction.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 0.2,
        allow_negative_numbers = true
    )]
    magnitude: f64,
    /// Monte Carlo: the seed of the draws.
    #[arg(long, value_name = "S", default_value_t = 1)]
    seed: u64,
    /// Output directory; default out/rejection-<scenario name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct NoiseArgs {
    /// Scenario with [sensors] and a complementary [estimator].
    #[arg(
        long,
        value_name = "FILE",
        default_value = "scenarios/sensors_so3.toml"
    )]
    scenario: PathBuf,
    /// Gyro noise densities to compare (rad/s/√Hz), comma-separated.
    #[arg(
        long,
        value_name = "LIST",
        default_value = "0.002,0.02,0.1",
        value_delimiter = ','
    )]
    gyro_noise: Vec<f64>,
    /// Seeded runs per configuration (sensor seeds 1..=N).
    #[arg(long, value_name = "N", default_value_t = 10)]
    runs: usize,
    /// Output directory; default out/noise.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct McArgs {
    /// Base scenario (TOML); default the built-in `montecarlo`.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Number of drawn samples (ignored with --samples).
    #[arg(long, default_value_t = 200, value_name = "N")]
    runs: usize,
    /// Seed of the sample stream.
    #[arg(long, default_value_t = 1, value_name = "S")]
    seed: u64,
    /// Laws to compare, comma-separated.
    #[arg(long, default_value = "eqt,gt,nog,asym", value_name = "LIST", value_delimiter = ',', value_parser = law_parser())]
    laws: Vec<Law>,
    /// Samples CSV (header rx,ry,rz,wx,wy,wz), one run per row.
    #[arg(long, value_name = "FILE")]
    samples: Option<PathBuf>,
    /// Worker threads (default: one per core). The numbers do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Output directory; default out/montecarlo.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Compare estimators instead of laws (the first of --laws flies every run): truth,
    /// complementary, eqf. Needs a scenario with [sensors] (and kind = "eqf" for eqf).
    #[arg(long, value_name = "LIST", value_delimiter = ',', value_parser = estimator_parser)]
    estimators: Vec<scenario::EstimatorKind>,
    /// With --estimators: start each filter this far (rad, about an axis drawn per run)
    /// from the true attitude instead of TRIAD, and time its convergence.
    #[arg(long, value_name = "RAD", requires = "estimators")]
    initial_error: Option<f64>,
}

fn estimator_parser(text: &str) -> Result<scenario::EstimatorKind, String> {
    use scenario::EstimatorKind::*;
    [Truth, Complementary, Eqf]
        .into_iter()
        .find(|k| k.name() == text)
        .ok_or_else(|| format!("`{text}`: expected truth, complementary or eqf"))
}

fn progress(len: u64, what: &str) -> ProgressBar {
    // indicatif draws only when stderr is a terminal.
    let bar = ProgressBar::new(len);
    if let Ok(style) =
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(what.to_owned());
    bar
}

fn sim(args: SimArgs, stop: &StopFlag) -> Result<(), SimError> {
    let mut s = args.source.load("seed")?;
    if let Some(l) = args.law {
        s = s.with_law(l)?;
    }
    let out = args.out.unwrap_or_else(|| Path::new("out").join(&s.name));
    ensure_dir(&out)?;
    let bar = progress(s.steps() + 1, &format!("sim {}", s.name));
    #[cfg(feature = "fault-injection")]
    let planted = sample_faults(&args.fault_sample)?;
    #[cfg(not(feature = "fault-injection"))]
    let planted = Vec::new();
    let traj = plant_sim::trajectory::simulate_planted(&s, &planted, &|k| {
        if k % 256 == 0 {
            bar.set_position(k);
            SimError::check(stop)?;
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    write_trajectory_csv(&traj, &out.join("trajectory.csv"))?;
    let summary = Summary::of(&traj, &s.name, s.law.name());
    write_json(&summary, &out.join("summary.json"))?;
    let title = format!(
        "{} — {} on {}, T = {} s",
        s.name,
        s.law.name().to_uppercase(),
        s.group.name().to_uppercase(),
        s.duration
    );
    trajectory_figure(&traj, &title, &out.join("figure"))?;
    let f = &summary.final_errors;
    println!(
        "scenario {} ({}, law {}), {} steps of {} s",
        s.name,
        s.group.name(),
        s.law.name(),
        s.steps(),
        s.control_period
    );
    println!(
        "final: L = {:.4e}, |Q_E - I| = {:.4e}, |p_E| = {:.4e}, attitude error = {:.4e}, velocity error = {:.4e}",
        f.lyapunov, f.config_error, f.momentum_error, f.attitude_error, f.velocity_error
    );
    println!(
        "peak torque {:.4}, effort {:.4}, settling time {}",
        summary.peak_torque,
        summary.effort,
        summary
            .settling_time
            .map(|t| format!("{t:.2} s"))
            .unwrap_or_else(|| "not settled".to_owned())
    );
    println!(
        "wrote {}/{{trajectory.csv, summary.json, figure.png, figure.svg}}",
        out.display()
    );
    Ok(())
}

fn rejection_cmd(args: RejectionArgs) -> Result<(), SimError> {
    use plant_sim::rejection;
    // default: the issue's set-point, shipped as a scenario file
    let s = if args.source.scenario.is_none() && args.source.builtin.is_none() {
        Scenario::from_file(Path::new("scenarios/reject_so3.toml"))?
    } else {
        args.source.load("seed")?
    };
    let v = rejection::Variants::of(&s, args.ki, args.c, args.gain)?;
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join(format!("rejection-{}", s.name)));
    ensure_dir(&out)?;
    let flown = rejection::compare(&s, &v)?;
    rejection::write(&flown, &s, &out)?;
    print!("{}", rejection::table(&flown, s.group.dims().1));
    println!(
        "wrote {}/{{rejection.csv, table.md, rejection.png, rejection.svg}}",
        out.display()
    );
    if args.runs > 0 {
        let runs = rejection::montecarlo(&s, &v, args.runs, args.magnitude, args.seed)?;
        rejection::write_mc(&runs, &out)?;
        let mut calm = s.clone();
        calm.disturbance = vec![0.0; s.group.dims().1];
        calm.rejection = Default::default();
        let undisturbed = plant_sim::trajectory::simulate(&calm, &|_| Ok(()))?
            .rows
            .last()
            .map_or(f64::NAN, |r| rejection::angle(r.attitude_error));
        println!(
            "Monte Carlo: {} random constant disturbances up to {} N·m (seed {}); without a \
             disturbance the plain law ends {undisturbed:.3e} rad from the reference",
            args.runs, args.magnitude, args.seed
        );
        print!("{}", rejection::mc_table(&runs));
        println!(
            "wrote {}/{{rejection_montecarlo.csv, montecarlo.md}}",
            out.display()
        );
    }
    Ok(())
}

fn noise_cmd(args: NoiseArgs) -> Result<(), SimError> {
    let base = Scenario::from_file(&args.scenario)?;
    let out = args.out.unwrap_or_else(|| Path::new("out").join("noise"));
    ensure_dir(&out)?;
    let rows = plant_sim::noise::study(&base, &args.gyro_noise, args.runs)?;
    plant_sim::noise::write(&rows, &base.name, &out)?;
    print!("{}", plant_sim::noise::table(&rows));
    println!(
        "wrote {}/{{noise.csv, table.md, noise.png, noise.svg}}",
        out.display()
    );
    Ok(())
}

fn montecarlo_cmd(args: McArgs, stop: &StopFlag) -> Result<(), SimError> {
    let base = match &args.scenario {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::builtin("montecarlo")?,
    };
    let laws = args.laws;
    if args.threads == Some(0) {
        return Err(SimError::Input("--threads: must be at least 1".to_owned()));
    }
    let samples = match &args.samples {
        Some(p) => montecarlo::read_samples(p)?,
        None => {
            if args.runs == 0 {
                return Err(SimError::Input("--runs: must be at least 1".to_owned()));
            }
            montecarlo::draw_samples(args.runs, args.seed)
        }
    };
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join("montecarlo"));
    ensure_dir(&out)?;
    if !args.estimators.is_empty() {
        let study = (args.estimators.as_slice(), args.initial_error, args.threads);
        return estimator_study(&base, &samples, study, laws[0], &out, stop);
    }
    let bar = progress((samples.len() * laws.len()) as u64, "montecarlo");
    let results = montecarlo::run_all(&base, &samples, &laws, args.threads, &|| bar.inc(1), stop)?;
    bar.finish_and_clear();
    montecarlo::write_runs_csv(&results, &out.join("runs.csv"))?;
    if let Some(sig) = stop.requested() {
        eprintln!(
            "{sig}: stopped after {} of {} runs; wrote {}/runs.csv",
            results.len(),
            samples.len() * laws.len(),
            out.display()
        );
        return Err(SimError::Interrupted(sig));
    }
    let mean = montecarlo::means(&results, &laws);
    montecarlo::write_mean_csv(&mean, &laws, base.control_period, &out.join("mean.csv"))?;
    let stats = montecarlo::stats(&results, &laws);
    write_json(&stats, &out.join("summary.json"))?;
    montecarlo::figure(
        &mean,
        &laws,
        base.control_period,
        samples.len(),
        &out.join("figure"),
    )?;
    println!(
        "Monte Carlo on `{}`: {} runs x {} laws, T = {} s",
        base.name,
        samples.len(),
        laws.len(),
        base.duration
    );
    print!("{}", montecarlo::table(&stats));
    println!(
        "wrote {}/{{runs.csv, mean.csv, summary.json, figure.png, figure.svg}}",
        out.display()
    );
    Ok(())
}

/// `montecarlo --estimators`: the filters on the same runs.
fn estimator_study(
    base: &Scenario,
    samples: &[montecarlo::Sample],
    (estimators, initial_error, threads): (&[scenario::EstimatorKind], Option<f64>, Option<usize>),
    law: Law,
    out: &Path,
    stop: &StopFlag,
) -> Result<(), SimError> {
    use plant_sim::estimator_study as study;
    let bar = progress((samples.len() * estimators.len()) as u64, "estimators");
    let results = study::run_study(
        base,
        samples,
        estimators,
        law,
        initial_error,
        threads,
        &|| bar.inc(1),
        stop,
    )?;
    bar.finish_and_clear();
    if let Some(sig) = stop.requested() {
        eprintln!(
            "{sig}: stopped after {} of {} runs",
            results.len(),
            samples.len() * estimators.len()
        );
        return Err(SimError::Interrupted(sig));
    }
    let stats = study::stats(&results, estimators);
    write_json(&stats, &out.join("summary.json"))?;
    study::write(&results, &stats, estimators, base.control_period, out)?;
    println!(
        "Estimators on `{}` with {}: {} runs each, T = {} s{}",
        base.name,
        law.name(),
        samples.len(),
        base.duration,
        initial_error.map_or(String::new(), |e| format!(", filters started {e} rad off"))
    );
    print!("{}", study::table(&stats));
    println!(
        "wrote {}/{{estimators.csv, estimators.md, nees.csv, summary.json, estimators.png, estimators.svg}}",
        out.display()
    );
    Ok(())
}

fn bench_loop_cmd(args: BenchLoopArgs, stop: &StopFlag) -> Result<(), SimError> {
    let rates = args.rates;
    if let Some(r) = rates
        .iter()
        .find(|x| !(x.is_finite() && **x > 0.0 && **x <= 100_000.0))
    {
        return Err(SimError::Input(format!(
            "--rates: `{r}` is not a rate in (0, 100000] Hz"
        )));
    }
    let out = args
        .out
        .unwrap_or_else(|| Path::new("out").join("bench-loop"));
    let result = plant_sim::bench_loop::bench_loop(
        &args.source,
        &rates,
        args.duration.as_secs_f64(),
        &args.cyclictest,
        &out,
        Some(thread_allocations),
        stop,
    )?;
    println!(
        "round trip of the controller loop (state published -> command received), scenario {}:",
        result.scenario
    );
    print!("{}", plant_sim::bench_loop::table(&result.cases));
    println!("\nthe floors, measured in the same run at the same rates and durations:");
    print!("{}", plant_sim::bench_loop::floors_table(&result));
    println!(
        "wrote {}/{{summary.json, table.md}} and one run directory per case",
        out.display()
    );
    Ok(())
}

fn run_cmd(args: RunArgs, stop: &StopFlag) -> Result<(), SimError> {
    use plant_sim::pair::{PairOptions, run_pair};
    let mut scenario = args.source.load("seed")?;
    if let Some(d) = args.duration {
        scenario.duration = d.as_secs_f64();
    }
    let state_faults = state_faults(&args)?;
    let spawn = !args.no_spawn;
    let opts = PairOptions {
        scenario,
        source: args.source.clone(),
        record: !args.no_record,
        thread_allocations: Some(thread_allocations),
        mode: args.mode,
        rate_hz: args.rate_hz,
        wake: args.wake,
        transport: args.transport,
        spawn,
        run: args.name.clone(),
        out: args
            .out
            .unwrap_or_else(|| Path::new("out").join(format!("run-{}", args.name))),
        miss_limit: args.miss_limit,
        rt: args.rt.clone(),
        controller_rt: link::rt::RtSettings {
            cpu: args.controller_cpu.clone().or_else(|| args.rt.cpu.clone()),
            ..args.rt.clone()
        },
        record_every: args.record_every,
        lockstep_timeout: args.lockstep_timeout,
        connect_timeout: args
            .connect_timeout
            .unwrap_or(Duration::from_secs(if spawn { 10 } else { 60 })),
        state_faults,
        #[cfg(feature = "fault-injection")]
        controller_fault_nan_torque: args.fault_nan_torque,
        #[cfg(feature = "fault-injection")]
        sample_faults: sample_faults(&args.fault_sample)?,
        #[cfg(not(feature = "fault-injection"))]
        sample_faults: Vec::new(),
        #[cfg(not(feature = "fault-injection"))]
        controller_fault_nan_torque: None,
        stop: stop.clone(),
    };
    let (_, s) = run_pair(&opts)?;
    print_pair_summary(&s, &opts.out);
    match stop.requested() {
        Some(sig) if s.interrupted => Err(SimError::Interrupted(sig)),
        _ => Ok(()),
    }
}

/// `plant_sim replay`: prints what the replay found; a difference outside a what-if is an
/// error (exit 1).
fn replay_cmd(args: ReplayArgs) -> Result<(), SimError> {
    use plant_sim::recorder::replay::{ReplayOptions, replay};
    let opts = ReplayOptions {
        dir: args.dir,
        law: args.law,
        scenario: args.scenario,
        kp: args.kp,
        kd: args.kd,
        out: args.out,
    };
    let r = replay(&opts)?;
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

fn monitor_cmd(args: MonitorArgs, stop: &StopFlag) -> Result<(), SimError> {
    use plant_sim::recorder::monitor::{MonitorEnd, MonitorOptions, monitor};
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

/// The `--fault-state K:KIND` injections (test builds only; empty otherwise).
/// `--fault-sample K:KIND` (test builds).
#[cfg(feature = "fault-injection")]
fn sample_faults(
    texts: &[String],
) -> Result<Vec<(u64, plant_sim::sensors::SampleFault)>, SimError> {
    texts
        .iter()
        .map(|text| {
            let bad = || {
                SimError::Input(format!(
                    "--fault-sample: expected K:gyro-nan|gyro-inf|gyro-spike|dir-nan|dir-inf|dir-zero|accel-far, got `{text}`"
                ))
            };
            let (k, kind) = text.split_once(':').ok_or_else(bad)?;
            let k: u64 = k.parse().map_err(|_| bad())?;
            let kind = plant_sim::sensors::SampleFault::parse(kind).ok_or_else(bad)?;
            Ok((k, kind))
        })
        .collect()
}

fn state_faults(
    #[allow(unused_variables)] args: &RunArgs,
) -> Result<Vec<(u64, plant_sim::pair::StateFault)>, SimError> {
    #[allow(unused_mut)]
    let mut state_faults = Vec::new();
    #[cfg(feature = "fault-injection")]
    for text in &args.fault_state {
        let bad = || {
            SimError::Input(format!(
                "--fault-state: expected K:version|group|nan, got `{text}`"
            ))
        };
        let (k, kind) = text.split_once(':').ok_or_else(bad)?;
        let k: u64 = k.parse().map_err(|_| bad())?;
        let kind = match kind {
            "version" => plant_sim::pair::StateFault::Version,
            "group" => plant_sim::pair::StateFault::Group,
            "nan" => plant_sim::pair::StateFault::Nan,
            _ => return Err(bad()),
        };
        state_faults.push((k, kind));
    }
    Ok(state_faults)
}

/// Prints a finished (or interrupted) pair run's summary to stdout.
fn print_pair_summary(s: &plant_sim::pair::PairSummary, out: &Path) {
    let f = &s.sim.final_errors;
    println!(
        "run `{}`: scenario {} ({}, law {}), {}, {} cycles, {} wake-up",
        s.run,
        s.sim.scenario,
        s.sim.group,
        s.sim.law,
        match s.rate_hz {
            Some(r) => format!("real time at {r} Hz"),
            None => "lockstep".to_owned(),
        },
        s.cycles,
        s.wake
    );
    println!(
        "final: L = {:.4e}, |Q_E - I| = {:.4e}, |p_E| = {:.4e}, attitude error = {:.4e}",
        f.lyapunov, f.config_error, f.momentum_error, f.attitude_error
    );
    let p = |x: &plant_sim::pair::Percentiles| {
        format!(
            "p50 {:.2} / p99 {:.2} / p99.9 {:.2} / max {:.2} us",
            x.p50_us, x.p99_us, x.p99_9_us, x.max_us
        )
    };
    println!(
        "round trip (state published -> command received): {}",
        p(&s.latency)
    );
    println!(
        "controller compute (state received -> command published): {}",
        p(&s.controller_compute)
    );
    if let Some(t) = &s.tick_lateness {
        println!("plant tick lateness (scheduling): {}", p(t));
    }
    match &s.deadline_note {
        Some(note) => println!("{note}; commands rejected {}", s.commands_rejected),
        None => println!(
            "deadline misses {}, safe-mode entries {} ({} cycles), commands rejected {}, late {}",
            s.deadline_misses,
            s.safe_mode_entries,
            s.safe_mode_cycles,
            s.commands_rejected,
            s.late_commands
        ),
    }
    println!(
        "wrote {}/{{trajectory.csv, summary.json, figure.png, figure.svg{}}}",
        out.display(),
        if s.recording.is_some() {
            ", messages.log, scenario.toml"
        } else {
            ""
        }
    );
}

fn reference_cmd(args: ReferenceArgs) -> Result<(), SimError> {
    let s = args.source.load("seed")?;
    let out = args.out.unwrap_or_else(|| Path::new("out").join(&s.name));
    let (csv, report) = plant_sim::reference::write_reference(&s, &out)?;
    println!(
        "reference of `{}` ({}, {}{}): {} samples at {} s; wrote {}, {}/reference.{{png,svg}} and {}/reference.json",
        s.name,
        s.group.name(),
        s.path
            .as_ref()
            .map_or("feedforward series", |p| p.file.as_str()),
        s.path
            .as_ref()
            .filter(|p| p.times.len() > 1)
            .map_or(String::new(), |p| format!(", path = \"{}\"", p.kind.name())),
        s.steps() + 1,
        s.control_period,
        csv.display(),
        out.display(),
        out.display()
    );
    print!("{}", plant_sim::reference::feasibility_text(&report));
    for w in &report.warnings {
        eprintln!("{w}");
    }
    if args.compare_paths {
        let c = plant_sim::reference::compare_paths(&s, &out)?;
        for ((way, f), (_, flown)) in c.reports.iter().zip(&c.tracking) {
            let tau = f.torque.iter().map(|p| p.value).fold(0.0f64, f64::max);
            println!(
                "  {way:<8} peak |ω_d| {:.4} rad/s at t = {:.2} s, peak |τ_d| on an axis {tau:.4}, flown: largest attitude error from the second waypoint on {flown:.3e}",
                f.angular_speed.value, f.angular_speed.t
            );
        }
        println!(
            "wrote {0}/paths.{{png,svg}} and {0}/paths.json",
            out.display()
        );
    }
    if args.strict && !report.warnings.is_empty() {
        return Err(SimError::Run(format!(
            "--strict: the feedforward alone exceeds the torque limit on {} axis/axes (see the warnings above)",
            report.warnings.len()
        )));
    }
    Ok(())
}

/// Runs `eqtrack-export` (beside this binary) with the same arguments; its exit status.
fn export_cmd(args: ExportArgs) -> Result<(), SimError> {
    let exe = std::env::current_exe()
        .map_err(|e| SimError::Run(format!("cannot locate plant_sim: {e}")))?;
    let path = exe.with_file_name("eqtrack-export");
    if !path.exists() {
        return Err(SimError::Run(format!(
            "{} not found: build it (cargo build --release --workspace)",
            path.display()
        )));
    }
    let mut cmd = std::process::Command::new(&path);
    cmd.arg(&args.dir).args(["--format", &args.format]);
    if let Some(out) = &args.out {
        cmd.arg("--out").arg(out);
    }
    if args.compress {
        cmd.arg("--compress");
    }
    let status = cmd
        .status()
        .map_err(|e| SimError::Run(format!("cannot start {}: {e}", path.display())))?;
    match status.code() {
        Some(0) => Ok(()),
        Some(2) => Err(SimError::Input(
            "the export refused its input (above)".to_owned(),
        )),
        _ => Err(SimError::Run(format!("eqtrack-export: {status}"))),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let stop = match StopFlag::install() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: cannot handle signals: {e}");
            return link::Exit::Failed.into();
        }
    };
    let result = match cli.command {
        None => sim(SimArgs::default(), &stop),
        Some(Command::Sim(a)) => sim(a, &stop),
        Some(Command::Montecarlo(a)) => montecarlo_cmd(a, &stop),
        Some(Command::Noise(a)) => noise_cmd(a),
        Some(Command::Rejection(a)) => rejection_cmd(a),
        Some(Command::Run(a)) => run_cmd(a, &stop),
        Some(Command::BenchLoop(a)) => bench_loop_cmd(a, &stop),
        Some(Command::Reference(a)) => reference_cmd(a),
        Some(Command::Export(a)) => export_cmd(a),
        Some(Command::Replay(a)) => replay_cmd(a),
        Some(Command::Monitor(a)) => monitor_cmd(a, &stop),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit().into()
        }
    }
}
