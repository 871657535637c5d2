//! The controller process: waits for plant states, runs the reference generator and the law
//! through the controller crate (the same code path as the in-process simulation), and
//! publishes torque commands — all through `link`'s [`ControllerEndpoint`]. Thin: the
//! mathematics is `controller`'s, the process layer is `link`'s.
//!
//! It follows the plant: the control period and the wake-up mode come from the state
//! messages. The first state's settings are compared with the controller's own (group,
//! period if `--rate-hz` is given, scenario fingerprint); a difference stops both sides.
//! After start-up nothing allocates — not a cycle, not a silence, not the plant's death. It
//! stops when the plant ends the run, when the plant's process is gone, after a silence
//! longer than the timeout, or on SIGINT/SIGTERM.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

use controller::group::{MatrixLieGroup, OnGroup};
use controller::path::{Path, PathReference};
use controller::{Controller, Rejection, RejectionConfig, Source, Trajectory};
use ipc_types::{CommandMsg, PlanInvalid, PlanMsg, StateMsg, check_plan, flags, name_str};
use link::plan::PlanReader;
use link::{
    ControllerEndpoint, ControllerEndpointConfig, Incoming, LinkError, Refusal, StopFlag,
    StopSignal, TransportKind, clock,
};
use scenario::Scenario;
use std::time::{Duration, Instant};

/// A fault to inject, for tests of the plant's own checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// At step k, publish a command with a NaN torque instead of the right one.
    NanTorque(u64),
}

/// Where the desired trajectory comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ReferenceMode {
    /// The scenario's own reference (feedforward series, waypoints or set-point).
    #[default]
    Scenario,
    /// Pieces streamed by a planner process on the run's `plan` service; until the first
    /// arrive, and whenever none covers `t_k`, the last pose given is held.
    Stream,
}

/// How to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// The scenario (law, gains, model inertia, reference).
    pub scenario: Scenario,
    /// Where the reference comes from.
    pub reference: ReferenceMode,
    /// The run name (service names derive from it).
    pub run: String,
    /// The transport.
    pub transport: TransportKind,
    /// A control period to insist on (s); `None`: follow the plant's.
    pub period: Option<f64>,
    /// How long to wait for the first state.
    pub startup_timeout: Duration,
    /// Silence after which the plant counts as gone.
    pub silence_timeout: Duration,
    /// A fault to inject (tests only).
    pub fault: Option<Fault>,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}

/// Why the node stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// The plant announced the end of the run.
    Shutdown,
    /// The plant's process is gone.
    PlantGone,
    /// No state within the silence timeout.
    Silence(Duration),
    /// No first state within the start-up timeout.
    NoPlant(Duration),
    /// SIGINT or SIGTERM.
    Signal(StopSignal),
    /// The plant's settings differ from the controller's (the plant was told).
    Mismatch(Refusal),
}

/// What the node did.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Why it stopped.
    pub stop: Stop,
    /// Commands published.
    pub cycles: u64,
    /// Rejected states per [`ipc_types::Invalid`] kind.
    pub rejected: [u64; 5],
    /// States the law refused (non-finite state), no command published.
    pub refused: u64,
    /// With `--reference stream`: plan messages refused per [`ipc_types::PlanInvalid`] kind
    /// (its discriminant), e.g. for a segment shorter than the control period.
    pub plans_refused: [u64; PlanInvalid::KINDS],
    /// Heap allocations counted between the end of the first cycle and the moment the node
    /// stopped (`None` if fewer than two cycles ran), and the cycles they span.
    pub allocations_after_startup: Option<(u64, u64)>,
}

/// Failures that prevent running.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The scenario cannot build a controller or a reference.
    #[error("scenario `{scenario}`: {source}")]
    Scenario {
        /// Its name.
        scenario: String,
        /// What is wrong.
        source: controller::Error,
    },
    /// The process layer failed.
    #[error(transparent)]
    Link(#[from] LinkError),
}

impl NodeError {
    /// The exit code class.
    pub fn exit(&self) -> link::Exit {
        match self {
            NodeError::Scenario { .. } | NodeError::Link(LinkError::InvalidRunName(_)) => {
                link::Exit::BadInput
            }
            NodeError::Link(_) => link::Exit::Failed,
        }
    }
}

/// Runs the node until it stops. `allocations()` reads the process's allocation counter
/// (the binary installs a counting allocator; pass `|| 0` without one).
pub fn run(opts: &Options, allocations: &dyn Fn() -> u64) -> Result<Report, NodeError> {
    opts.scenario.group.dispatch(Node { opts, allocations })
}

struct Node<'a> {
    opts: &'a Options,
    allocations: &'a dyn Fn() -> u64,
}

impl OnGroup for Node<'_> {
    type Output = Result<Report, NodeError>;
    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        run_group::<G, N, M>(self.opts, self.allocations)
    }
}

/// One controller cycle without IPC: steps the reference up to the state's k (normally it is
/// there already), runs the law through the controller crate (finite-state check,
/// saturation) with the state's configuration and body velocity, and fills the command.
/// Allocation-free; generic over the scalar so the same cycle can be measured in f32, and
/// over the reference source. The state must have passed `ipc_types::check_state` (its
/// sequence number jumps by at most `MAX_SEQ_JUMP`, which bounds the catching up). The plain
/// law only: with disturbance-rejection terms, see [`Responder`].
pub fn respond<T, G, R, const N: usize, const M: usize>(
    controller: &Controller<T, G, N, M>,
    reference: &mut R,
    msg: &StateMsg,
) -> Result<CommandMsg, controller::Error>
where
    T: controller::Real,
    G: MatrixLieGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    let (q, v) = catch_up(reference, msg);
    let out = controller.compute(&q, &v, &reference.desired())?;
    Ok(command::<T, G, N, M>(
        msg.seq,
        &out,
        controller.config().law,
    ))
}

/// Steps `reference` to the state's k and reads the state in the scalar `T`.
fn catch_up<T, R, const N: usize, const M: usize>(
    reference: &mut R,
    msg: &StateMsg,
) -> (nalgebra::SMatrix<T, N, N>, nalgebra::SVector<T, M>)
where
    T: controller::Real,
    R: Trajectory<T, N, M>,
{
    while reference.step_index() < msg.seq {
        reference.advance();
    }
    (
        msg.configuration::<N>().map(controller::real::<T>),
        msg.velocity::<M>().map(controller::real::<T>),
    )
}

/// A scalar as `f64` (NaN if it cannot be converted).
fn to_f64<T: controller::Real>(x: T) -> f64 {
    nalgebra::try_convert::<T, f64>(x).unwrap_or(f64::NAN)
}

/// The command for state `seq` from the law's output, naming the law that computed it.
fn command<T, G, const N: usize, const M: usize>(
    seq: u64,
    out: &controller::LawOutput<T, N, M>,
    law: controller::Law,
) -> CommandMsg
where
    T: controller::Real,
    G: MatrixLieGroup<N, M>,
{
    let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
    cmd.seq = seq;
    cmd.law = link::wire::law_code(law);
    cmd.set_torque(&out.torque.map(to_f64::<T>));
    cmd.lyapunov = to_f64(out.lyapunov.total);
    for i in 0..M.min(ipc_types::MAX_M) {
        cmd.observer[i] = to_f64(out.observer[i]);
        cmd.integral[i] = to_f64(out.integral[i]);
    }
    cmd
}

/// The controller's cycle with its state between cycles: the law, the disturbance-rejection
/// terms (docs/maths.md, "Disturbance rejection") fed with the torque each state says the
/// plant applied, and the sequence number of the last state processed. The node and
/// `plant_sim replay` answer states through it, so replay repeats the node bit for bit.
#[derive(Debug, Clone)]
pub struct Responder<T: controller::Real, G, const N: usize, const M: usize> {
    controller: Controller<T, G, N, M>,
    rejection: Option<Rejection<T, M>>,
    previous: Option<u64>,
}

impl<T, G, const N: usize, const M: usize> Responder<T, G, N, M>
where
    T: controller::Real,
    G: MatrixLieGroup<N, M>,
{
    /// A responder with the terms of `rejection` (none: the plain law).
    pub fn new(
        controller: Controller<T, G, N, M>,
        rejection: RejectionConfig<T, M>,
    ) -> Result<Self, controller::Error> {
        let rejection = if rejection.any() {
            Some(Rejection::new(
                rejection,
                controller.config().torque_limit.as_ref(),
            )?)
        } else {
            None
        };
        Ok(Responder {
            controller,
            rejection,
            previous: None,
        })
    }

    /// The controller.
    pub fn controller(&self) -> &Controller<T, G, N, M> {
        &self.controller
    }

    /// The disturbance-rejection terms' state, if any run.
    pub fn rejection(&self) -> Option<&Rejection<T, M>> {
        self.rejection.as_ref()
    }

    /// Answers state `msg` (see [`respond`]). The terms update only when the state follows
    /// the last one processed (`seq = previous + 1`); after a gap they re-anchor. The command
    /// carries the estimate, the integral's torque and the previous sequence number.
    pub fn respond<R: Trajectory<T, N, M>>(
        &mut self,
        reference: &mut R,
        msg: &StateMsg,
    ) -> Result<CommandMsg, controller::Error> {
        let (q, v) = catch_up(reference, msg);
        let desired = reference.desired();
        let before = self
            .rejection
            .as_ref()
            .map(|r| (*r.estimate(), *r.integral_state()));
        let out = match &mut self.rejection {
            None => self.controller.compute(&q, &v, &desired)?,
            Some(r) => {
                let applied = msg.applied_torque::<M>().map(controller::real::<T>);
                let follows = self
                    .previous
                    .is_some_and(|p| p.checked_add(1) == Some(msg.seq));
                self.controller.compute_rejecting(
                    r,
                    &q,
                    &v,
                    &desired,
                    &applied,
                    controller::real(msg.control_period),
                    follows,
                )?
            }
        };
        let mut cmd = command::<T, G, N, M>(msg.seq, &out, self.controller.config().law);
        cmd.previous_seq = self.previous.unwrap_or(ipc_types::NO_PREVIOUS);
        if let Some((estimate, z)) = before {
            for i in 0..M.min(ipc_types::MAX_M) {
                cmd.estimate_before[i] = to_f64(estimate[i]);
                cmd.z_before[i] = to_f64(z[i]);
            }
        }
        self.previous = Some(msg.seq);
        Ok(cmd)
    }

    /// Restores the state this responder had before it answered the recorded command `cmd`
    /// (replay): the terms from the command's `estimate_before` and `z_before`, their anchor
    /// from `previous` (the recorded state `cmd.previous_seq`; `None` if there is none or it
    /// is not in the record), and the previous sequence number. Without terms it only sets
    /// the sequence number.
    pub fn restore(&mut self, cmd: &CommandMsg, previous: Option<&StateMsg>) {
        self.previous = (cmd.previous_seq != ipc_types::NO_PREVIOUS).then_some(cmd.previous_seq);
        if let Some(r) = &mut self.rejection {
            let from = |xs: &[f64; ipc_types::MAX_M]| {
                nalgebra::SVector::<T, M>::from_fn(|i, _| controller::real::<T>(xs[i]))
            };
            let anchor = previous.map(|p| {
                (
                    p.configuration::<N>().map(controller::real::<T>),
                    p.velocity::<M>().map(controller::real::<T>),
                )
            });
            self.controller.restore_rejection(
                r,
                &from(&cmd.estimate_before),
                &from(&cmd.z_before),
                anchor.as_ref().map(|(q, v)| (q, v)),
            );
        }
    }
}

/// Logs without allocating (the arguments are formatted straight into stderr).
fn log(msg: std::fmt::Arguments) {
    eprintln!("controller_node: {msg}");
}

/// The loop's state between cycles.
struct Cycles<'a, G: MatrixLieGroup<N, M>, const N: usize, const M: usize> {
    opts: &'a Options,
    responder: Responder<f64, G, N, M>,
    reference: Option<Source<f64, G, N, M>>,
    /// With `--reference stream`: the plan board and what came from it.
    stream: Option<Stream>,
    cycles: u64,
    refused: u64,
    /// Allocations counted at the end of the first cycle.
    baseline: Option<u64>,
}

impl<G: MatrixLieGroup<N, M>, const N: usize, const M: usize> Cycles<'_, G, N, M> {
    /// Answers one state; advances the reference to the next tick.
    fn answer(
        &mut self,
        ep: &mut ControllerEndpoint,
        msg: &StateMsg,
        received: u64,
        allocations: &dyn Fn() -> u64,
    ) -> Result<(), NodeError> {
        let reference = match &mut self.reference {
            Some(r) => r,
            None => {
                let r = self.reference.insert(first_reference(self.opts, msg)?);
                if let (Some(stream), Source::Path(p)) = (&mut self.stream, &mut *r) {
                    stream.pull(p);
                }
                r
            }
        };
        match self.responder.respond(reference, msg) {
            Ok(mut cmd) => {
                cmd.state_received_ns = received;
                if let Some(stream) = &self.stream {
                    stream.intake.stamp(&mut cmd);
                }
                if let Some(a) = self.baseline {
                    cmd.heap_allocations = allocations().saturating_sub(a);
                }
                if self.opts.fault == Some(Fault::NanTorque(msg.seq)) {
                    cmd.tau[0] = f64::NAN;
                    log(format_args!(
                        "fault injection: publishing a NaN torque for seq {}",
                        msg.seq
                    ));
                }
                cmd.compute_ns = clock::monotonic_ns().saturating_sub(received);
                ep.publish(&cmd)?;
                self.cycles += 1;
            }
            Err(e) => {
                self.refused += 1;
                if self.refused == 1 {
                    log(format_args!(
                        "law refused state seq {}: {e}; no torque published",
                        msg.seq
                    ));
                }
            }
        }
        if let (Some(stream), Source::Path(p)) = (&mut self.stream, &mut *reference) {
            // after the command is out, so reading the plan adds nothing to the round trip
            stream.pull(p);
            p.advance();
            stream.watch(p);
        } else {
            reference.advance();
        }
        if self.cycles == 1 && self.baseline.is_none() {
            self.baseline = Some(allocations());
        }
        Ok(())
    }
}

/// The reference, built on the first state with the plant's control period.
fn first_reference<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    opts: &Options,
    msg: &StateMsg,
) -> Result<Source<f64, G, N, M>, NodeError> {
    let mut s = opts.scenario.clone();
    s.control_period = msg.control_period;
    log(format_args!(
        "plant found: period {} s, {} wake-up, scenario `{}`; first state seq {}",
        msg.control_period,
        if msg.flags & ipc_types::flags::WAKE_EVENT != 0 {
            "event"
        } else {
            "busy-poll"
        },
        name_str(&msg.scenario),
        msg.seq
    ));
    let bad = |source| NodeError::Scenario {
        scenario: s.name.clone(),
        source,
    };
    if opts.reference == ReferenceMode::Scenario {
        return s.reference_source::<G, N, M>().map_err(bad);
    }
    log(format_args!(
        "reference: streamed on `eqtrack/{}/plan`; holding the scenario's initial reference pose until a planner's pieces arrive",
        opts.run
    ));
    streamed_reference(&s).map_err(bad)
}

/// The reference a streamed run starts from (docs/maths.md, "Streamed pieces"): a path that
/// holds, at rest, the pose the scenario's own reference starts from, at the scenario's
/// control period, until plan messages append pieces ([`PlanIntake::take`]). The node and
/// `plant_sim replay` start from it.
pub fn streamed_reference<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
) -> Result<Source<f64, G, N, M>, controller::Error> {
    let start = s.reference_source::<G, N, M>()?.desired().q;
    let held = PathReference::new(
        Path::hold(start)?,
        nalgebra::SMatrix::from_row_slice(&s.model_inertia),
        s.control_period,
    )?;
    Ok(Source::Path(held))
}

/// What a streamed reference has taken from the plan board: the pieces appended so far and
/// the messages taken. The node and `plant_sim replay` append pieces through it, so replay
/// repeats the node's path bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanIntake {
    /// The end time of the last segment appended (pieces that start earlier are old).
    high_water: f64,
    /// Plan messages taken (accepted or refused).
    pub received: u32,
    /// `(planner pid, seq)` of the last message taken (`(0, 0)`: none).
    pub last: (u32, u64),
}

impl Default for PlanIntake {
    fn default() -> Self {
        PlanIntake {
            high_water: f64::NEG_INFINITY,
            received: 0,
            last: (0, 0),
        }
    }
}

impl PlanIntake {
    /// Takes plan message `msg`: checks it ([`check_plan`] at the reference's period) and
    /// appends its pieces that start no earlier than the last piece appended ends and end no
    /// earlier than the reference's time. Allocation-free.
    pub fn take<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        msg: &PlanMsg,
        reference: &mut PathReference<f64, G, N, M>,
    ) -> Result<(), PlanInvalid> {
        self.received = self.received.wrapping_add(1);
        self.last = (msg.planner_pid, msg.seq);
        check_plan(msg, link::wire::wire_group(G::KIND), reference.period())?;
        let now = reference.time();
        for w in msg.used() {
            let seg = link::wire::segment::<N, M>(w);
            if seg.t0 < self.high_water || seg.t1 < now {
                continue;
            }
            if reference.path_mut().push(seg).is_err() {
                // full: the planner republishes the window as time moves on
                break;
            }
            self.high_water = seg.t1;
        }
        Ok(())
    }

    /// Writes what was taken into a command ([`flags::STREAMED`], `plans_received`,
    /// `plan_seq`, `plan_pid`).
    pub fn stamp(&self, cmd: &mut CommandMsg) {
        cmd.flags |= flags::STREAMED;
        cmd.plans_received = self.received;
        (cmd.plan_pid, cmd.plan_seq) = self.last;
    }
}

/// The streamed reference's bookkeeping: which pieces the path has, and whether it ran dry.
struct Stream {
    reader: PlanReader,
    /// The pieces and messages taken.
    intake: PlanIntake,
    /// No piece covers `t_k` or lies ahead of it (at the start: none came yet).
    dry: bool,
    /// Whether any piece has come.
    started: bool,
    /// Plan messages refused, per [`ipc_types::PlanInvalid`] kind (its discriminant) (each kind logged once).
    rejected: [u64; PlanInvalid::KINDS],
}

impl Stream {
    fn open(run: &str) -> Result<Stream, NodeError> {
        Ok(Stream {
            reader: PlanReader::open(run)?,
            intake: PlanIntake::default(),
            dry: true,
            started: false,
            rejected: [0; PlanInvalid::KINDS],
        })
    }

    /// Appends the new pieces of every unseen plan message: those that start no earlier
    /// than the last piece appended ends and end no earlier than now. Allocation-free.
    fn pull<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        reference: &mut PathReference<f64, G, N, M>,
    ) {
        while let Some(msg) = self.reader.receive() {
            if let Err(kind) = self.intake.take(&msg, reference) {
                let i = kind as usize;
                self.rejected[i] += 1;
                if self.rejected[i] == 1 {
                    // a short leg: say which (its index in the planner's path and its times)
                    let period = reference.period();
                    let which = msg
                        .used()
                        .iter()
                        .enumerate()
                        .find(|(_, w)| kind == PlanInvalid::ShortLeg && w.t1 - w.t0 < period)
                        .map_or(String::new(), |(j, w)| {
                            format!(
                                ": piece {} from t = {} s to t = {} s lasts {:e} s, less than the control period {period} s",
                                msg.first_index as usize + j,
                                w.t0,
                                w.t1,
                                w.t1 - w.t0
                            )
                        });
                    log(format_args!(
                        "refused a plan message from pid {} ({kind}{which}); its pieces are not used. Further refusals of this kind are counted, not logged",
                        msg.planner_pid
                    ));
                }
            }
        }
    }

    /// Logs once when the stream runs dry (the last pose given is held, at rest: every
    /// piece ends at rest) and once when pieces cover `t_k` again.
    fn watch<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &mut self,
        reference: &PathReference<f64, G, N, M>,
    ) {
        let t = reference.time();
        let dry = reference.path().end_time().is_none_or(|end| end < t);
        if dry == self.dry {
            return;
        }
        self.dry = dry;
        if dry {
            log(format_args!(
                "t = {t:.3} s: the stream ran dry (no piece covers t or lies ahead): holding the last pose given, at rest"
            ));
        } else {
            let end = reference.path().end_time().unwrap_or(t);
            log(format_args!(
                "t = {t:.3} s: stream {}: {} pieces, up to t = {end:.3} s",
                if self.started { "resumed" } else { "started" },
                reference.path().segments().count()
            ));
            self.started = true;
        }
    }
}

/// Logs each rejection kind once.
fn log_invalid(ep: &mut ControllerEndpoint) {
    while let Some(r) = ep.next_invalid() {
        let m = &r.msg;
        log(format_args!(
            "rejected state seq {} ({}: version {}, group code {}, period {} s); no torque for it. Further rejections of this kind are counted, not logged",
            m.seq, r.kind, m.version, m.group, m.control_period
        ));
    }
}

fn run_group<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    opts: &Options,
    allocations: &dyn Fn() -> u64,
) -> Result<Report, NodeError> {
    let s = &opts.scenario;
    let responder = s
        .controller::<G, N, M>()
        .and_then(|c| Responder::new(c, s.rejection_config()))
        .map_err(|source| NodeError::Scenario {
            scenario: s.name.clone(),
            source,
        })?;
    let mut ep = ControllerEndpoint::open(ControllerEndpointConfig {
        run: opts.run.clone(),
        transport: opts.transport,
        group: s.group,
        period: opts.period,
        fingerprint: s.fingerprint(),
        scenario: s.name.clone(),
    })?;
    log(format_args!(
        "run `{}`: scenario `{}`, {} on {}, waiting for the plant",
        opts.run,
        s.name,
        s.law.name(),
        s.group.name()
    ));
    let stream = match opts.reference {
        ReferenceMode::Stream => Some(Stream::open(&opts.run)?),
        ReferenceMode::Scenario => None,
    };
    let mut cycles = Cycles {
        opts,
        responder,
        reference: None,
        stream,
        cycles: 0,
        refused: 0,
        baseline: None,
    };
    let started = Instant::now();
    let stop = loop {
        if let Some(sig) = opts.stop.requested() {
            break Stop::Signal(sig);
        }
        match ep.wait_state(Duration::from_millis(20)) {
            Incoming::State(msg, received) => {
                cycles.answer(&mut ep, &msg, received, allocations)?
            }
            Incoming::Shutdown => break Stop::Shutdown,
            Incoming::Mismatch(r) => break Stop::Mismatch(r),
            Incoming::PlantGone => break Stop::PlantGone,
            Incoming::Nothing if !ep.connected() && started.elapsed() > opts.startup_timeout => {
                break Stop::NoPlant(opts.startup_timeout);
            }
            Incoming::Nothing if ep.connected() && ep.silence() > opts.silence_timeout => {
                break Stop::Silence(ep.silence());
            }
            Incoming::Nothing => {}
        }
        log_invalid(&mut ep);
    };
    let allocations_after_startup = cycles
        .baseline
        .filter(|_| cycles.cycles >= 2)
        .map(|a| (allocations().saturating_sub(a), cycles.cycles - 1));
    Ok(Report {
        stop,
        cycles: cycles.cycles,
        rejected: ep.invalid_states(),
        refused: cycles.refused,
        plans_refused: cycles
            .stream
            .as_ref()
            .map_or([0; PlanInvalid::KINDS], |s| s.rejected),
        allocations_after_startup,
    })
}
