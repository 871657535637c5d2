//! `plant_sim run`: the plant process of the pair, written against `link`'s
//! [`PlantEndpoint`] like any plant (docs/architecture.md, "One control cycle").
//!
//! * **lockstep**: the plant publishes state k and waits for command k before integrating
//!   `[t_k, t_{k+1})`; the result equals `plant_sim sim` bit for bit.
//! * **realtime**: tick k+1 comes at `t0 + (k+1)/F` on CLOCK_MONOTONIC
//!   ([`link::clock::sleep_until`]); command k must arrive before it. What is applied is the
//!   [`DeadlinePolicy`]'s decision: the command, the held torque, or the safe-mode torque
//!   (`controller::law::safe_mode_torque`) after `miss_limit` consecutive misses.
//!
//! SIGINT/SIGTERM stop the loop at the next cycle; the cycles that ran are written and the
//! summary says `"interrupted": true` (docs/architecture.md, "Stopping a run").

use crate::SimError;
use crate::output::{Summary, ensure_dir, write_json, write_trajectory_csv};
use crate::plot::trajectory_figure;
use crate::recorder::{Header, Record, Recorder, RecordingReport};
use crate::spawn::Spawned;
use crate::trajectory::{Row, SimulatedTrajectory, input};
use controller::Trajectory as _;
use controller::group::{MatrixLieGroup, OnGroup};
use controller::law::{safe_mode_torque, saturate};
use hdrhistogram::Histogram;
use ipc_types::StateMsg;
use link::wire::group_code;
use link::{
    Command, DeadlinePolicy, Decision, NoCommand, PlantEndpoint, PlantEndpointConfig, StopFlag,
    Transition, TransportKind, Wake, clock,
};
use nalgebra::SVector;
use scenario::Scenario;
use scenario::cli::ScenarioSource;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The summary's note on a lockstep run's deadline figures.
pub const LOCKSTEP_NOTE: &str = "lockstep: the plant waits for every command, so deadline misses, late commands and safe mode do not apply (none are counted)";

/// How the plant's clock runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Wait for each command; exact.
    Lockstep,
    /// Step on the wall clock.
    Realtime,
}

/// A corrupted state to publish instead of the real one (tests of the controller's checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateFault {
    /// Wrong protocol version.
    Version,
    /// Wrong group code.
    Group,
    /// A NaN in the velocity.
    Nan,
}

/// Everything `plant_sim run` needs.
#[derive(Debug, Clone)]
pub struct PairOptions {
    /// The scenario.
    pub scenario: Scenario,
    /// Where the scenario came from: the spawned `controller_node` loads the same, and the
    /// flight recording keeps a copy of it.
    pub source: ScenarioSource,
    /// Lockstep or real time.
    pub mode: Mode,
    /// Real-time rate (Hz); the control period becomes 1/F.
    pub rate_hz: f64,
    /// Busy polling or events.
    pub wake: Wake,
    /// iceoryx2, or the Unix-socket baseline.
    pub transport: TransportKind,
    /// Spawn `controller_node` (else wait for one started by hand).
    pub spawn: bool,
    /// Run name.
    pub run: String,
    /// Output directory.
    pub out: PathBuf,
    /// Consecutive deadline misses that start safe mode.
    pub miss_limit: u32,
    /// Record every cycle in `messages.log` (the flight recorder, [`crate::recorder`]) and
    /// publish the live status the monitor shows.
    pub record: bool,
    /// The calling thread's heap allocations so far (the binary's counting allocator; `None`
    /// without one). The loop's count is in the summary.
    pub thread_allocations: Option<fn() -> u64>,
    /// Keep every Nth cycle in trajectory.csv (and the last): long runs at a high rate
    /// otherwise hold every row in memory (1 = every cycle).
    pub record_every: u64,
    /// Real-time settings of the plant process (applied after the controller is spawned,
    /// which therefore does not inherit them).
    pub rt: link::rt::RtSettings,
    /// Real-time settings passed to the spawned controller (`plant_sim run` gives it the
    /// plant's priority and memory locking, and `--controller-cpu`, else the plant's CPUs).
    pub controller_rt: link::rt::RtSettings,
    /// Lockstep: how long to wait for a command.
    pub lockstep_timeout: Duration,
    /// How long to wait for the controller to appear.
    pub connect_timeout: Duration,
    /// Test only: corrupted states instead of the real ones at these steps.
    pub state_faults: Vec<(u64, StateFault)>,
    /// Test only: the spawned controller publishes a NaN torque instead of command k.
    pub controller_fault_nan_torque: Option<u64>,
    /// Test only: faults planted in the sensors' samples at these ticks.
    pub sample_faults: Vec<(u64, crate::sensors::SampleFault)>,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}

/// Percentiles of a latency histogram, in microseconds.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Percentiles {
    /// Samples.
    pub count: u64,
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p99_9_us: f64,
    /// Maximum.
    pub max_us: f64,
}

impl Percentiles {
    fn of(h: &Histogram<u64>) -> Percentiles {
        let us = |ns: u64| ns as f64 / 1000.0;
        Percentiles {
            count: h.len(),
            p50_us: us(h.value_at_quantile(0.5)),
            p99_us: us(h.value_at_quantile(0.99)),
            p99_9_us: us(h.value_at_quantile(0.999)),
            max_us: us(h.max()),
        }
    }
}

/// `summary.json` of `plant_sim run`: the simulation summary plus the loop's figures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PairSummary {
    /// As `plant_sim sim`.
    #[serde(flatten)]
    pub sim: Summary,
    /// `lockstep` or `realtime`.
    pub mode: String,
    /// `spin` or `event`.
    pub wake: String,
    /// Run name.
    pub run: String,
    /// Real time: the rate (Hz).
    pub rate_hz: Option<f64>,
    /// Control cycles run.
    pub cycles: u64,
    /// trajectory.csv keeps every Nth cycle (and the last).
    pub record_every: u64,
    /// Whether SIGINT/SIGTERM stopped the run before its end.
    pub interrupted: bool,
    /// The signal that stopped it (`SIGINT`, `SIGTERM`).
    pub signal: Option<String>,
    /// Round trip: state published → command received (excludes the connection cycle).
    pub latency: Percentiles,
    /// The round trip's first leg: state published → received by the controller (its
    /// wake-up and read; the clock is the machine's one CLOCK_MONOTONIC).
    pub leg_to_controller: Percentiles,
    /// The controller's compute time (state received → command published).
    pub controller_compute: Percentiles,
    /// The round trip's last leg: command published → received by the plant.
    pub leg_to_plant: Percentiles,
    /// Real time: how late the plant woke for its ticks (scheduling). A tick more than a
    /// period late makes the controller's command for it arrive too late by construction.
    pub tick_lateness: Option<Percentiles>,
    /// Commands that missed their deadline (real time).
    pub deadline_misses: u64,
    /// Times safe mode was entered.
    pub safe_mode_entries: u64,
    /// Cycles spent in safe mode.
    pub safe_mode_cycles: u64,
    /// Commands rejected by the plant's checks (never applied).
    pub commands_rejected: u64,
    /// Commands that arrived after their deadline (ignored).
    pub late_commands: u64,
    /// Lockstep: why the deadline figures above are zero (the plant waits for every
    /// command: deadlines, late commands and safe mode do not apply). Absent in real time.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deadline_note: Option<String>,
    /// Exit status of the spawned controller (`None`: not spawned or killed).
    pub controller_exit: Option<i32>,
    /// `iceoryx2` or `uds`.
    pub transport: String,
    /// Heap allocations the controller reported making after its first cycle (from its last
    /// command).
    pub controller_heap_allocations: Option<u64>,
    /// The real-time settings of both processes: applied, refused (with the OS's reason),
    /// and the CPUs and scheduler read back.
    pub realtime: Realtime,
    /// The flight recording (`None`: `--no-record`).
    pub recording: Option<RecordingReport>,
    /// Heap allocations made by the plant's loop thread from the end of its first cycle (the
    /// first state published to the connected controller) to the end of the loop (`None`:
    /// not counted).
    pub plant_loop_heap_allocations: Option<u64>,
}

/// What the real-time settings did in each process
/// (docs/architecture.md, "Real-time settings").
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct Realtime {
    /// The plant's own report.
    pub plant: link::rt::RtReport,
    /// The report of the controller `plant_sim run` started (`controller_node --rt-report`),
    /// read when it answered; `None` for a controller started by hand (`--no-spawn`), whose
    /// settings only it knows.
    pub controller: Option<link::rt::RtReport>,
}

fn log(msg: std::fmt::Arguments) {
    eprintln!("plant_sim: {msg}");
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
    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        run_group::<G, N, M>(self.0)
    }
}

/// The loop's figures.
struct Stats {
    latency: Histogram<u64>,
    to_controller: Histogram<u64>,
    to_plant: Histogram<u64>,
    compute: Histogram<u64>,
    lateness: Histogram<u64>,
    last_allocations: Option<u64>,
}

impl Stats {
    fn new() -> Result<Stats, SimError> {
        let h = Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3)
            .map_err(|e| SimError::Run(e.to_string()))?;
        Ok(Stats {
            latency: h.clone(),
            to_controller: h.clone(),
            to_plant: h.clone(),
            compute: h.clone(),
            lateness: h,
            last_allocations: None,
        })
    }

    fn command(&mut self, c: &Command, published: u64, first: bool) {
        if !first {
            let _ = self
                .latency
                .record(c.received_ns.saturating_sub(published).max(1));
            let _ = self
                .to_controller
                .record(c.msg.state_received_ns.saturating_sub(published).max(1));
            let _ = self
                .to_plant
                .record(c.received_ns.saturating_sub(c.msg.stamp_ns).max(1));
        }
        let _ = self.compute.record(c.msg.compute_ns.max(1));
        self.last_allocations = Some(c.msg.heap_allocations);
    }
}

/// The plant side of one run: body, scenario, endpoint, policy and records.
struct PlantRun<'a, G: MatrixLieGroup<N, M>, const N: usize, const M: usize> {
    opts: &'a PairOptions,
    s: Scenario,
    steps: u64,
    period_ns: u64,
    plant: controller::integrator::RigidBody<f64, G, N, M>,
    reference: controller::Source<f64, G, N, M>,
    cfg: controller::ControllerConfig<f64, N, M>,
    ep: PlantEndpoint,
    policy: DeadlinePolicy,
    stats: Stats,
    rows: Vec<Row>,
    status: Vec<u8>,
    /// Cycles run (rows are kept every `record_every`).
    cycles: u64,
    tau: SVector<f64, M>,
    /// The disturbance-rejection terms of the last fresh command (`None`: the scenario has
    /// none).
    terms: Option<crate::trajectory::Terms>,
    published: u64,
    /// The state published last (with its stamp).
    state: StateMsg,
    recorder: Option<Recorder>,
    t0: u64,
    /// What the real-time settings did.
    rt: Realtime,
    /// The sensors and the estimator (`None`: the law is handed the exact state).
    estimation: Option<crate::estimation::Estimation>,
    /// The samples and estimate of the state published last.
    estimate: Option<crate::trajectory::EstimateRow>,
    /// The same, with the true state, for the flight recorder.
    sensor_record: Option<crate::recorder::SensorRecord>,
}

fn run_group<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    opts: &PairOptions,
) -> Result<(SimulatedTrajectory, PairSummary), SimError> {
    let mut run = PlantRun::<G, N, M>::new(opts)?;
    ensure_dir(&opts.out)?;
    if opts.record {
        run.start_recorder()?;
    }
    let mut child = Spawned::start(opts)?;
    run.rt.plant = opts.rt.apply();
    for line in run.rt.plant.lines() {
        log(format_args!("real-time settings: {line}"));
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
    let wall = started.elapsed();
    let (rejected, late) = (run.ep.invalid_commands(), run.ep.late_commands());
    // The run is over: tell the controller, then reap it.
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

impl<'a, G: MatrixLieGroup<N, M>, const N: usize, const M: usize> PlantRun<'a, G, N, M> {
    /// The scenario at the run's period, the body, the reference for the records, the
    /// endpoint.
    fn new(opts: &'a PairOptions) -> Result<Self, SimError> {
        let mut s = opts.scenario.clone();
        let fingerprint = s.fingerprint();
        let steps = match opts.mode {
            Mode::Realtime => {
                s.control_period = 1.0 / opts.rate_hz;
                (s.duration * opts.rate_hz).round() as u64
            }
            Mode::Lockstep => s.steps(),
        };
        let plant = s.plant_body::<G, N, M>().map_err(input(&s))?;
        let reference = s.reference_source::<G, N, M>().map_err(input(&s))?;
        let cfg = s.controller_config::<N, M>();
        let ep = PlantEndpoint::open(PlantEndpointConfig {
            run: opts.run.clone(),
            group: s.group,
            control_period: s.control_period,
            transport: opts.transport,
            wake: opts.wake,
            fingerprint,
            scenario: s.name.clone(),
        })?;
        Ok(PlantRun {
            opts,
            steps,
            period_ns: (s.control_period * 1e9).round() as u64,
            plant,
            reference,
            cfg,
            ep,
            policy: DeadlinePolicy::new(opts.miss_limit),
            stats: Stats::new()?,
            rows: Vec::with_capacity((steps / opts.record_every.max(1)) as usize + 2),
            status: Vec::with_capacity((steps / opts.record_every.max(1)) as usize + 2),
            cycles: 0,
            tau: SVector::zeros(),
            terms: s.rejection_config::<M>().any().then(|| {
                crate::trajectory::Terms::of(&SVector::<f64, M>::zeros(), &SVector::zeros())
            }),
            published: 0,
            state: StateMsg::new(link::wire::wire_group(s.group)),
            recorder: None,
            t0: 0,
            rt: Realtime::default(),
            estimation: crate::estimation::Estimation::new(
                &s,
                s.control_period,
                &opts.sample_faults,
            )?,
            estimate: None,
            sensor_record: None,
            s,
        })
    }

    fn realtime(&self) -> bool {
        self.opts.mode == Mode::Realtime
    }

    /// Copies the scenario into the output directory and starts the flight recorder (its
    /// channel holds half a second of cycles, at least 4096).
    fn start_recorder(&mut self) -> Result<(), SimError> {
        let opts = self.opts;
        opts.source.save("seed", &opts.out)?;
        let header = Header {
            group: group_code(self.s.group),
            control_period: self.s.control_period,
            rate_hz: if self.realtime() { opts.rate_hz } else { 0.0 },
            realtime: self.realtime(),
            event_wake: opts.wake == link::Wake::Event,
            miss_limit: opts.miss_limit,
            fingerprint: opts.scenario.fingerprint(),
            run: opts.run.clone(),
            scenario: self.s.name.clone(),
            law: self.s.law.name().to_owned(),
            plant_pid: std::process::id(),
            sensors: self.estimation.is_some(),
        };
        let capacity = ((0.5 / self.s.control_period) as usize).clamp(4096, 1 << 16);
        let sink = crate::recorder::monitor::status_sink(&opts.run, &header);
        // the plan board, read on the recorder's thread: a controller started with
        // `--reference stream` takes its pieces from it, and replay needs them
        let run = opts.run.clone();
        let plans: crate::recorder::PlanSourceFactory = Box::new(move || {
            match link::plan::PlanReader::for_recorder(&run) {
                Ok(mut r) => Some(Box::new(move || r.receive()) as crate::recorder::PlanSource),
                Err(e) => {
                    log(format_args!(
                        "warning: the flight recorder cannot read the plan board ({e}): a streamed run will not replay"
                    ));
                    None
                }
            }
        });
        self.recorder = Some(Recorder::start(
            &opts.out,
            &header,
            capacity,
            Some(sink),
            Some(plans),
        )?);
        Ok(())
    }

    /// Publishes state k (or the test's corrupted version of it).
    fn publish(&mut self, k: u64) -> Result<(), SimError> {
        let mut msg = self.ep.state_template();
        msg.seq = k;
        msg.t = k as f64 * self.s.control_period;
        // the torque applied over the last period (zero at k = 0): the rejection terms' input
        msg.set_applied(&self.tau);
        match &mut self.estimation {
            None => msg.set_state(self.plant.configuration(), &self.plant.velocity()),
            Some(e) => {
                // the torque held over the last period, as the in-process simulation has it
                let r = G::rotation(self.plant.configuration());
                let held = self.tau + self.s.disturbance_wrench::<M>(k.saturating_sub(1), &r);
                let (q_hat, v_hat, row) = e.measure(k, &self.plant, &held);
                msg.set_state(&q_hat, &v_hat);
                if self.recorder.is_some() {
                    let mut truth = StateMsg::new(link::wire::wire_group(self.s.group));
                    truth.set_state(self.plant.configuration(), &self.plant.velocity());
                    self.sensor_record = Some(row.sensor_record(&truth));
                }
                self.estimate = Some(row);
            }
        }
        if let Some(&(_, fault)) = self.opts.state_faults.iter().find(|(fk, _)| *fk == k) {
            corrupt(&mut msg, fault, self.s.group);
            log(format_args!(
                "fault injection: publishing a corrupted state ({fault:?}) for seq {k}"
            ));
        }
        self.published = self.ep.publish_message(&msg)?;
        msg.stamp_ns = self.published;
        self.state = msg;
        Ok(())
    }

    /// Publishes state 0 and waits for command 0; the clock starts when it arrives.
    fn connect(&mut self, child: &mut Spawned) -> Result<Command, SimError> {
        let opts = self.opts;
        if opts.spawn {
            log(format_args!(
                "run `{}`: started controller_node, waiting for it",
                opts.run
            ));
        } else {
            log(format_args!(
                "run `{}`: waiting up to {:.0} s for a controller (controller_node --name {} ...)",
                opts.run,
                opts.connect_timeout.as_secs_f64(),
                opts.run
            ));
        }
        self.publish(0)?;
        let give_up = Instant::now() + opts.connect_timeout;
        let first = loop {
            match self.ep.wait_command(0, clock::monotonic_ns() + 1_000_000) {
                Ok(c) => break c,
                Err(NoCommand::Refused(r)) => return Err(SimError::Mismatch(Box::new(r))),
                Err(NoCommand::Missed) => {}
            }
            self.log_invalid();
            SimError::check(&opts.stop)?;
            if let Some(status) = child.exited() {
                return Err(SimError::Run(format!(
                    "controller_node exited before the run started ({status})"
                )));
            }
            if Instant::now() > give_up {
                return Err(SimError::Run(format!(
                    "no controller answered on run `{}` within {:.0} s",
                    opts.run,
                    opts.connect_timeout.as_secs_f64()
                )));
            }
        };
        self.t0 = clock::monotonic_ns();
        log(format_args!(
            "controller connected; running {} steps {} ({} wake-up, period {} s)",
            self.steps,
            if self.realtime() {
                "in real time"
            } else {
                "in lockstep"
            },
            self.opts.wake,
            self.s.control_period
        ));
        Ok(first)
    }

    /// Command k in real time: waits for it until the tick's deadline and asks the
    /// [`DeadlinePolicy`] what to apply.
    fn realtime_command(
        &mut self,
        k: u64,
        pending: Option<Command>,
    ) -> Result<(Option<Command>, link::Step, u64), SimError> {
        let deadline = self.t0 + (k + 1) * self.period_ns;
        let got = match pending {
            Some(c) => Some(c),
            None => match self.ep.wait_command(k, deadline) {
                Ok(c) => Some(c),
                Err(NoCommand::Refused(r)) => return Err(SimError::Mismatch(Box::new(r))),
                Err(NoCommand::Missed) => None,
            },
        };
        // the first command arrived before the clock started: it is on time by definition
        let arrival = got.map(|c| link::Arrival {
            at_ns: if k == 0 { deadline } else { c.received_ns },
            ..c.arrival()
        });
        Ok((got, self.policy.step(k, deadline, arrival), deadline))
    }

    /// Command k in lockstep: waits for it (checking the controller and the stop flag). Only
    /// `--lockstep-timeout` ends the wait for lack of a command; a rejected command ends the
    /// run at once, since lockstep applies every command or none (nothing is ever held).
    fn lockstep_command(&mut self, k: u64, child: &mut Spawned) -> Result<Command, SimError> {
        let give_up = Instant::now() + self.opts.lockstep_timeout;
        let rejected = self.ep.invalid_commands();
        loop {
            match self.ep.wait_command(k, clock::monotonic_ns() + 20_000_000) {
                Ok(c) => return Ok(c),
                Err(NoCommand::Refused(r)) => return Err(SimError::Mismatch(Box::new(r))),
                Err(NoCommand::Missed) => {}
            }
            if self.ep.invalid_commands() > rejected {
                let why = self
                    .ep
                    .next_invalid()
                    .map(|r| format!(" (seq {}: {})", r.msg.seq, r.kind))
                    .unwrap_or_default();
                return Err(SimError::Run(format!(
                    "lockstep: the controller's command for step {k} was rejected by the plant's checks{why}; a lockstep run applies every command and holds none, so it stops here"
                )));
            }
            SimError::check(&self.opts.stop)?;
            if let Some(status) = child.exited() {
                return Err(SimError::Run(format!(
                    "controller_node exited during the run, at step {k} ({status})"
                )));
            }
            if Instant::now() > give_up {
                return Err(SimError::Run(format!(
                    "lockstep: no command for step {k} within {:.1} s (--lockstep-timeout)",
                    self.opts.lockstep_timeout.as_secs_f64()
                )));
            }
        }
    }

    /// Tick k: obtain command k, decide, record the row, wait for the tick's end.
    ///
    /// Real time: command k is judged against the wall-clock deadline `t0 + (k+1)·period` by
    /// the [`DeadlinePolicy`]. Lockstep: command k is waited for and applied; no clock is read
    /// and the policy is not consulted (docs/architecture.md, "Lockstep").
    fn cycle(
        &mut self,
        k: u64,
        pending: Option<Command>,
        child: &mut Spawned,
    ) -> Result<(), SimError> {
        let (got, step, deadline) = if self.realtime() {
            self.realtime_command(k, pending)?
        } else {
            let c = match pending {
                Some(c) => c,
                None => self.lockstep_command(k, child)?,
            };
            // the tick's nominal end, t_{k+1} in ns: a lockstep record holds no clock reading
            (Some(c), link::Step::LOCKSTEP, (k + 1) * self.period_ns)
        };
        self.log_invalid();
        if let Some(c) = &got {
            self.stats.command(c, self.published, k == 0);
        }
        let v = self.plant.velocity();
        self.tau = match (step.decision, &got) {
            (Decision::Fresh, Some(c)) => {
                if self.terms.is_some() {
                    self.terms = Some(crate::trajectory::Terms {
                        observer: c.msg.observer,
                        integral: c.msg.integral,
                    });
                }
                c.torque()
            }
            (Decision::Safe, _) => {
                safe_mode_torque(&self.cfg.kd, &v, self.cfg.torque_limit.as_ref())
            }
            _ => self.tau,
        };
        saturate(&mut self.tau, self.cfg.torque_limit.as_ref());
        self.log_transition(k, step.transition, step.misses_in_row);
        self.record(k, step.decision);
        if let Some(rec) = &mut self.recorder {
            let mut applied = [0.0; ipc_types::MAX_M];
            applied[..M].copy_from_slice(self.tau.as_slice());
            rec.push(&Record {
                cycle: k,
                decision: step.decision,
                misses_in_row: step.misses_in_row,
                deadline_ns: deadline,
                applied,
                state: self.state,
                command: got.map(|c| (c.msg, c.received_ns)),
                sensors: self.sensor_record,
            });
        }
        if self.realtime() {
            clock::sleep_until(deadline);
            let _ = self
                .stats
                .lateness
                .record(clock::monotonic_ns().saturating_sub(deadline).max(1));
        }
        self.live_status();
        Ok(())
    }

    /// Integrates `[t_k, t_{k+1})` under the held torque and publishes state k+1.
    fn advance(&mut self, k: u64) -> Result<(), SimError> {
        let applied = self.tau + self.s.disturbance_at::<M>(k);
        let (h, substeps) = (self.s.control_period, self.s.plant_substeps);
        match self.s.world_disturbance::<M>() {
            None => self.plant.advance(&applied, h, substeps),
            Some(w) => self.plant.advance_with_world(&applied, &w, h, substeps),
        }
        self.reference.advance();
        self.publish(k + 1)
    }

    fn record(&mut self, k: u64, decision: Decision) {
        self.cycles += 1;
        if !k.is_multiple_of(self.opts.record_every.max(1)) && k != self.steps {
            return;
        }
        let t = controller::real::<f64>(k as f64) * self.s.control_period;
        self.rows.push(
            Row::new::<G, N, M>(
                t,
                self.plant.configuration(),
                &self.plant.velocity(),
                &self.reference.desired(),
                &self.tau,
                &self.cfg.inertia,
                &self.cfg.k,
            )
            .with_estimate(self.estimate)
            .with_terms(self.terms),
        );
        if self.realtime() {
            self.status.push(decision.code());
        }
    }

    fn log_transition(&self, k: u64, transition: Option<Transition>, in_row: u32) {
        let t = k as f64 * self.s.control_period;
        match transition {
            Some(Transition::EnteredSafe) => log(format_args!(
                "t = {t:.3} s: {in_row} consecutive deadline misses, entering SAFE MODE (damping only, tau = -K_d V)"
            )),
            Some(Transition::LeftSafe) => log(format_args!(
                "t = {t:.3} s: fresh commands are back, leaving safe mode"
            )),
            None => {}
        }
    }

    fn log_invalid(&mut self) {
        while let Some(r) = self.ep.next_invalid() {
            log(format_args!(
                "rejected command seq {} ({}); it is never applied. Further rejections of this kind are counted, not logged",
                r.msg.seq, r.kind
            ));
        }
    }

    /// A status line on a terminal, four times a second.
    fn live_status(&mut self) {
        let every = (0.25 / self.s.control_period).max(1.0) as u64;
        if !self.cycles.is_multiple_of(every) || !std::io::stderr().is_terminal() {
            return;
        }
        if let Some(r) = self.rows.last() {
            eprint!(
                "\r  t = {:8.3} s  L = {:10.4e}  misses {:6}  {}  RTT p50 {:7.1} us  ",
                r.t,
                r.lyapunov,
                self.policy.misses(),
                if self.policy.in_safe_mode() {
                    "SAFE MODE"
                } else {
                    "tracking "
                },
                self.stats.latency.value_at_quantile(0.5) as f64 / 1000.0
            );
        }
    }

    fn live_status_end(&self) {
        if std::io::stderr().is_terminal() {
            eprintln!();
        }
    }

    /// Writes trajectory.csv, summary.json and the figure.
    fn write(
        mut self,
        interrupted: Option<link::StopSignal>,
        controller_exit: Option<i32>,
        rejected: u64,
        late: u64,
        loop_allocations: Option<u64>,
    ) -> Result<(SimulatedTrajectory, PairSummary), SimError> {
        // a failed recording (a full disk) is reported, and the run's results still written
        let recording = match self.recorder.take().map(Recorder::finish) {
            Some(Ok(r)) => Some(r),
            Some(Err(e)) => {
                log(format_args!("warning: the flight recording failed: {e}"));
                None
            }
            None => None,
        };
        if let Some(e) = recording.as_ref().and_then(|r| r.error.as_ref()) {
            log(format_args!(
                "warning: the flight recording stopped early: {e}"
            ));
        }
        if let Some(r) = &recording {
            log(format_args!(
                "flight recording: {} cycles in {}{}",
                r.records,
                r.path,
                if r.dropped > 0 {
                    format!(" ({} records dropped: the disk did not keep up)", r.dropped)
                } else {
                    String::new()
                }
            ));
        }
        let (opts, s) = (self.opts, &self.s);
        let realtime = self.realtime();
        let cycles = self.cycles;
        let estimator = self.estimation.as_ref().map(|e| e.report(&self.rows));
        let traj = SimulatedTrajectory {
            estimator,
            group: s.group,
            // the spacing of the rows kept (the effort sums over them)
            control_period: s.control_period * opts.record_every.max(1) as f64,
            duration: cycles.saturating_sub(1) as f64 * s.control_period,
            rows: self.rows,
            status: self.status,
        };
        let summary = PairSummary {
            sim: Summary::of(&traj, &s.name, s.law.name()),
            mode: if realtime { "realtime" } else { "lockstep" }.to_owned(),
            wake: opts.wake.name().to_owned(),
            run: opts.run.clone(),
            rate_hz: realtime.then_some(opts.rate_hz),
            cycles,
            record_every: opts.record_every.max(1),
            interrupted: interrupted.is_some(),
            signal: interrupted.map(|s| s.name().to_owned()),
            latency: Percentiles::of(&self.stats.latency),
            leg_to_controller: Percentiles::of(&self.stats.to_controller),
            controller_compute: Percentiles::of(&self.stats.compute),
            leg_to_plant: Percentiles::of(&self.stats.to_plant),
            tick_lateness: realtime.then(|| Percentiles::of(&self.stats.lateness)),
            // lockstep never steps the policy: its counters stay 0
            deadline_misses: self.policy.misses(),
            safe_mode_entries: self.policy.safe_entries(),
            safe_mode_cycles: self.policy.safe_cycles(),
            commands_rejected: rejected,
            late_commands: if realtime {
                late + self.policy.late()
            } else {
                0
            },
            deadline_note: (!realtime).then(|| LOCKSTEP_NOTE.to_owned()),
            controller_exit,
            transport: opts.transport.name().to_owned(),
            controller_heap_allocations: self.stats.last_allocations,
            realtime: self.rt.clone(),
            recording,
            plant_loop_heap_allocations: loop_allocations,
        };
        write_trajectory_csv(&traj, &opts.out.join("trajectory.csv"))?;
        write_json(&summary, &opts.out.join("summary.json"))?;
        let title = format!(
            "{} — {} on {}, {} ({}){}",
            s.name,
            s.law.name().to_uppercase(),
            s.group.name().to_uppercase(),
            if realtime {
                format!("real time at {} Hz", opts.rate_hz)
            } else {
                "lockstep".to_owned()
            },
            opts.run,
            if interrupted.is_some() {
                ", interrupted"
            } else {
                ""
            }
        );
        trajectory_figure(&traj, &title, &opts.out.join("figure"))?;
        Ok((traj, summary))
    }
}

/// Corrupts a state as a test asks.
fn corrupt(msg: &mut StateMsg, fault: StateFault, group: controller::GroupKind) {
    match fault {
        StateFault::Version => msg.version += 1,
        StateFault::Group => {
            let other = controller::GroupKind::ALL
                .into_iter()
                .find(|g| *g != group)
                .unwrap_or(group);
            msg.group = group_code(other);
        }
        StateFault::Nan => msg.v[0] = f64::NAN,
    }
}
