//! One control cycle of the plant: obtain command k (lockstep: wait for it; real time: by the deadline, through the deadline policy), apply it, record it, integrate.

use super::{PlantRun, log};
use crate::SimError;
use crate::spawn::Spawned;
use crate::trajectory::Row;
use eqtrack_controller::Trajectory as _;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::law::{safe_mode_torque, saturate};
use link::{Command, Decision, NoCommand, Transition, clock};
use recorder::Record;
use std::io::IsTerminal;
use std::time::Instant;

impl<'a, G: BuiltinGroup<N, M>, const N: usize, const M: usize> PlantRun<'a, G, N, M> {
    /// Command k in real time: waits for it until the tick's deadline and asks the
    /// [`DeadlinePolicy`] what to apply.
    pub(super) fn realtime_command(
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
    pub(super) fn lockstep_command(
        &mut self,
        k: u64,
        child: &mut Spawned,
    ) -> Result<Command, SimError> {
        let give_up = Instant::now() + self.opts.lockstep_timeout;
        let rejected = self.ep.invalid_commands();
        loop {
            self.ping();
            match self.ep.wait_command(k, clock::monotonic_ns() + 20_000_000) {
                Ok(c) => return Ok(c),
                Err(NoCommand::Refused(r)) => return Err(SimError::Mismatch(Box::new(r))),
                Err(NoCommand::Missed) => {}
            }
            if let Some(e) = self.lockstep_invalid(k, rejected) {
                return Err(e);
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

    /// Lockstep: the error that ends the run when a command failed the plant's checks since
    /// the count was `before` (`None`: none did). Lockstep applies every command and holds
    /// none, so an invalid command cannot be replaced; the run stops, naming the step.
    pub(super) fn lockstep_invalid(&mut self, k: u64, before: u64) -> Option<SimError> {
        if self.ep.invalid_commands() <= before {
            return None;
        }
        let why = self
            .ep
            .next_invalid()
            .map(|r| format!(" (seq {}: {})", r.msg.seq, r.kind))
            .unwrap_or_default();
        Some(SimError::Run(format!(
            "lockstep: the controller's command for step {k} was rejected by the plant's checks{why}; a lockstep run applies every command and holds none, so it stops here"
        )))
    }

    /// Tick k: obtain command k, decide, record the row, wait for the tick's end.
    ///
    /// Real time: command k is judged against the wall-clock deadline `t0 + (k+1)·period` by
    /// the [`DeadlinePolicy`]. Lockstep: command k is waited for and applied; no clock is read
    /// and the policy is not consulted (docs/architecture.md, "Lockstep").
    pub(super) fn cycle(
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
        if self.params.is_some()
            && let Some(c) = &got
            && c.msg.flags & ipc_types::flags::TUNED == 0
        {
            return Err(SimError::Run(format!(
                "--tunable: the controller's command for step {k} was not computed with the run's params board (its flags lack TUNED): start a controller_node of this build"
            )));
        }
        if let Some(c) = &got {
            self.stats.command(c, self.published, k == 0);
        }
        if self.vehicle.is_some() {
            self.actuate(k, step.decision, got.as_ref());
        } else {
            self.apply_wrench(step.decision, got.as_ref());
        }
        self.log_transition(k, step.transition, step.misses_in_row);
        self.take_onboard_estimate(k);
        if let Some(c) = &got {
            self.follow_failsafe(k, &c.msg);
        }
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

    /// `[failsafe]`: the manager's state word command `cmd` carries, kept (transitions, the
    /// row's action, logged), and the set-point the controller flies engaged for the rows at
    /// the estimate it answered: the one state k carried, or with the filter on board, the one
    /// its command brought back.
    fn follow_failsafe(&mut self, k: u64, cmd: &ipc_types::CommandMsg) {
        let Some(sup) = &mut self.failsafe else {
            return;
        };
        match (&self.onboard, &self.estimate) {
            (Some(_), Some(e)) => self.reference.observe(
                &nalgebra::SMatrix::<f64, N, N>::from_fn(|i, j| e.q_hat[i * N + j]),
                &nalgebra::SVector::<f64, M>::from_fn(|i, _| e.v_hat[i]),
            ),
            _ => self.reference.observe(
                &self.state.configuration::<N>(),
                &self.state.velocity::<M>(),
            ),
        }
        let before = sup.transitions().len();
        sup.follow(k as f64 * self.s.control_period, cmd.failsafe);
        if sup.transitions().len() > before {
            self.reference.engage(sup.action());
        }
        for tr in &sup.transitions()[before..] {
            log(format_args!("{tr}"));
        }
    }

    /// Integrates `[t_k, t_{k+1})` under the held torque and publishes state k+1.
    pub(super) fn advance(&mut self, k: u64) -> Result<(), SimError> {
        if let Some(v) = &mut self.vehicle {
            v.advance(&mut self.plant, &self.s, k);
            self.reference.advance();
            return self.publish(k + 1);
        }
        let applied = self.tau + self.s.disturbance_at::<M>(k);
        let (h, substeps) = (self.s.control_period, self.s.plant_substeps);
        match self.s.world_disturbance::<M>() {
            None => self.plant.advance(&applied, h, substeps),
            Some(w) => self.plant.advance_with_world(&applied, &w, h, substeps),
        }
        self.reference.advance();
        self.publish(k + 1)
    }

    /// The decision's wrench on the body: a fresh command's `τ`, the safe-mode damping, or
    /// the held one; saturated.
    fn apply_wrench(&mut self, decision: Decision, got: Option<&Command>) {
        let v = self.plant.velocity();
        self.tau = match (decision, got) {
            (Decision::Fresh, Some(c)) => {
                self.take_terms(c);
                c.torque()
            }
            (Decision::Safe, _) => {
                safe_mode_torque(&self.cfg.kd, &v, self.cfg.torque_limit.as_ref())
            }
            _ => self.tau,
        };
        saturate(&mut self.tau, self.cfg.torque_limit.as_ref());
    }

    /// The decision through the vehicle's actuators (docs/vehicles.md, "In the pair"): a
    /// fresh command's `u_cmd`, the plant's own allocation of the safe-mode damping, or the
    /// held commands. `τ` becomes the wrench the law counts as applied.
    fn actuate(&mut self, k: u64, decision: Decision, got: Option<&Command>) {
        let v = self.plant.velocity();
        let Some(vehicle) = &mut self.vehicle else {
            return;
        };
        vehicle.failures_at(k as f64 * self.s.control_period);
        if let Some(c) = got {
            vehicle.heard(&c.msg, k as f64 * self.s.control_period);
        }
        match (decision, got) {
            (Decision::Fresh, Some(c)) => {
                vehicle.apply(&c.msg, &v);
                self.take_terms(c);
            }
            (Decision::Safe, _) => {
                let damping = safe_mode_torque(&self.cfg.kd, &v, self.cfg.torque_limit.as_ref());
                vehicle.safe(&damping, &self.plant);
            }
            _ => vehicle.hold(&v),
        }
        if let Some(vehicle) = &self.vehicle {
            self.tau = vehicle.accounted;
        }
    }

    /// A fresh command's disturbance-rejection terms, for the rows.
    fn take_terms(&mut self, c: &Command) {
        if self.terms.is_some() {
            self.terms = Some(crate::trajectory::Terms {
                observer: c.msg.observer,
                integral: c.msg.integral,
            });
        }
    }

    pub(super) fn record(&mut self, k: u64, decision: Decision) {
        self.cycles += 1;
        if !k.is_multiple_of(self.opts.record_every.max(1)) && k != self.steps {
            return;
        }
        let t = eqtrack_controller::real::<f64>(k as f64) * self.s.control_period;
        let row = Row::new::<G, N, M>(
            t,
            self.plant.configuration(),
            &self.plant.velocity(),
            &self.reference.desired(),
            &self.tau,
            &self.cfg,
        )
        .with_estimate(self.estimate)
        .with_terms(self.terms);
        // a vehicle's row: its allocation and actuators, and tau the actuators' wrench
        self.rows
            .push(match self.vehicle.as_ref().and_then(|v| v.row) {
                Some((vehicle, wrench)) => row.with_vehicle(vehicle, &wrench),
                None => row,
            });
        if let Some(sup) = &mut self.failsafe {
            sup.row();
        }
        if self.realtime() {
            self.status.push(decision.code());
        }
    }

    pub(super) fn log_transition(&self, k: u64, transition: Option<Transition>, in_row: u32) {
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

    pub(super) fn log_invalid(&mut self) {
        while let Some(r) = self.ep.next_invalid() {
            log(format_args!(
                "rejected command seq {} ({}); it is never applied. Further rejections of this kind are counted, not logged",
                r.msg.seq, r.kind
            ));
        }
    }

    /// A status line on a terminal, four times a second.
    pub(super) fn live_status(&mut self) {
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

    pub(super) fn live_status_end(&self) {
        if std::io::stderr().is_terminal() {
            eprintln!();
        }
    }
}
