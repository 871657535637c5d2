//! The controller process: waits for plant states, runs the reference generator and the law
//! through the controller crate (the same code path as the in-process simulation), and
//! publishes torque commands. Thin: all mathematics comes from `controller`.
//!
//! It follows the plant: the control period and the wake-up mode (busy polling or iceoryx2
//! events) come from the state messages. Every message is validated (version, group, finite
//! numbers, increasing sequence, period); a rejected one is counted and each kind logged once.
//! After start-up a cycle performs no heap allocation. It exits when the plant says the run is
//! over, when the plant's node is gone, or after a silence longer than the timeout.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use controller::group::{MatrixLieGroup, Se3, So3};
use controller::{Controller, GroupKind, Reference};
use ipc_types::ipc::{ControllerPorts, Link, monotonic_ns, node_alive};
use ipc_types::uds::ControllerUds;
use ipc_types::{CommandMsg, Reject, StateMsg, check_state, flags};
use nalgebra::{SMatrix, SVector};
use scenario::Scenario;
use std::time::{Duration, Instant};

/// A fault to inject, for tests of the plant's own checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// At step k, publish a command with a NaN torque instead of the right one.
    NanTorque(u64),
}

/// How to run.
#[derive(Debug, Clone)]
pub struct Options {
    /// The scenario (law, gains, model inertia, reference).
    pub scenario: Scenario,
    /// The run name (service names derive from it).
    pub run: String,
    /// How long to wait for the first state.
    pub startup_timeout: Duration,
    /// Silence after which the plant counts as gone.
    pub silence_timeout: Duration,
    /// A fault to inject (tests only).
    pub fault: Option<Fault>,
    /// The transport (iceoryx2, or the Unix-socket baseline for benchmarks).
    pub transport: Transport,
}

/// How the two processes exchange messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    /// iceoryx2 shared memory (the product).
    Iceoryx2,
    /// Unix datagram sockets (the benchmark baseline).
    Uds,
}

/// Why the node stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stop {
    /// The plant announced the end of the run.
    Shutdown,
    /// The plant's node is dead or gone.
    PlantGone,
    /// No state within the timeout.
    Silence(Duration),
    /// No first state within the start-up timeout.
    NoPlant(Duration),
}

/// What the node did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Report {
    /// Why it stopped.
    pub stop: Stop,
    /// Commands published.
    pub cycles: u64,
    /// Rejected states per [`Reject`] kind.
    pub rejected: [u64; 5],
    /// States the law refused (non-finite state), no command published.
    pub refused: u64,
    /// Heap allocations counted between the end of the first cycle and the end of the loop
    /// (`None` if fewer than two cycles ran), and the cycles they span.
    pub allocations_after_startup: Option<(u64, u64)>,
}

/// Failures that prevent running.
#[derive(Debug)]
pub enum NodeError {
    /// Bad input (exit code 2).
    Input(String),
    /// IPC set-up or communication failure (exit code 1).
    Ipc(String),
}

impl std::fmt::Display for NodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NodeError::Input(s) | NodeError::Ipc(s) => f.write_str(s),
        }
    }
}

/// Runs the node until it stops. `allocations()` reads the process's allocation counter
/// (the binary installs a counting allocator; pass `|| 0` without one).
pub fn run(opts: &Options, allocations: &dyn Fn() -> u64) -> Result<Report, NodeError> {
    let names = ipc_types::service_names(&opts.run).ok_or_else(|| {
        NodeError::Input(format!(
            "invalid run name `{}` (1-64 of A-Z a-z 0-9 _ -)",
            opts.run
        ))
    })?;
    match opts.transport {
        Transport::Iceoryx2 => {
            let node = ipc_types::ipc::node(&opts.run, "controller").map_err(NodeError::Ipc)?;
            let ports = ControllerPorts::open(&node, &opts.run).map_err(NodeError::Ipc)?;
            dispatch(opts, &ports, Some(names.plant_node.as_str()), allocations)
        }
        Transport::Uds => {
            let link = ControllerUds::open(&opts.run, "controller").map_err(NodeError::Ipc)?;
            dispatch(opts, &link, None, allocations)
        }
    }
}

fn dispatch<L: Link<CommandMsg, StateMsg>>(
    opts: &Options,
    link: &L,
    plant_node: Option<&str>,
    allocations: &dyn Fn() -> u64,
) -> Result<Report, NodeError> {
    match opts.scenario.group {
        GroupKind::So3 => {
            run_group::<So3, L, 3, 3>(opts, ipc_types::group::SO3, link, plant_node, allocations)
        }
        GroupKind::Se3 => {
            run_group::<Se3, L, 4, 6>(opts, ipc_types::group::SE3, link, plant_node, allocations)
        }
    }
}

/// One controller cycle without IPC: steps the reference up to the state's k (normally it is
/// there already), runs the law through the controller crate (finite-state check,
/// saturation) with the state's configuration and body velocity, and fills the command.
/// Allocation-free; generic over the scalar so the same cycle can be measured in f32.
pub fn respond<T, G, const N: usize, const M: usize>(
    controller: &Controller<T, G, N, M>,
    reference: &mut Reference<T, G, N, M>,
    msg: &StateMsg,
    group_code: u32,
) -> Result<CommandMsg, controller::Error>
where
    T: controller::Real,
    G: MatrixLieGroup<N, M>,
{
    while reference.step_index() < msg.seq {
        reference.advance();
    }
    let q = SMatrix::<T, N, N>::from_fn(|i, j| controller::real(msg.q[i * N + j]));
    let v = SVector::<T, M>::from_fn(|i, _| controller::real(msg.v[i]));
    let out = controller.compute(&q, &v, &reference.desired())?;
    let mut cmd = CommandMsg::new(group_code);
    cmd.seq = msg.seq;
    for i in 0..M {
        cmd.tau[i] = nalgebra::try_convert(out.torque[i]).unwrap_or(f64::NAN);
    }
    cmd.lyapunov = nalgebra::try_convert(out.lyapunov.total).unwrap_or(f64::NAN);
    Ok(cmd)
}

fn log(msg: std::fmt::Arguments) {
    eprintln!("controller_node: {msg}");
}

/// Logs each rejection kind once, counts all.
struct Rejections {
    counts: [u64; 5],
}

impl Rejections {
    fn reject(&mut self, kind: Reject, msg: &StateMsg, expected_group: u32, period: Option<f64>) {
        let i = kind.index();
        if self.counts[i] == 0 {
            let detail = match kind {
                Reject::Version => format!(
                    "version {}, expected {}",
                    msg.version,
                    ipc_types::PROTOCOL_VERSION
                ),
                Reject::Group => format!("group code {}, expected {}", msg.group, expected_group),
                Reject::NonFinite => "the state holds NaN or infinity".to_owned(),
                Reject::Sequence => {
                    format!("seq {} does not follow the last accepted one", msg.seq)
                }
                Reject::Period => format!(
                    "period {} s, running with {:?} s",
                    msg.control_period, period
                ),
            };
            log(format_args!(
                "rejected state seq {} ({}: {detail}); no torque for it. Further rejections of this kind are counted, not logged",
                msg.seq,
                kind.name()
            ));
        }
        self.counts[i] += 1;
    }
}

fn run_group<
    G: MatrixLieGroup<N, M>,
    L: Link<CommandMsg, StateMsg>,
    const N: usize,
    const M: usize,
>(
    opts: &Options,
    group_code: u32,
    ports: &L,
    plant_node: Option<&str>,
    allocations: &dyn Fn() -> u64,
) -> Result<Report, NodeError> {
    let s = &opts.scenario;
    let controller = s
        .controller::<G, N, M>()
        .map_err(|e| NodeError::Input(format!("scenario `{}`: {e}", s.name)))?;
    log(format_args!(
        "run `{}`: scenario `{}`, {} on {}, waiting for the plant",
        opts.run,
        s.name,
        s.law.name(),
        s.group.name()
    ));

    let mut reference: Option<Reference<f64, G, N, M>> = None;
    let mut rejections = Rejections { counts: [0; 5] };
    let mut refused = 0u64;
    let mut logged_refusal = false;
    let mut last_seq: Option<u64> = None;
    let mut cycles = 0u64;
    let mut baseline: Option<(u64, u64)> = None; // (allocations, cycles) after the first cycle
    let mut event_mode = false;
    let started = Instant::now();
    let mut last_state = Instant::now();
    let mut last_liveness = Instant::now();
    let mut spins = 0u32;

    let stop = 'outer: loop {
        // 1. Wait for at least one state (busy poll, or the event listener once the plant
        //    has said it notifies).
        let mut latest: Option<StateMsg> = None;
        loop {
            if let Some(msg) = ports.receive() {
                if msg.flags & flags::SHUTDOWN != 0 && msg.version == ipc_types::PROTOCOL_VERSION {
                    break 'outer Stop::Shutdown;
                }
                let period = reference.as_ref().map(|r| r.period());
                let period_ok =
                    msg.control_period > 0.0 && period.is_none_or(|p| p == msg.control_period);
                let checked = check_state(&msg, group_code, last_seq).and(if period_ok {
                    Ok(())
                } else {
                    Err(Reject::Period)
                });
                match checked {
                    Ok(()) => {
                        last_seq = Some(msg.seq);
                        latest = Some(msg);
                    }
                    Err(kind) => rejections.reject(kind, &msg, group_code, period),
                }
            }
            if latest.is_some() {
                break;
            }
            if event_mode {
                ports.wait(Duration::from_millis(20));
            } else if reference.is_none() {
                std::thread::sleep(Duration::from_micros(200));
            } else {
                std::hint::spin_loop();
            }
            spins = spins.wrapping_add(1);
            if event_mode || reference.is_none() || spins.is_multiple_of(1024) {
                let silent = last_state.elapsed();
                if reference.is_none() {
                    if started.elapsed() > opts.startup_timeout {
                        break 'outer Stop::NoPlant(opts.startup_timeout);
                    }
                } else if silent > opts.silence_timeout {
                    break 'outer Stop::Silence(silent);
                } else if silent > Duration::from_millis(100)
                    && last_liveness.elapsed() > Duration::from_millis(100)
                {
                    last_liveness = Instant::now();
                    if plant_node.is_some_and(|n| !node_alive(n)) {
                        break 'outer Stop::PlantGone;
                    }
                }
            }
        }
        let Some(msg) = latest else { continue };
        let received = monotonic_ns();
        last_state = Instant::now();
        event_mode = msg.flags & flags::WAKE_EVENT != 0;

        // 2. The reference at t_k: built on the first state with the plant's period, then
        //    stepped (it is normally already at k: it is advanced right after each command).
        if reference.is_none() {
            let mut sc = s.clone();
            sc.control_period = msg.control_period;
            let r = sc
                .reference_generator::<G, N, M>()
                .map_err(|e| NodeError::Input(format!("scenario `{}`: {e}", s.name)))?;
            log(format_args!(
                "plant found: period {} s, {} wake-up; first state seq {}",
                msg.control_period,
                if event_mode { "event" } else { "busy-poll" },
                msg.seq
            ));
            reference = Some(r);
        }
        let Some(reference) = reference.as_mut() else {
            continue;
        };
        // 3. The law, through the controller crate.
        match respond(&controller, reference, &msg, group_code) {
            Ok(mut cmd) => {
                cmd.state_received_ns = received;
                if let Some((a, _)) = baseline {
                    cmd.heap_allocations = allocations().saturating_sub(a);
                }
                if opts.fault == Some(Fault::NanTorque(msg.seq)) {
                    cmd.tau[0] = f64::NAN;
                    log(format_args!(
                        "fault injection: publishing a NaN torque for seq {}",
                        msg.seq
                    ));
                }
                publish(ports, cmd, received);
                if event_mode {
                    ports.notify();
                }
                cycles += 1;
            }
            Err(e) => {
                refused += 1;
                if !logged_refusal {
                    logged_refusal = true;
                    log(format_args!(
                        "law refused state seq {}: {e}; no torque published",
                        msg.seq
                    ));
                }
            }
        }
        // 4. Advance the reference to t_{k+1} while waiting for the next state.
        reference.advance();
        if cycles == 1 && baseline.is_none() {
            baseline = Some((allocations(), cycles));
        }
    };
    let allocations_after_startup = baseline
        .filter(|_| cycles >= 2)
        .map(|(a, c)| (allocations().saturating_sub(a), cycles - c));
    Ok(Report {
        stop,
        cycles,
        rejected: rejections.counts,
        refused,
        allocations_after_startup,
    })
}

/// Writes a command, with its compute time (state received → now). Allocation-free.
fn publish<L: Link<CommandMsg, StateMsg>>(ports: &L, mut cmd: CommandMsg, received: u64) {
    cmd.compute_ns = monotonic_ns().saturating_sub(received);
    ports.send(cmd);
}
