//! The plant side of one run: its state, set-up, the connection, the published states and the written results.

use super::{
    LOCKSTEP_NOTE, Mode, PairOptions, PairSummary, Percentiles, Realtime, StateFault, Stats, log,
};
use crate::SimError;
use crate::output::{Summary, write_json, write_trajectory_csv};
use crate::plot::trajectory_figure;
use crate::spawn::Spawned;
use crate::trajectory::{Row, SimulatedTrajectory, input};
use eqtrack_controller::group::BuiltinGroup;
use ipc_types::StateMsg;
use link::wire::group_code;
use link::{Command, DeadlinePolicy, NoCommand, PlantEndpoint, PlantEndpointConfig, clock};
use nalgebra::SVector;
use recorder::{Header, Recorder};
use scenario::Scenario;
use std::time::Instant;

/// The plant side of one run: body, scenario, endpoint, policy and records.
pub(super) struct PlantRun<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> {
    pub(super) opts: &'a PairOptions,
    pub(super) s: Scenario,
    pub(super) steps: u64,
    pub(super) period_ns: u64,
    pub(super) plant: eqtrack_controller::integrator::RigidBody<f64, G, N, M>,
    /// The reference for the records, under the failsafe's set-points as the controller's
    /// commands engage them (nominal: the reference bit for bit).
    pub(super) reference:
        crate::failsafe::SupervisedReference<G, eqtrack_controller::Source<f64, G, N, M>, N, M>,
    pub(super) cfg: eqtrack_controller::ControllerConfig<f64, N, M>,
    pub(super) ep: PlantEndpoint,
    pub(super) policy: DeadlinePolicy,
    pub(super) stats: Stats,
    pub(super) rows: Vec<Row>,
    pub(super) status: Vec<u8>,
    /// Cycles run (rows are kept every `record_every`).
    pub(super) cycles: u64,
    pub(super) tau: SVector<f64, M>,
    /// The disturbance-rejection terms of the last fresh command (`None`: the scenario has
    /// none).
    pub(super) terms: Option<crate::trajectory::Terms>,
    pub(super) published: u64,
    /// The state published last (with its stamp).
    pub(super) state: StateMsg,
    pub(super) recorder: Option<Recorder>,
    pub(super) t0: u64,
    /// What the real-time settings did.
    pub(super) rt: Realtime,
    /// The sensors and the estimator (`None`: the law is handed the exact state).
    pub(super) estimation: Option<crate::estimation::Estimation>,
    /// The samples and estimate of the state published last.
    pub(super) estimate: Option<crate::trajectory::EstimateRow>,
    /// The firmware's local origin ([`scenario::Scenario::local_origin`]): a serial
    /// controller's positions are relative to it.
    pub(super) origin: [f64; 3],
    /// A controller that estimates on board: the slot its transport shares, the samples of
    /// the state published last, and the last estimate a command brought back (the rows
    /// take it).
    pub(super) onboard: Option<(
        link::serial::OnboardSlot,
        Option<crate::sensors::Samples>,
        Option<eqtrack_serial_wire::Estimate>,
    )>,
    /// The same, with the true state, for the flight recorder.
    pub(super) sensor_record: Option<recorder::SensorRecord>,
    /// The vehicle (`None`: the command's wrench acts on the body directly).
    pub(super) vehicle: Option<super::vehicle::PairVehicle<M>>,
    /// `--tunable`: the `params` board the loop writes, and the parameter thread.
    pub(super) params: Option<link::params::ParamsWriter>,
    pub(super) tuning: Option<crate::tuning::Tuning>,
    /// The changes that took effect (set when the loop has ended).
    pub(super) param_changes: Option<Vec<recorder::ParamChange>>,
    /// `[failsafe]`: the manager's transitions, as the controller's commands report them.
    pub(super) failsafe: Option<crate::failsafe::Supervision>,
    /// A service manager's watchdog (docs/pair-on-a-board.md, "Watchdogs"), pinged from the
    /// loop and its waits only.
    pub(super) notifier: link::notify::Notifier,
}

/// The service manager's notifier the process's environment asks for
/// (docs/pair-on-a-board.md, "Watchdogs"); a bad environment is bad input, naming the variable.
fn notifier() -> Result<link::notify::Notifier, SimError> {
    link::notify::Notifier::from_process()
        .map_err(|e| SimError::Input(format!("service manager: {e}")))
}

/// `--tunable`: the run's `params` board with the scenario's gains (`None` without).
fn params_board(
    opts: &PairOptions,
    s: &Scenario,
    fingerprint: u64,
) -> Result<Option<link::params::ParamsWriter>, SimError> {
    if !opts.tunable {
        return Ok(None);
    }
    if opts.serial.is_some() {
        return Err(SimError::Input(
            "--tunable: run-time parameters travel on the run's iceoryx2 services; the processor-in-the-loop serial link does not carry them".to_owned(),
        ));
    }
    let first = ipc_types::ParamMsg::new(
        link::wire::wire_group(s.group),
        fingerprint,
        crate::tuning::gains(s, 0),
    );
    Ok(Some(link::params::ParamsWriter::open(&opts.run, first)?))
}

/// Corrupts a state as a test asks.
pub(super) fn corrupt(msg: &mut StateMsg, fault: StateFault, group: eqtrack_controller::GroupKind) {
    match fault {
        StateFault::Version => msg.version += 1,
        StateFault::Group => {
            let other = eqtrack_controller::GroupKind::ALL
                .into_iter()
                .find(|g| *g != group)
                .unwrap_or(group);
            msg.group = group_code(other);
        }
        StateFault::Nan => msg.v[0] = f64::NAN,
    }
}

impl<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> PlantRun<'a, G, N, M> {
    /// The scenario at the run's period, the body, the reference for the records, the
    /// endpoint.
    pub(super) fn new(opts: &'a PairOptions) -> Result<Self, SimError> {
        let mut s = opts.scenario.clone();
        let fingerprint = s.fingerprint();
        let steps = run_steps(opts, &mut s);
        let plant = s.plant_body::<G, N, M>().map_err(input(&s))?;
        let reference = crate::failsafe::Supervision::supervise::<G, _, N, M>(
            &s,
            s.reference_source::<G, N, M>().map_err(input(&s))?,
        );
        let cfg = s.controller_config::<N, M>();
        let vehicle = super::vehicle::PairVehicle::of(&s, &plant.velocity())?;
        let config = PlantEndpointConfig {
            actuators: vehicle.as_ref().map_or(0, |v| v.count()),
            run: opts.run.clone(),
            group: s.group,
            control_period: s.control_period,
            transport: opts.transport,
            wake: opts.wake,
            fingerprint,
            scenario: s.name.clone(),
        };
        let mut estimation =
            crate::estimation::Estimation::new(&s, s.control_period, &opts.sample_faults)?;
        // a controller on a serial link runs the scenario's filter itself: it is sent the
        // samples, and the rows take its estimate
        // the firmware's local origin: positions cross the serial line relative to it
        let origin = s.local_origin();
        let onboard = onboard(opts, &s)?;
        if onboard.is_some() {
            estimation = estimation.map(crate::estimation::Estimation::on_board);
        }
        let params = params_board(opts, &s, fingerprint)?;
        let ep = match &opts.serial {
            None => PlantEndpoint::open(config)?,
            Some(c) => {
                let transport = link::serial::SerialTransport::new(
                    (c.open)()?,
                    std::sync::Arc::clone(&c.counts),
                    c.corrupt,
                )
                .with_noise(c.noise)
                .with_onboard(onboard.clone())
                .with_origin(origin);
                PlantEndpoint::with_transport(config, Box::new(transport))
            }
        };
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
            estimation,
            onboard: onboard.map(|slot| (slot, None, None)),
            origin,
            estimate: None,
            sensor_record: None,
            vehicle,
            params,
            tuning: None,
            param_changes: None,
            failsafe: crate::failsafe::Supervision::following(
                &s,
                (steps / opts.record_every.max(1)) as usize + 2,
            ),
            notifier: notifier()?,
            s,
        })
    }

    /// `--tunable`: starts the parameter thread (after the output directory exists, where
    /// it records the changes).
    pub(super) fn start_tuning(&mut self) -> Result<(), SimError> {
        if self.params.is_none() {
            return Ok(());
        }
        let opts = self.opts;
        let tuner = scenario::tuning::Tuner::from_source(&opts.source, "seed")
            .map_err(|e| SimError::Input(e.to_string()))?;
        self.tuning = Some(crate::tuning::Tuning::start(
            &opts.run,
            tuner,
            opts.record.then(|| opts.out.clone()),
            self.s.control_period,
        )?);
        Ok(())
    }

    /// Before state k goes out: a change waiting is put in force from cycle k on, at once
    /// for everything it touches (the plant's damping and Lyapunov gains, the estimator,
    /// the `params` board the controller reads). Allocation-free.
    fn retune(&mut self, k: u64) {
        let Some(r) = self.tuning.as_ref().and_then(crate::tuning::Tuning::take) else {
            return;
        };
        if let Some(g) = r.gains {
            self.cfg.k = nalgebra::SMatrix::from_fn(|i, j| g.k[i * N + j]);
            self.cfg.kd = nalgebra::SMatrix::from_fn(|i, j| g.kd[i * M + j]);
            if let Some(board) = &mut self.params {
                board.change(ipc_types::Gains { cycle: k, ..g });
            }
        }
        if let (Some((kp, ki)), Some(e)) = (r.estimator, &mut self.estimation)
            && let Err(e) = e.retune(kp, ki)
        {
            log(format_args!(
                "warning: the estimator refused its new gains: {e}"
            ));
        }
        if let Some(t) = &self.tuning {
            t.applied(k);
        }
    }

    pub(super) fn realtime(&self) -> bool {
        self.opts.mode == Mode::Realtime
    }

    /// Copies the scenario into the output directory and starts the flight recorder (its
    /// channel holds half a second of cycles, at least 4096).
    pub(super) fn start_recorder(&mut self) -> Result<(), SimError> {
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
        let sink = crate::status::status_sink(&opts.run, &header);
        // the plan board, read on the recorder's thread: a controller started with
        // `--reference stream` takes its pieces from it, and replay needs them
        let run = opts.run.clone();
        let plans: recorder::PlanSourceFactory = Box::new(move || {
            match link::plan::PlanReader::for_recorder(&run) {
                Ok(mut r) => Some(Box::new(move || r.receive()) as recorder::PlanSource),
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
    pub(super) fn publish(&mut self, k: u64) -> Result<(), SimError> {
        self.retune(k);
        let mut msg = self.ep.state_template();
        if self.params.is_some() {
            msg.flags |= ipc_types::flags::TUNABLE;
        }
        msg.seq = k;
        msg.t = k as f64 * self.s.control_period;
        // the torque applied over the last period (zero at k = 0): the rejection terms' input
        msg.set_applied(&self.tau);
        if let Some(v) = &self.vehicle {
            // the wheels' tachometers: the law's gyroscopic term needs them
            let (speeds, count) = v.wheel_speeds(&self.plant.velocity());
            msg.set_wheel_speeds(&speeds[..count]);
        }
        match &mut self.estimation {
            None => msg.set_state(self.plant.configuration(), &self.plant.velocity()),
            Some(e) => {
                // the torque held over the last period, as the in-process simulation has it
                let held = match &self.vehicle {
                    Some(v) => v.held,
                    None => {
                        let r = G::rotation(self.plant.configuration());
                        self.tau
                            + self
                                .s
                                .disturbance_wrench::<G, N, M>(k.saturating_sub(1), &r)
                    }
                };
                if let Some((slot, sent, _)) = &mut self.onboard {
                    let samples = e.sample(k, &self.plant, &held);
                    if let Ok(mut o) = slot.lock() {
                        o.samples = Some((k, wire_samples(&samples, &self.origin)));
                    }
                    *sent = Some(samples);
                    msg.set_state(self.plant.configuration(), &self.plant.velocity());
                } else {
                    let (q_hat, v_hat, row) = e.measure(k, &self.plant, &held);
                    msg.set_state(&q_hat, &v_hat);
                    // the gated estimator's health, the failsafe's `estimator` cause
                    msg.flags |= match row.health {
                        Some(eqtrack_estimator::health::Health::Degraded(_)) => {
                            ipc_types::flags::ESTIMATE_DEGRADED
                        }
                        Some(eqtrack_estimator::health::Health::Lost(_)) => {
                            ipc_types::flags::ESTIMATE_LOST
                        }
                        _ => 0,
                    };
                    if self.recorder.is_some() {
                        let mut truth = StateMsg::new(link::wire::wire_group(self.s.group));
                        truth.set_state(self.plant.configuration(), &self.plant.velocity());
                        self.sensor_record = Some(row.sensor_record(&truth));
                    }
                    self.estimate = Some(row);
                }
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

    /// A controller that estimates on board: the row's estimate columns for state k, from
    /// the estimate its command k brought back (none came, in real time: the last one, with
    /// tick k's samples and its error against tick k's attitude).
    pub(super) fn take_onboard_estimate(&mut self, k: u64) {
        let Some((slot, Some(samples), last)) = &mut self.onboard else {
            return;
        };
        let got = slot.lock().ok().and_then(|mut o| o.estimate.take());
        if let Some((_, e)) = got.filter(|(seq, _)| *seq == k) {
            *last = Some(e);
        }
        let (Some(e), samples) = (last.as_ref(), *samples) else {
            return;
        };
        // the firmware's position is relative to its local origin: back in world coordinates
        let origin = self.origin;
        let q_hat = nalgebra::SMatrix::<f64, N, N>::from_fn(|i, j| {
            let shift = if N == 4 && j == 3 && i < 3 {
                origin[i]
            } else {
                0.0
            };
            e.q.get(i * N + j)
                .map_or(f64::NAN, |x| f64::from(*x) + shift)
        });
        let v_hat =
            SVector::<f64, M>::from_fn(|i, _| e.v.get(i).map_or(f64::NAN, |x| f64::from(*x)));
        let bias = nalgebra::Vector3::from(e.bias.map(f64::from));
        let row = crate::estimation::row(
            samples,
            self.plant.configuration(),
            &q_hat,
            &v_hat,
            &bias,
            None,
            None,
        );
        if self.recorder.is_some() {
            let mut truth = StateMsg::new(link::wire::wire_group(self.s.group));
            truth.set_state(self.plant.configuration(), &self.plant.velocity());
            self.sensor_record = Some(row.sensor_record(&truth));
        }
        self.estimate = Some(row);
    }

    /// Publishes state 0 and waits for command 0; the clock starts when it arrives.
    pub(super) fn connect(&mut self, child: &mut Spawned) -> Result<Command, SimError> {
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
            self.ping();
            match self.ep.wait_command(0, clock::monotonic_ns() + 1_000_000) {
                Ok(c) => break c,
                Err(NoCommand::Refused(r)) => return Err(SimError::Mismatch(Box::new(r))),
                Err(NoCommand::Missed) => {}
            }
            if !self.realtime()
                && let Some(e) = self.lockstep_invalid(0, 0)
            {
                return Err(e);
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

    /// The service manager's watchdog: a ping when one is due; the first that cannot be
    /// sent is logged.
    pub(super) fn ping(&mut self) {
        self.notifier.keep_alive(clock::monotonic_ns, |e| {
            log(format_args!(
                "service manager: cannot ping the watchdog: {e}"
            ));
        });
    }

    /// Ends the flight recording and logs how it went; a failed recording (a full disk) is
    /// reported, and the run's results are still written.
    fn finish_recording(&mut self) -> Option<recorder::RecordingReport> {
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
        recording
    }

    /// Writes trajectory.csv, summary.json and the figure.
    pub(super) fn write(
        mut self,
        interrupted: Option<link::StopSignal>,
        controller_exit: Option<i32>,
        rejected: u64,
        late: u64,
        loop_allocations: Option<u64>,
    ) -> Result<(SimulatedTrajectory, PairSummary), SimError> {
        let recording = self.finish_recording();
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
            vehicle: None,
            failsafe: self.failsafe.take(),
        };
        let traj = SimulatedTrajectory {
            vehicle: self
                .vehicle
                .as_ref()
                .map(|v| v.report(&traj.rows, traj.control_period)),
            ..traj
        };
        let summary = PairSummary {
            sim: Summary::of(&traj, &s.name, s.law.name()).with_error_frame(s),
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
            transport: match &opts.serial {
                Some(c) => c.name.clone(),
                None => opts.transport.name().to_owned(),
            },
            controller_heap_allocations: self.stats.last_allocations,
            realtime: self.rt.clone(),
            recording,
            plant_loop_heap_allocations: loop_allocations,
            parameter_changes: self.param_changes.take(),
        };
        write_trajectory_csv(&traj, &opts.out.join("trajectory.csv"))?;
        write_json(&summary, &opts.out.join("summary.json"))?;
        let title = figure_title(s, opts, realtime, interrupted.is_some());
        trajectory_figure(&traj, &title, &opts.out.join("figure"))?;
        Ok((traj, summary))
    }
}

/// The run figure's title: the scenario, the law, the group, the mode and the run's name.
fn figure_title(s: &Scenario, opts: &PairOptions, realtime: bool, interrupted: bool) -> String {
    format!(
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
        if interrupted { ", interrupted" } else { "" }
    )
}

/// The samples as the serial frame carries them (`f32`, as the board's sensors give them);
/// a position fix relative to the firmware's local origin, the difference formed in `f64`.
fn wire_samples(s: &crate::sensors::Samples, origin: &[f64; 3]) -> eqtrack_serial_wire::Samples {
    let f = |v: &nalgebra::Vector3<f64>| [v[0] as f32, v[1] as f32, v[2] as f32];
    let o = nalgebra::Vector3::from(*origin);
    eqtrack_serial_wire::Samples {
        gyro: f(&s.gyro),
        directions: s.directions[..s.count.min(4)].iter().map(f).collect(),
        accel: s.accel.as_ref().map(f),
        position: s.position.as_ref().map(|x| f(&(x - o))),
    }
}

/// The run's steps; in real time, the scenario's period set to the run's rate.
fn run_steps(opts: &PairOptions, s: &mut scenario::Scenario) -> u64 {
    match opts.mode {
        Mode::Realtime => {
            s.control_period = 1.0 / opts.rate_hz;
            (s.duration * opts.rate_hz).round() as u64
        }
        Mode::Lockstep => s.steps(),
    }
}

/// The slot for the estimate a controller on a serial link computes on board (it runs the
/// scenario's filter, and with `gate = true` its innovation gate, itself), or `None`.
fn onboard(
    opts: &PairOptions,
    s: &scenario::Scenario,
) -> Result<Option<link::serial::OnboardSlot>, SimError> {
    if opts.serial.is_none() || s.filter_settings()?.is_none() {
        return Ok(None);
    }
    Ok(Some(link::serial::OnboardSlot::default()))
}
