//! The controller process: waits for plant states, runs the reference generator and the law
//! through the controller crate (the same code path as the in-process simulation), and
//! publishes torque commands — all through `link`'s [`ControllerEndpoint`]. Thin: the
//! mathematics is `eqtrack-controller`'s, the process layer is `link`'s.
//!
//! It follows the plant: the control period and the wake-up mode come from the state
//! messages. The first state's settings are compared with the controller's own (group,
//! period if `--rate-hz` is given, scenario fingerprint); a difference stops both sides.
//! After start-up nothing allocates — not a cycle, not a silence, not the plant's death. It
//! stops when the plant ends the run, when the plant's process is gone, after a silence
//! longer than the timeout, or on SIGINT/SIGTERM.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use eqtrack_controller::{Source, Trajectory};
use ipc_types::{PlanInvalid, StateMsg, name_str};
use link::{ControllerEndpoint, ControllerEndpointConfig, Incoming, clock};
use std::time::{Duration, Instant};

mod options;
mod stream;

use control_cycle::{Responder, streamed_reference};
pub use options::{Fault, NodeError, Options, ReferenceMode, Report, Stop};
use stream::Stream;

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
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        run_group::<G, N, M>(self.opts, self.allocations)
    }
}

/// Logs without allocating (the arguments are formatted straight into stderr).
fn log(msg: std::fmt::Arguments) {
    link::log_line(format_args!("controller_node: {msg}"));
}

/// The loop's state between cycles.
struct Cycles<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> {
    opts: &'a Options,
    responder: Responder<f64, G, N, M>,
    reference: Option<Source<f64, G, N, M>>,
    /// With `--reference stream`: the plan board and what came from it.
    stream: Option<Stream>,
    cycles: u64,
    refused: u64,
    /// Allocations counted at the end of the first cycle.
    baseline: Option<u64>,
    /// A run with run-time gains: the `params` board (opened at the first such state) and
    /// the gains in force (`None`: the scenario's).
    params: Option<link::params::ParamsReader>,
    tuned: Option<ipc_types::Gains>,
    /// The scenario's fingerprint: only the `params` board of this run is taken.
    fingerprint: u64,
    /// The first state this process answered (a test's planted hang comes only in a process
    /// that started before it).
    first: Option<u64>,
}

/// Why a state of a run with run-time gains gets no answer.
#[derive(Debug)]
enum Untuned {
    /// The `params` board could not be opened.
    Open(link::LinkError),
    /// The board cannot answer this state.
    Board(ipc_types::ParamInvalid),
    /// The gains on the board are refused by the law's checks.
    Gains(eqtrack_controller::Error),
}

/// Why a state gets no answer: the law's refusal, or the run-time gains'.
#[derive(Debug)]
enum Refusal {
    Law(eqtrack_controller::Error),
    Untuned(Untuned),
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Law(e) => write!(f, "{e}"),
            Refusal::Untuned(e) => write!(f, "{e}"),
        }
    }
}

impl std::fmt::Display for Untuned {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Untuned::Open(e) => write!(f, "cannot read the run's params board: {e}"),
            Untuned::Board(e) => write!(f, "{e}"),
            Untuned::Gains(e) => write!(f, "run-time gains refused: {e}"),
        }
    }
}

impl<G: BuiltinGroup<N, M>, const N: usize, const M: usize> Cycles<'_, G, N, M> {
    /// A state of a run with run-time gains: puts the gains the `params` board gives for it
    /// in force (docs/live.md, "Tuning a running pair"). Allocation-free after the board is
    /// open; the gains change only when the board's set for this state differs.
    fn retune(&mut self, msg: &StateMsg) -> Result<(), Untuned> {
        let reader = match &mut self.params {
            Some(r) => r,
            None => self
                .params
                .insert(link::params::ParamsReader::open(&self.opts.run).map_err(Untuned::Open)?),
        };
        let board = reader
            .latest()
            .ok_or(Untuned::Board(ipc_types::ParamInvalid::Version))?;
        let gains = *board
            .gains_for(msg.seq, msg.group, self.fingerprint)
            .map_err(Untuned::Board)?;
        if self.tuned.is_some_and(|t| t == gains) {
            return Ok(());
        }
        self.responder.retune(&gains).map_err(Untuned::Gains)?;
        if self.tuned.is_some() || board.seq > 0 {
            log(format_args!(
                "state seq {}: run-time gains of change {} in force (from cycle {})",
                msg.seq, board.seq, gains.cycle
            ));
        }
        self.tuned = Some(gains);
        Ok(())
    }

    /// Answers one state; advances the reference to the next tick.
    fn answer(
        &mut self,
        ep: &mut ControllerEndpoint,
        msg: &StateMsg,
        received: u64,
        allocations: &dyn Fn() -> u64,
    ) -> Result<(), NodeError> {
        // a run with run-time gains: the gains for this state first
        let tunable = msg.flags & ipc_types::flags::TUNABLE != 0;
        let untuned = if tunable {
            self.retune(msg).err()
        } else {
            None
        };
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
        // no allocation on a refusal either: the reason is formatted only when logged
        let answer = match untuned {
            Some(e) => Err(Refusal::Untuned(e)),
            None => self.responder.respond(reference, msg).map_err(Refusal::Law),
        };
        match answer {
            Ok(mut cmd) => {
                if tunable {
                    cmd.flags |= ipc_types::flags::TUNED;
                }
                cmd.state_received_ns = received;
                if let Some(stream) = &self.stream {
                    stream.intake.stamp(&mut cmd);
                }
                if let Some(a) = self.baseline {
                    cmd.heap_allocations = allocations().saturating_sub(a);
                }
                // the first state at or after k (the controller may skip states), in a
                // process that started before it (the one a watchdog restarts does not hang)
                let first = *self.first.get_or_insert(msg.seq);
                if let Some(Fault::HangAt(k) | Fault::HangWithSideNotifier(k)) = self.opts.fault
                    && msg.seq >= k
                    && first < k
                {
                    log(format_args!("fault injection: the loop hangs at seq {k}"));
                    loop {
                        std::thread::park();
                    }
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
fn first_reference<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
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

/// A notification the service manager did not take: logged, the run goes on (the manager
/// restarts a process whose watchdog pings stop, which is what it is there for).
fn notify(sent: std::io::Result<()>) {
    if let Err(e) = sent {
        log(format_args!("service manager: cannot notify: {e}"));
    }
}

/// [`Fault::HangWithSideNotifier`]: a thread that pings the watchdog whatever the loop does
/// (tests only; the mistake the watchdog tests must catch).
fn side_notifier(fault: Option<Fault>) {
    if let Some(Fault::HangWithSideNotifier(_)) = fault
        && let Ok(mut n) = link::notify::Notifier::from_process()
    {
        log(format_args!(
            "fault injection: a side thread pings the watchdog"
        ));
        std::thread::spawn(move || {
            loop {
                let _ = n.progress(clock::monotonic_ns());
                std::thread::sleep(Duration::from_millis(10));
            }
        });
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

/// The controller's cycle for scenario `s`: the law, its rejection terms, and a vehicle's
/// allocation.
fn responder_for<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &scenario::Scenario,
) -> Result<Responder<f64, G, N, M>, NodeError> {
    let responder = s
        .controller::<G, N, M>()
        .and_then(|c| Responder::new(c, s.rejection_config()))
        .map_err(|source| NodeError::Scenario {
            scenario: s.name.clone(),
            source,
        })?;
    let responder = match control_cycle::Supervisor::of(s) {
        Some(sup) => responder.with_supervisor(sup),
        None => responder,
    };
    Ok(match &s.vehicle {
        None => responder,
        Some(_) => {
            responder.with_vehicle(control_cycle::ControllerVehicle::of(s).map_err(|what| {
                NodeError::Vehicle {
                    scenario: s.name.clone(),
                    what,
                }
            })?)
        }
    })
}

fn run_group<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    opts: &Options,
    allocations: &dyn Fn() -> u64,
) -> Result<Report, NodeError> {
    let s = &opts.scenario;
    let responder = responder_for::<G, N, M>(s)?;
    // a service manager's watchdog (docs/pair-on-a-board.md, "Watchdogs"): pinged from this
    // loop only, once per pass when due
    let mut notifier = link::notify::Notifier::from_process()?;
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
        s.law_label(),
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
        params: None,
        tuned: None,
        fingerprint: s.fingerprint(),
        first: None,
    };
    notify(notifier.ready());
    side_notifier(opts.fault);
    let started = Instant::now();
    let stop = loop {
        notifier.keep_alive(clock::monotonic_ns, |e| {
            log(format_args!(
                "service manager: cannot ping the watchdog: {e}"
            ));
        });
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
    notify(notifier.stopping());
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
