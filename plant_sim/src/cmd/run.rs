//! `plant_sim run`: the plant process of the pair, and the summary it prints.

#[cfg(feature = "fault-injection")]
use super::sample_faults;
use alloc_counter::thread_allocations;
use clap::Args;
use link::{StopFlag, TransportKind, Wake};
use plant::SimError;
use plant::pair::Mode;
use scenario::cli::{ScenarioSource, positive_seconds};
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(Args)]
pub(crate) struct RunArgs {
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
    /// Transport: iceoryx2, uds (the Unix-socket baseline; spawned controllers follow), or
    /// a processor-in-the-loop firmware on a serial link: tcp:HOST:PORT (QEMU's UART) or
    /// serial:PATH[@BAUD] (a board's serial port, default 115200 baud; docs/pil.md).
    #[arg(long, value_name = "T", default_value = "iceoryx2", value_parser = transport_parser)]
    transport: Transport,
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
    /// Let gains change while the run flies: serve the run's parameter service
    /// (`plant_sim param --name RUN get|set KEY VALUE`), write the `params` board the
    /// controller reads, record each change in `params.log`. Off by default. See
    /// docs/live.md, "Tuning a running pair".
    #[arg(long)]
    tunable: bool,
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
    /// Test builds only, serial transports: flip one bit of the Nth frame received from the
    /// firmware (1: its Hello; the command of state k is frame k + 2).
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "N", hide = true)]
    fault_corrupt_frame: Option<u64>,
    /// Test builds only, serial transports: a burst of seeded noise on the line before every
    /// frame sent to the firmware.
    #[cfg(feature = "fault-injection")]
    #[arg(long, value_name = "SEED", hide = true)]
    fault_line_noise: Option<u64>,
}

/// What `--transport` names: a process transport, or a firmware on a serial link.
#[derive(Debug, Clone)]
pub(crate) enum Transport {
    /// iceoryx2 or uds, to a `controller_node`.
    Process(TransportKind),
    /// A processor-in-the-loop firmware.
    Serial(link::serial::SerialTarget),
}

fn transport_parser(text: &str) -> Result<Transport, String> {
    match text {
        "iceoryx2" => Ok(Transport::Process(TransportKind::Iceoryx2)),
        "uds" => Ok(Transport::Process(TransportKind::Uds)),
        _ if text.starts_with("tcp:") || text.starts_with("serial:") => {
            text.parse().map(Transport::Serial)
        }
        _ => Err(format!(
            "`{text}`: expected iceoryx2, uds, tcp:HOST:PORT or serial:PATH[@BAUD]"
        )),
    }
}

/// The serial controller of `--transport tcp:…|serial:…` (`None` for a process transport).
fn serial_controller(args: &RunArgs) -> Option<plant::pair::SerialController> {
    let Transport::Serial(target) = &args.transport else {
        return None;
    };
    #[cfg(feature = "fault-injection")]
    let (corrupt, noise) = (
        args.fault_corrupt_frame.map(link::serial::CorruptCommand),
        args.fault_line_noise.map(link::serial::LineNoise),
    );
    #[cfg(not(feature = "fault-injection"))]
    let (corrupt, noise) = (None, None);
    let target = target.clone();
    Some(plant::pair::SerialController {
        name: match &target {
            link::serial::SerialTarget::Tcp(a) => format!("tcp:{a}"),
            link::serial::SerialTarget::Device(p, b) => format!("serial:{}@{b}", p.display()),
        },
        open: std::sync::Arc::new(move || link::serial::connect(&target)),
        counts: Default::default(),
        corrupt,
        noise,
    })
}

pub(crate) fn run_cmd(args: RunArgs, stop: &StopFlag) -> Result<(), SimError> {
    use plant::pair::{PairOptions, run_pair};
    let mut scenario = args.source.load("seed")?;
    if let Some(d) = args.duration {
        scenario.duration = d.as_secs_f64();
    }
    let state_faults = state_faults(&args)?;
    let serial = serial_controller(&args);
    let spawn = !args.no_spawn && serial.is_none();
    let opts = PairOptions {
        scenario,
        source: args.source.clone(),
        record: !args.no_record,
        thread_allocations: Some(thread_allocations),
        mode: args.mode,
        rate_hz: args.rate_hz,
        wake: args.wake,
        transport: match args.transport {
            Transport::Process(kind) => kind,
            Transport::Serial(_) => TransportKind::Iceoryx2,
        },
        spawn,
        serial: serial.clone(),
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
        tunable: args.tunable,
        stop: stop.clone(),
    };
    plant::trajectory::warn_world_frame(&opts.scenario, opts.scenario.steps());
    let (traj, s) = run_pair(&opts)?;
    print_pair_summary(&s, &opts.scenario.law_label(), &opts.out);

    if let Some(c) = &serial {
        print_serial_counts(c);
    }
    match stop.requested() {
        Some(sig) if s.interrupted => Err(SimError::Interrupted(sig)),
        _ => super::sim::diverged(&traj, &opts.out),
    }
}

/// The `--fault-state K:KIND` injections (test builds only; empty otherwise).
pub(crate) fn state_faults(
    #[allow(unused_variables)] args: &RunArgs,
) -> Result<Vec<(u64, plant::pair::StateFault)>, SimError> {
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
            "version" => plant::pair::StateFault::Version,
            "group" => plant::pair::StateFault::Group,
            "nan" => plant::pair::StateFault::Nan,
            _ => return Err(bad()),
        };
        state_faults.push((k, kind));
    }
    Ok(state_faults)
}

/// Prints a finished (or interrupted) pair run's summary to stdout.
/// `law` names the law as [`scenario::Scenario::law_label`] does.
pub(crate) fn print_pair_summary(s: &plant::pair::PairSummary, law: &str, out: &Path) {
    let f = &s.sim.final_errors;
    println!(
        "run `{}`: scenario {} ({}, law {}), {}, {} cycles, {} wake-up",
        s.run,
        s.sim.scenario,
        s.sim.group,
        law,
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
    let p = |x: &plant::pair::Percentiles| {
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
    for line in s.sim.vehicle.iter().flat_map(|v| v.detection_lines()) {
        println!("{line}");
    }
    if let Some(changes) = &s.parameter_changes {
        println!("parameter changes: {}", changes.len());
        for c in changes {
            println!(
                "  cycle {} (t = {:.3} s): {} = {} (was {})",
                c.cycle, c.t, c.key, c.value, c.previous
            );
        }
    }
    println!(
        "wrote {}/{{trajectory.csv, summary.json, figure.png, figure.svg{}{}}}",
        out.display(),
        if s.recording.is_some() {
            ", messages.log, scenario.toml"
        } else {
            ""
        },
        if s.recording.is_some() && s.parameter_changes.is_some() {
            ", params.log"
        } else {
            ""
        }
    );
}

/// What the serial link counted (processor in the loop).
fn print_serial_counts(c: &plant::pair::SerialController) {
    use std::sync::atomic::Ordering::Relaxed;
    println!(
        "serial link {}: {} commands, {} corrupted frames dropped, {} firmware resets, {} unexpected frames",
        c.name,
        c.counts.commands.load(Relaxed),
        c.counts.corrupt.load(Relaxed),
        c.counts.resets.load(Relaxed),
        c.counts.unexpected.load(Relaxed)
    );
}
