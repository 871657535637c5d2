//! A vehicle on the controller's side (docs/vehicles.md, "In the pair"): the law's wrench
//! less the known restoring wrench, allocated to the actuators within their bounds, with the
//! rate limit and the failures the controller is told of, and with `[fault_detection]` the
//! failures its detector finds. The command carries the answer.

use eqtrack_allocation::{Commands, VehicleControl};
use eqtrack_controller::group::BuiltinGroup;
use failsafe::monitor::applied_as_sent;
use ipc_types::{CommandMsg, MAX_ACTUATORS, StateMsg};
use nalgebra::SVector;
use scenario::Scenario;
use scenario::vehicle::VehicleSpec;

/// The controller's vehicle between cycles.
#[derive(Debug, Clone)]
pub struct ControllerVehicle<const M: usize> {
    control: VehicleControl<f64, M>,
    spec: VehicleSpec,
    count: usize,
    /// The failure detector (docs/maths.md, "Failure detection"; `None`: off).
    detector: Option<detection::Detector<f64, M>>,
    /// The scenario its settings come from: a plant that runs another period than the
    /// scenario's (`--rate-hz`) gets a detector made for that period on its first state.
    detecting: Option<Box<Scenario>>,
    /// The wrench the last command counted as applied: the next state's `applied` says
    /// whether the plant applied that command (a held one, or safe mode, says otherwise).
    accounted: Option<SVector<f64, M>>,
    /// Which of the scenario's failures the allocator has been told of (each once).
    told: Vec<bool>,
    /// The span test of the actuators, run again only after a failure is told or found.
    span: eqtrack_allocation::SpanWatch<f64, M>,
    /// `[failsafe] actuators_residual` (N·m), and whether the last allocation fell short of
    /// its torque by more (`failsafe::monitor::torque_short`).
    residual_limit: Option<f64>,
    short: bool,
}

impl<const M: usize> ControllerVehicle<M> {
    /// The scenario's vehicle at control period `period`, without a detector. `Err`: its
    /// tables do not make an allocator on this group, which the scenario's load already
    /// refuses.
    pub fn new(spec: &VehicleSpec, period: f64) -> Result<Self, String> {
        Ok(ControllerVehicle {
            control: spec.control::<M>(period)?,
            count: spec.count(),
            spec: spec.clone(),
            detector: None,
            detecting: None,
            accounted: None,
            told: vec![false; spec.failures.len()],
            span: eqtrack_allocation::SpanWatch::default(),
            residual_limit: None,
            short: false,
        })
    }

    /// Scenario `s`'s vehicle, with its failure detector when it has `[fault_detection]`
    /// (`Scenario::detector_config`, at the scenario's period until a state says another).
    /// `Err`: no vehicle, or its tables do not make an allocator or a detector on this group.
    pub fn of(s: &Scenario) -> Result<Self, String> {
        let spec = s.vehicle.as_ref().ok_or("the scenario has no [vehicle]")?;
        let mut v = Self::new(spec, s.control_period)?;
        v.residual_limit = s.failsafe.and_then(|f| f.actuators_residual);
        if s.fault_detection.is_some() {
            v.detector = Some(detector_at::<M>(s)?);
            v.detecting = Some(Box::new(s.clone()));
        }
        Ok(v)
    }

    /// Stops running the failure detector: what it told the allocator stays, and the commands
    /// carry no findings (replay, once it cannot follow the detector).
    pub fn lose_detector(&mut self) {
        self.detector = None;
        self.detecting = None;
    }

    /// Tells the allocator what the recorded command `cmd` found, as the detector told it in
    /// that cycle (docs/maths.md, "Failure detection": what was told before of the actuator
    /// forgotten, then held at 0 or the stuck value, or its column scaled). A detection the
    /// detector queued behind another of the same cycle reached the wire a cycle after the
    /// allocator heard of it; told from the record, it comes that cycle late.
    pub fn follow(&mut self, cmd: &CommandMsg) {
        let Some(j) = (cmd.detected as usize).checked_sub(1) else {
            return;
        };
        if let Some(kind) = detection::Kind::from_code(cmd.detected_kind, cmd.detected_value) {
            kind.tell(j, &mut self.control);
        }
    }

    /// The failure detector, if it runs.
    pub fn detector(&self) -> Option<&detection::Detector<f64, M>> {
        self.detector.as_ref()
    }

    /// The actuator count (the reaction wheels' motors included, after the others).
    pub fn count(&self) -> usize {
        self.count
    }

    /// The reaction wheels' count (each state carries their speeds).
    pub fn wheels(&self) -> usize {
        self.spec.wheels.len()
    }

    /// Whether state `msg` carries as many wheel speeds as the vehicle has wheels: the
    /// gyroscopic term needs every wheel's, so a plant with other wheels is not answered.
    pub fn check_wheels(&self, msg: &StateMsg) -> Result<(), eqtrack_controller::Error> {
        if msg.wheels as usize == self.wheels() {
            Ok(())
        } else {
            Err(eqtrack_controller::Error::WrongShape {
                quantity: eqtrack_controller::Quantity::WheelSpeeds,
                expected: self.wheels(),
                found: msg.wheels as usize,
            })
        }
    }

    /// Allocates the law's wrench `tau` for state `msg` (attitude from its configuration,
    /// told failures from its `t_k`) and writes the vehicle's fields of `cmd`, the command
    /// the limit narrowed around included. With a detector, first its cycle over the
    /// period that ended at `msg`, which may tell the allocator of a failure found, as the
    /// in-process simulation does; the command carries the finding. The period counts only
    /// if the controller answered the state just before (`follows`) and the plant applied
    /// that answer (the state's `applied` is the wrench it accounted, bit for bit): over a
    /// missed state, a held command or safe mode the thrust was not what the detector
    /// believes, and it starts afresh ([`detection::Detector::gap`]). Allocation-free.
    pub fn answer<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        msg: &StateMsg,
        tau: &SVector<f64, M>,
        follows: bool,
        cmd: &mut CommandMsg,
    ) {
        self.observe::<G, N>(msg, follows, cmd);
        self.allocate::<G, N>(msg, (tau, None), false, cmd);
    }

    /// The first half of [`ControllerVehicle::answer`], before the law: the period, the
    /// failures told by now and the detector's cycle, its finding written into `cmd`.
    pub fn observe<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        msg: &StateMsg,
        follows: bool,
        cmd: &mut CommandMsg,
    ) {
        self.control.set_period(msg.control_period);
        self.spec
            .tell_failures(&mut self.control, msg.t, msg.control_period, &mut self.told);
        let r_hat = G::rotation(&msg.configuration::<N>());
        if let (Some(d), Some(s)) = (&mut self.detector, &mut self.detecting)
            && d.config().period != msg.control_period
        {
            // the plant's period (checked positive and finite by the link), met once
            s.control_period = msg.control_period;
            match detector_at::<M>(s) {
                Ok(fresh) => *d = fresh,
                // settings that do not hold at the plant's period: no detector rather than
                // one made for another period (the commands then say it does not run)
                Err(_) => self.lose_detector(),
            }
        }
        if let Some(d) = &mut self.detector {
            let applied = msg.applied_torque::<M>();
            let as_sent = applied_as_sent(
                self.accounted.as_ref().map(|a| a.as_slice()),
                applied.as_slice(),
            );
            if !(follows && as_sent) {
                d.gap();
            }
            let v = msg.velocity::<M>();
            if let Some(found) =
                d.observe_wheeled::<G, N>(&v, &r_hat, msg.wheel_speeds(), &mut self.control)
            {
                write_detection(cmd, &found);
            }
            cmd.alarms = d.alarms();
            cmd.flags |= ipc_types::flags::DETECTING;
            let last = d.statistic();
            if last.testing {
                cmd.statistic = last.best;
                cmd.suspect = last.actuator as u32 + 1;
            }
        }
    }

    /// Whether the actuators it may still move no longer span every wrench (the failsafe's
    /// `actuators` cause; docs/failsafe.md, "Causes"). The span test runs again only when the
    /// bounds or the effectiveness changed since the last call (a failure told or found).
    pub fn lost(&mut self) -> bool {
        self.span.lost(&self.control)
    }

    /// Whether the last allocation fell short of its torque by more than
    /// `[failsafe] actuators_residual` (the `actuators` cause's second condition;
    /// docs/failsafe.md, "Causes"). Never without the key.
    pub fn short(&self) -> bool {
        self.short
    }

    /// The second half of [`ControllerVehicle::answer`], after the law: the law's wrench `tau`
    /// allocated at the state's attitude, or the failsafe's `thrust` demand when it flies one
    /// (every actuator at its minimum when `disarmed`, the failsafe's `disarm`), the detector
    /// told the command, and the vehicle's fields of `cmd`.
    pub fn allocate<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        msg: &StateMsg,
        (tau, thrust): (&SVector<f64, M>, Option<&SVector<f64, M>>),
        disarmed: bool,
        cmd: &mut CommandMsg,
    ) {
        let r_hat = G::rotation(&msg.configuration::<N>());
        if let Some(p) = self.control.previous() {
            cmd.u_previous.copy_from_slice(p.as_slice());
        }
        // the wheels' gyroscopic torque, added to the demand and not counted as applied
        let mut gyroscopic = SVector::<f64, M>::zeros();
        let mut a = match thrust {
            Some(demand) => self.control.actuate_demand(*demand),
            None if self.spec.wheels.is_empty() => self.control.actuate(tau, &r_hat),
            None => {
                let v = msg.velocity::<M>();
                let omega = nalgebra::Vector3::new(v[0], v[1], v[2]);
                let speeds = msg.wheel_speeds();
                gyroscopic = self.control.wheels().gyroscopic(&omega, speeds);
                self.control.actuate_wheeled(tau, &r_hat, &omega, speeds)
            }
        };
        self.short = failsafe::monitor::torque_short(
            a.allocation.status.code(),
            a.torque_residual(),
            self.residual_limit,
        );
        if disarmed {
            self.control.disarm(&mut a);
        }
        if let Some(d) = &mut self.detector {
            d.commanded(&a.allocation.u);
        }
        let accounted = if self.spec.wheels.is_empty() {
            a.applied(&self.control.restoring(&r_hat))
        } else {
            a.applied(&self.control.restoring(&r_hat)) - gyroscopic
        };
        self.accounted = Some(accounted);
        cmd.actuators = self.count as u32;
        cmd.alloc_status = u32::from(a.allocation.status.code());
        for i in 0..M.min(ipc_types::MAX_M) {
            cmd.demand[i] = a.demand[i];
            cmd.achieved[i] = a.allocation.achieved[i];
            cmd.accounted[i] = accounted[i];
        }
        cmd.u_cmd.copy_from_slice(a.allocation.u.as_slice());
    }

    /// Restores the rate limit's memory from a recorded command (replay): the command it
    /// narrowed around, when the controller had answered before.
    pub fn restore(&mut self, cmd: &CommandMsg) {
        let previous = (cmd.previous_seq != ipc_types::NO_PREVIOUS)
            .then(|| Commands::<f64>::from_fn(|j, _| cmd.u_previous[j.min(MAX_ACTUATORS - 1)]));
        self.control.set_previous(previous);
    }
}

/// Scenario `s`'s failure detector at its control period.
fn detector_at<const M: usize>(s: &Scenario) -> Result<detection::Detector<f64, M>, String> {
    let config = s
        .detector_config::<M>()
        .ok_or("fault_detection: the vehicle does not make a detector on this group")?;
    detection::Detector::new(config).map_err(|e| format!("fault_detection: {e}"))
}

/// Writes detection `found` into the command's detection fields (docs/wire.md).
fn write_detection(cmd: &mut CommandMsg, found: &detection::Detection<f64>) {
    cmd.detected = found.actuator as u32 + 1;
    cmd.detected_kind = found.kind.code();
    cmd.detected_value = found.kind.value();
    cmd.detected_refined = u32::from(found.refined);
}
