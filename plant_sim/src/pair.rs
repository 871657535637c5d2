//! `plant_sim run`: the plant process of the pair, talking to `controller_node` over
//! iceoryx2 shared memory (`ipc_types`), in lockstep or against the wall clock.
//!
//! * **lockstep**: the plant publishes state k and waits for command k before integrating
//!   `[t_k, t_{k+1})`; the result equals `plant_sim sim` bit for bit.
//! * **realtime**: tick k+1 comes at `t0 + (k+1)/F` on CLOCK_MONOTONIC (absolute-time
//!   `clock_nanosleep`, then a short spin — never an iceoryx2 timeout; in event mode the wait
//!   for a command is a select(2) on the listener bounded by the tick). Command k must arrive
//!   before tick k+1; otherwise it is a deadline miss and the previous torque is held. After
//!   `miss_limit` consecutive misses the plant enters **safe mode**: damping only,
//!   `τ = −K_d V` (the scenario's K_d, body frame, within the torque limit), which brings the
//!   body to rest instead of tracking; it leaves safe mode at the first fresh command.

use crate::SimError;
use crate::output::{Summary, ensure_dir, write_json, write_trajectory_csv};
use crate::plot::trajectory_figure;
use crate::trajectory::{Row, Trajectory};
use controller::GroupKind;
use controller::group::{MatrixLieGroup, Se3, So3};
use hdrhistogram::Histogram;
use ipc_types::ipc::{Link, PlantPorts, monotonic_ns, node_alive};
use ipc_types::uds::PlantUds;
use ipc_types::{CommandMsg, Reject, StateMsg, check_command, flags};
use nalgebra::{SMatrix, SVector};
use scenario::Scenario;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// How the plant's clock runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Wait for each command; exact.
    Lockstep,
    /// Step on the wall clock.
    Realtime,
}

/// How each side waits for the other's message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// Busy polling: lowest latency, a core per waiting process.
    Spin,
    /// iceoryx2 events: the waiting process sleeps.
    Event,
}

/// How the two processes exchange messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    /// iceoryx2 shared memory (the product).
    Iceoryx2,
    /// Unix datagram sockets (the benchmark baseline).
    Uds,
}

impl Transport {
    /// `iceoryx2` or `uds`.
    pub fn name(self) -> &'static str {
        match self {
            Transport::Iceoryx2 => "iceoryx2",
            Transport::Uds => "uds",
        }
    }
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
    /// Arguments that make `controller_node` load the same scenario.
    pub scenario_args: Vec<String>,
    /// Lockstep or real time.
    pub mode: Mode,
    /// Real-time rate (Hz); the control period becomes 1/F.
    pub rate_hz: f64,
    /// Busy polling or events.
    pub wake: Wake,
    /// iceoryx2, or the Unix-socket baseline.
    pub transport: Transport,
    /// Spawn `controller_node` (else wait for one started by hand).
    pub spawn: bool,
    /// Run name.
    pub run: String,
    /// Output directory.
    pub out: PathBuf,
    /// Consecutive deadline misses that start safe mode.
    pub miss_limit: u32,
    /// Lockstep: how long to wait for a command.
    pub lockstep_timeout: Duration,
    /// How long to wait for the controller to appear.
    pub connect_timeout: Duration,
    /// Test only: corrupted states instead of the real ones at these steps.
    pub state_faults: Vec<(u64, StateFault)>,
    /// Test only: the spawned controller publishes a NaN torque instead of command k.
    pub controller_fault_nan_torque: Option<u64>,
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
    /// Control cycles (rows).
    pub cycles: u64,
    /// Round trip: state published → command received (excludes the connection cycle).
    pub latency: Percentiles,
    /// The controller's compute time (state received → command published).
    pub controller_compute: Percentiles,
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
    /// Exit status of the spawned controller (`None`: not spawned or killed).
    pub controller_exit: Option<i32>,
    /// `iceoryx2` or `uds`.
    pub transport: String,
    /// Heap allocations the controller reported making after its first cycle (from its last
    /// command).
    pub controller_heap_allocations: Option<u64>,
}

fn log(msg: std::fmt::Arguments) {
    eprintln!("plant_sim: {msg}");
}

/// The spawned controller; killed and reaped on drop, so no zombie outlives the plant.
struct Spawned(Option<Child>);

impl Spawned {
    fn exited(&mut self) -> Option<std::process::ExitStatus> {
        self.0.as_mut().and_then(|c| c.try_wait().ok().flatten())
    }

    fn finish(&mut self, grace: Duration) -> Option<i32> {
        let mut child = self.0.take()?;
        let until = Instant::now() + grace;
        loop {
            if let Ok(Some(status)) = child.try_wait() {
                return status.code();
            }
            if Instant::now() > until {
                let _ = child.kill();
                let _ = child.wait();
                log(format_args!(
                    "controller_node did not exit within {grace:?}; killed"
                ));
                return None;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for Spawned {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Sleeps until `deadline` (CLOCK_MONOTONIC ns): absolute-time sleep to 40 µs before it, then
/// spin.
pub fn sleep_until(deadline: u64) {
    const SPIN_NS: u64 = 40_000;
    if deadline > SPIN_NS {
        let early = deadline - SPIN_NS;
        if monotonic_ns() < early {
            let ts = nix::sys::time::TimeSpec::new(
                (early / 1_000_000_000) as i64,
                (early % 1_000_000_000) as i64,
            );
            let _ = nix::time::clock_nanosleep(
                nix::time::ClockId::CLOCK_MONOTONIC,
                nix::time::ClockNanosleepFlags::TIMER_ABSTIME,
                &ts,
            );
        }
    }
    while monotonic_ns() < deadline {
        std::hint::spin_loop();
    }
}

/// Runs the pair; returns the trajectory and the summary (also written to `out`).
pub fn run_pair(opts: &PairOptions) -> Result<(Trajectory, PairSummary), SimError> {
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
    if ipc_types::service_names(&opts.run).is_none() {
        return Err(SimError::Input(format!(
            "--name: invalid run name `{}` (1-64 of A-Z a-z 0-9 _ -)",
            opts.run
        )));
    }
    let setup = |e: String| SimError::Run(format!("IPC set-up failed: {e}"));
    match opts.transport {
        Transport::Iceoryx2 => {
            let names = ipc_types::service_names(&opts.run)
                .ok_or_else(|| SimError::Input("bad run name".to_owned()))?;
            if node_alive(&names.plant_node) {
                return Err(SimError::Input(format!(
                    "a plant for run `{}` is already running: choose another --name",
                    opts.run
                )));
            }
            let node = ipc_types::ipc::node(&opts.run, "plant").map_err(setup)?;
            let ports = PlantPorts::open(&node, &opts.run).map_err(setup)?;
            dispatch(opts, &ports)
        }
        Transport::Uds => {
            let link = PlantUds::open(&opts.run, "plant").map_err(setup)?;
            dispatch(opts, &link)
        }
    }
}

fn dispatch<L: Link<StateMsg, CommandMsg>>(
    opts: &PairOptions,
    link: &L,
) -> Result<(Trajectory, PairSummary), SimError> {
    match opts.scenario.group {
        GroupKind::So3 => run_group::<So3, L, 3, 3>(opts, ipc_types::group::SO3, link),
        GroupKind::Se3 => run_group::<Se3, L, 4, 6>(opts, ipc_types::group::SE3, link),
    }
}

struct Waiter<'a, L> {
    ports: &'a L,
    group: u32,
    wake: Wake,
    rejected: u64,
    logged: [bool; 5],
    late: u64,
}

enum Got {
    Command(CommandMsg, u64),
    Deadline,
}

impl<L: Link<StateMsg, CommandMsg>> Waiter<'_, L> {
    /// Waits for command `k` until `deadline` (ns; `None`: until `give_up`), calling `idle`
    /// now and then (for liveness checks); `Err` when `give_up` passes.
    fn wait(
        &mut self,
        k: u64,
        deadline: Option<u64>,
        give_up: u64,
        idle: &mut dyn FnMut() -> Result<(), SimError>,
    ) -> Result<Got, SimError> {
        let mut polls = 0u32;
        loop {
            if let Some(msg) = self.ports.receive() {
                match check_command(&msg, self.group, k) {
                    Ok(()) => return Ok(Got::Command(msg, monotonic_ns())),
                    Err(Reject::Sequence) if msg.seq < k => self.late += 1,
                    Err(kind) => {
                        self.rejected += 1;
                        if !self.logged[kind.index()] {
                            self.logged[kind.index()] = true;
                            log(format_args!(
                                "rejected command seq {} ({}); it is never applied. Further rejections of this kind are counted, not logged",
                                msg.seq,
                                kind.name()
                            ));
                        }
                    }
                }
            }
            let now = monotonic_ns();
            if deadline.is_some_and(|d| now >= d) {
                return Ok(Got::Deadline);
            }
            if now >= give_up {
                return Err(SimError::Run(format!("no command for step {k}: timed out")));
            }
            polls = polls.wrapping_add(1);
            if polls.is_multiple_of(256) {
                idle()?;
            }
            let until = deadline.unwrap_or(give_up);
            match self.wake {
                Wake::Spin => std::hint::spin_loop(),
                Wake::Event => {
                    // precise wait on the command event, bounded by the tick; untimed waits
                    // (connection, lockstep) in 1 ms slices, so `idle` runs between them
                    let mut wait = until.saturating_sub(now);
                    if deadline.is_none() {
                        wait = wait.min(1_000_000);
                    }
                    let _ = self.ports.wait_notified(Duration::from_nanos(wait));
                    if deadline.is_none() || polls.is_multiple_of(16) {
                        idle()?;
                    }
                }
            }
        }
    }
}

fn publish<L: Link<StateMsg, CommandMsg>>(ports: &L, msg: StateMsg, notify: bool) -> u64 {
    let stamp = ports.send(msg);
    if notify {
        ports.notify();
    }
    stamp
}

fn spawn_controller(opts: &PairOptions) -> Result<Child, SimError> {
    let exe = std::env::current_exe()
        .map_err(|e| SimError::Run(format!("cannot locate plant_sim: {e}")))?;
    let path = exe.with_file_name("controller_node");
    if !path.exists() {
        return Err(SimError::Run(format!(
            "{} not found: build it (cargo build --release --workspace) or start one by hand and pass --no-spawn",
            path.display()
        )));
    }
    let mut cmd = Command::new(&path);
    cmd.args(&opts.scenario_args)
        .args(["--name", &opts.run])
        .stdin(Stdio::null());
    if opts.transport == Transport::Uds {
        cmd.args(["--transport", "uds"]);
    }
    if let Some(k) = opts.controller_fault_nan_torque {
        cmd.args(["--fault-nan-torque", &k.to_string()]);
    }
    cmd.spawn()
        .map_err(|e| SimError::Run(format!("cannot start {}: {e}", path.display())))
}

fn run_group<
    G: MatrixLieGroup<N, M>,
    L: Link<StateMsg, CommandMsg>,
    const N: usize,
    const M: usize,
>(
    opts: &PairOptions,
    group: u32,
    ports: &L,
) -> Result<(Trajectory, PairSummary), SimError> {
    let realtime = opts.mode == Mode::Realtime;
    let mut s = opts.scenario.clone();
    let steps = if realtime {
        s.control_period = 1.0 / opts.rate_hz;
        (s.duration * opts.rate_hz).round() as u64
    } else {
        s.steps()
    };
    let period = s.control_period;
    let period_ns = (period * 1e9).round() as u64;
    let input = |e: controller::Error| SimError::Input(format!("scenario `{}`: {e}", s.name));
    let mut plant = s.plant_body::<G, N, M>().map_err(input)?;
    let mut monitor = s.reference_generator::<G, N, M>().map_err(input)?;
    let cfg = s.controller_config::<N, M>();
    let limit = cfg.torque_limit;
    let disturbance = s.disturbance_vector::<M>();
    ensure_dir(&opts.out)?;
    let mut child = Spawned(if opts.spawn {
        Some(spawn_controller(opts)?)
    } else {
        None
    });
    let event = opts.wake == Wake::Event;
    let mut waiter = Waiter {
        ports,
        group,
        wake: opts.wake,
        rejected: 0,
        logged: [false; 5],
        late: 0,
    };

    let state_msg = |k: u64, q: &SMatrix<f64, N, N>, v: &SVector<f64, M>| {
        let mut m = StateMsg::new(group);
        m.seq = k;
        m.t = controller::real::<f64>(k as f64) * period;
        m.control_period = period;
        m.flags = if event { flags::WAKE_EVENT } else { 0 };
        for i in 0..N {
            for j in 0..N {
                m.q[i * N + j] = q[(i, j)];
            }
        }
        for i in 0..M {
            m.v[i] = v[i];
        }
        m
    };
    let publish_state =
        |k: u64, q: &SMatrix<f64, N, N>, v: &SVector<f64, M>| -> Result<u64, SimError> {
            let mut msg = state_msg(k, q, v);
            if let Some(&(_, fault)) = opts.state_faults.iter().find(|(fk, _)| *fk == k) {
                {
                    match fault {
                        StateFault::Version => msg.version += 1,
                        StateFault::Group => {
                            msg.group = if group == ipc_types::group::SO3 {
                                ipc_types::group::SE3
                            } else {
                                ipc_types::group::SO3
                            }
                        }
                        StateFault::Nan => msg.v[0] = f64::NAN,
                    }
                    log(format_args!(
                        "fault injection: publishing a corrupted state ({fault:?}) for seq {k}"
                    ));
                }
            }
            Ok(publish(ports, msg, event))
        };

    // Connect: publish state 0 (kept in the service's history for a late controller) and
    // wait for command 0; the clock starts when it arrives.
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
    let q0 = *plant.configuration();
    let v0 = plant.velocity();
    let mut stamp = publish_state(0, &q0, &v0)?;
    let connect_until = monotonic_ns() + opts.connect_timeout.as_nanos() as u64;
    let mut connect_idle = || -> Result<(), SimError> {
        ports.resend();
        if let Some(status) = child.exited() {
            return Err(SimError::Run(format!(
                "controller_node exited before the run started ({status})"
            )));
        }
        std::thread::sleep(Duration::from_micros(500));
        Ok(())
    };
    let first = match waiter.wait(0, None, connect_until, &mut connect_idle) {
        Ok(Got::Command(c, t)) => (c, t),
        Ok(Got::Deadline) | Err(_) => {
            return Err(SimError::Run(format!(
                "no controller answered on run `{}` within {:.0} s",
                opts.run,
                opts.connect_timeout.as_secs_f64()
            )));
        }
    };
    let t0 = monotonic_ns();
    let started = Instant::now();
    log(format_args!(
        "controller connected; running {} steps {} ({} wake-up, period {} s)",
        steps,
        if realtime {
            "in real time"
        } else {
            "in lockstep"
        },
        if event { "event" } else { "busy-poll" },
        period
    ));

    let mut latency = Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3)
        .map_err(|e| SimError::Run(e.to_string()))?;
    let mut compute = latency.clone();
    let mut lateness = latency.clone();
    let mut rows = Vec::with_capacity(steps as usize + 1);
    let mut status = Vec::new();
    let mut tau = SVector::<f64, M>::zeros();
    let (mut misses, mut in_row, mut safe_entries, mut safe_cycles) = (0u64, 0u32, 0u64, 0u64);
    let mut safe = false;
    let live = std::io::stderr().is_terminal();
    let mut last_status = Instant::now();
    let mut last_allocations = None;
    let mut pending = Some(first);

    for k in 0..=steps {
        let q = *plant.configuration();
        let v = plant.velocity();
        // 1. Command k.
        let got = match pending.take() {
            Some((c, t)) => Got::Command(c, t),
            None if realtime => {
                let mut idle = || Ok(());
                waiter.wait(k, Some(t0 + (k + 1) * period_ns), u64::MAX, &mut idle)?
            }
            None => {
                let give_up = monotonic_ns() + opts.lockstep_timeout.as_nanos() as u64;
                let mut idle = || -> Result<(), SimError> {
                    if let Some(status) = child.exited() {
                        return Err(SimError::Run(format!(
                            "controller_node exited during the run ({status})"
                        )));
                    }
                    Ok(())
                };
                waiter.wait(k, None, give_up, &mut idle).map_err(|_| {
                    SimError::Run(format!(
                        "lockstep: no command for step {k} within {:.1} s",
                        opts.lockstep_timeout.as_secs_f64()
                    ))
                })?
            }
        };
        // 2. The torque held over [t_k, t_{k+1}).
        let row_status = match got {
            Got::Command(c, received) => {
                if k > 0 {
                    let _ = latency.record(received.saturating_sub(stamp).max(1));
                }
                let _ = compute.record(c.compute_ns.max(1));
                last_allocations = Some(c.heap_allocations);
                tau = SVector::<f64, M>::from_fn(|i, _| c.tau[i]);
                in_row = 0;
                if safe {
                    safe = false;
                    log(format_args!(
                        "t = {:.3} s: fresh commands are back, leaving safe mode",
                        k as f64 * period
                    ));
                }
                0
            }
            Got::Deadline => {
                misses += 1;
                in_row += 1;
                if in_row >= opts.miss_limit && !safe {
                    safe = true;
                    safe_entries += 1;
                    log(format_args!(
                        "t = {:.3} s: {} consecutive deadline misses, entering SAFE MODE (damping only, tau = -K_d V)",
                        k as f64 * period,
                        in_row
                    ));
                }
                if safe {
                    safe_cycles += 1;
                    tau = -(cfg.kd * v);
                    2
                } else {
                    1
                }
            }
        };
        if let Some(l) = &limit {
            for i in 0..M {
                tau[i] = tau[i].clamp(-l[i], l[i]);
            }
        }
        let t = controller::real::<f64>(k as f64) * period;
        rows.push(Row::new::<G, N, M>(
            t,
            &q,
            &v,
            &monitor.desired(),
            &tau,
            &cfg.inertia,
            &cfg.k,
        ));
        if realtime {
            status.push(row_status);
            let tick = t0 + (k + 1) * period_ns;
            sleep_until(tick);
            let _ = lateness.record(monotonic_ns().saturating_sub(tick).max(1));
        }
        if live && last_status.elapsed() > Duration::from_millis(250) {
            last_status = Instant::now();
            let r = rows[rows.len() - 1];
            eprint!(
                "\r  t = {:8.3} s  L = {:10.4e}  misses {:6}  {}  RTT p50 {:7.1} us  ",
                r.t,
                r.lyapunov,
                misses,
                if safe { "SAFE MODE" } else { "tracking " },
                latency.value_at_quantile(0.5) as f64 / 1000.0
            );
        }
        if k == steps {
            break;
        }
        // 3. Integrate [t_k, t_{k+1}) and publish state k+1.
        let applied = tau + disturbance;
        plant.advance(&applied, period, s.plant_substeps);
        monitor.advance();
        stamp = publish_state(k + 1, plant.configuration(), &plant.velocity())?;
    }
    if live {
        eprintln!();
    }
    let elapsed = started.elapsed();
    // The run is over: tell the controller, then reap it.
    let mut bye = StateMsg::new(group);
    bye.seq = steps + 1;
    bye.flags = flags::SHUTDOWN;
    publish(ports, bye, true);
    let controller_exit = child.finish(Duration::from_secs(3));

    let traj = Trajectory {
        group: s.group,
        control_period: period,
        duration: steps as f64 * period,
        rows,
        status,
    };
    let summary = PairSummary {
        sim: Summary::of(&traj, &s.name, s.law.name()),
        mode: if realtime { "realtime" } else { "lockstep" }.to_owned(),
        wake: if event { "event" } else { "spin" }.to_owned(),
        run: opts.run.clone(),
        rate_hz: realtime.then_some(opts.rate_hz),
        cycles: steps + 1,
        latency: Percentiles::of(&latency),
        controller_compute: Percentiles::of(&compute),
        tick_lateness: realtime.then(|| Percentiles::of(&lateness)),
        deadline_misses: misses,
        safe_mode_entries: safe_entries,
        safe_mode_cycles: safe_cycles,
        commands_rejected: waiter.rejected,
        late_commands: waiter.late,
        controller_exit,
        transport: opts.transport.name().to_owned(),
        controller_heap_allocations: last_allocations,
    };
    write_trajectory_csv(&traj, &opts.out.join("trajectory.csv"))?;
    write_json(&summary, &opts.out.join("summary.json"))?;
    let title = format!(
        "{} — {} on {}, {} ({})",
        s.name,
        s.law.name().to_uppercase(),
        s.group.name().to_uppercase(),
        if realtime {
            format!("real time at {} Hz", opts.rate_hz)
        } else {
            "lockstep".to_owned()
        },
        opts.run
    );
    trajectory_figure(&traj, &title, &opts.out.join("figure"))?;
    log(format_args!(
        "{} cycles in {:.3} s of wall time",
        steps + 1,
        elapsed.as_secs_f64()
    ));
    Ok((traj, summary))
}
