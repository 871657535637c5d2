//! The law on one group: the reference, the controller and its rejection terms, and the last
//! state answered (the terms update only on consecutive states, as in the pair).

use crate::watch::Watcher;
use crate::{Config, ConfigError, Dropped, Failure, MAX_SEQ_JUMP};
use eqtrack_allocation::{Commands, VehicleControl};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::{Controller, Reference, Rejection};
use eqtrack_estimator::health::{Gate, Health};
use eqtrack_serial_wire::{Allocation, CommandFrame, Estimate, Samples, StateFrame};
use heapless::Vec;
use nalgebra::{SMatrix, SVector, Vector3};

/// In this order (`repr(C)`): the detector last ([`Engine::watcher`]).
#[repr(C)]
pub(crate) struct Engine<G, const N: usize, const M: usize> {
    controller: Controller<f32, G, N, M>,
    start: Reference<f32, G, N, M>,
    reference: Reference<f32, G, N, M>,
    rejection_start: Option<Rejection<f32, M>>,
    rejection: Option<Rejection<f32, M>>,
    previous: Option<u64>,
    law: u8,
    filter_start: Option<eqtrack_estimator::Filter<f32>>,
    filter: Option<eqtrack_estimator::Filter<f32>>,
    /// The step of the samples the filter took last (its next step spans the gap).
    filtered: Option<u64>,
    /// The innovation gate and health monitor, where the estimator has one, as at start and
    /// now; the health after the last step.
    gate_start: Option<Gate<f32>>,
    gate: Option<Gate<f32>>,
    health: Health,
    vehicle_start: Option<VehicleControl<f32, M>>,
    vehicle: Option<VehicleControl<f32, M>>,
    /// The actuator count and the failures the controller is told of, and which of them it
    /// has been told (each once, so that what the detector finds later stands).
    failures: Vec<Failure, 12>,
    told: [bool; 12],
    /// The allocator's columns (thrusters, then wheels) and, of them, the reaction wheels:
    /// a state must carry one speed per wheel.
    actuators: usize,
    wheels: usize,
    /// The failsafe manager and what it flies, where the configuration has one, as at start
    /// and now.
    manager_start: Option<Manager<G, N, M>>,
    manager: Option<Manager<G, N, M>>,
    /// The failure detector, where the configuration has one (and the crate is built with
    /// it, feature `detector`). Last: it is kilobytes, and with it last the other fields stay
    /// within a load's reach of the engine's address on a Cortex-M4F, however it grows.
    watcher: Option<Watcher<M>>,
}

/// The failsafe manager on the firmware (docs/failsafe.md, "In the pair and on the firmware"):
/// the monitor, the set-point it flies, and the span test of the actuators (run again only
/// when a failure is told or found).
#[derive(Clone)]
struct Manager<G, const N: usize, const M: usize> {
    monitor: failsafe::monitor::Monitor<f32>,
    setpoint: failsafe::setpoint::Setpoint<f32, G, N, M>,
    span: eqtrack_allocation::SpanWatch<f32, M>,
    /// The thrust-axis law `descend` flies once a direction of control is lost (SE(3),
    /// a vehicle with weight).
    thrust: Option<failsafe::thrust_axis::ThrustAxis<f32>>,
    /// `actuators_residual`, and whether the last allocation fell short of its torque by
    /// more (`failsafe::monitor::torque_short`).
    residual_limit: Option<f32>,
    short: bool,
    /// The wrench the host reports in the next state's `applied` if it applied the last
    /// command: its `accounted` with a vehicle, its `tau` without. Another raises `link`.
    sent: Option<SVector<f32, M>>,
}

fn vec<const C: usize>(xs: &[f32]) -> Vec<f32, C> {
    // every caller's slice fits: at most 6 entries into capacity 6
    Vec::from_slice(&xs[..xs.len().min(C)]).unwrap_or_default()
}

impl<G: BuiltinGroup<N, M>, const N: usize, const M: usize> Engine<G, N, M> {
    pub(crate) fn new(config: &Config) -> Result<Self, ConfigError> {
        let controller = config.controller::<G, N, M>()?;
        let reference = config.reference::<G, N, M>()?;
        let rejection = config.rejection::<M>()?;
        let rejection = Rejection::of(rejection, controller.config().torque_limit.as_ref())?;
        let filter = match &config.estimator {
            None => None,
            Some(e) => Some(e.settings().build(N == 4).map_err(ConfigError::Estimator)?),
        };
        let gate = match config.estimator.as_ref().and_then(|e| e.gate.as_ref()) {
            None => None,
            Some(g) => Some(Gate::new(
                g.config()?,
                config.estimator.as_ref().map_or(0, |e| e.world.len()),
                N == 4,
            )),
        };
        let vehicle = match &config.vehicle {
            None => None,
            Some(v) => Some(v.control::<M>(config.identity.period as f32)?),
        };
        let watcher = Watcher::of(config, controller.config().inertia)?;
        let manager = match &config.failsafe {
            None => None,
            Some(f) => {
                let (cfg, limits) = f.manager()?;
                Some(Manager {
                    monitor: failsafe::monitor::Monitor::new(cfg, limits),
                    setpoint: failsafe::setpoint::Setpoint::new(
                        reference.desired().q,
                        controller.config().inertia,
                        failsafe::setpoint::Rates {
                            descend: f.descend_rate,
                            ascend: f.ascend_rate,
                        },
                    ),
                    span: eqtrack_allocation::SpanWatch::default(),
                    thrust: thrust_axis(config, f.lag),
                    residual_limit: f.actuators_residual,
                    sent: None,
                    short: false,
                })
            }
        };
        Ok(Engine {
            manager_start: manager.clone(),
            manager,
            told: [false; 12],
            watcher,
            filter_start: filter,
            filter,
            filtered: None,
            gate_start: gate,
            gate,
            health: Health::Healthy,
            vehicle_start: vehicle,
            vehicle,
            failures: config
                .vehicle
                .as_ref()
                .map(|v| v.failures.clone())
                .unwrap_or_default(),
            actuators: config.vehicle.as_ref().map_or(0, crate::Vehicle::count),
            wheels: config.vehicle.as_ref().map_or(0, |v| v.wheels.len()),
            controller,
            start: reference.clone(),
            reference,
            rejection_start: rejection,
            rejection,
            previous: None,
            law: config.law,
        })
    }

    /// A new run: the reference at `t = 0`, the terms as at start.
    pub(crate) fn restart(&mut self) {
        self.reference = self.start.clone();
        self.rejection = self.rejection_start;
        self.filter = self.filter_start;
        self.filtered = None;
        self.gate = self.gate_start;
        self.health = Health::Healthy;
        self.vehicle = self.vehicle_start;
        if let Some(w) = &mut self.watcher {
            w.restart();
        }
        self.told = [false; 12];
        self.previous = None;
        self.manager = self.manager_start.clone();
    }

    pub(crate) fn answer(&mut self, s: &StateFrame, period: f32) -> Result<CommandFrame, Dropped> {
        let estimates = self.filter.is_some();
        if s.applied.len() != M
            || s.samples.is_some() != estimates
            || (!estimates && (s.q.len() != N * N || s.v.len() != M))
            || s.wheel_speeds.len() != self.wheels
        {
            return Err(Dropped::Shape);
        }
        if !s.wheel_speeds.iter().all(|x| x.is_finite()) {
            return Err(Dropped::Law);
        }
        let at = self.reference.step_index();
        if s.seq < at {
            return Err(Dropped::Backwards);
        }
        if s.seq - at > MAX_SEQ_JUMP {
            return Err(Dropped::Jump);
        }
        while self.reference.step_index() < s.seq {
            self.reference.advance();
        }
        let (q, v, estimate) = match (&mut self.filter, &s.samples) {
            (Some(f), Some(samples)) => {
                // one period a state; after states lost on the line, the time since the
                // samples it took last (at most MAX_FILTER_GAP periods)
                let gap = self
                    .filtered
                    .map_or(1, |p| s.seq.saturating_sub(p).clamp(1, MAX_FILTER_GAP));
                self.filtered = Some(s.seq);
                let (e, health) =
                    estimate::<N, M>(f, self.gate.as_mut(), samples, period * gap as f32);
                self.health = health;
                (e.q, e.v, Some(e))
            }
            _ => (
                SMatrix::<f32, N, N>::from_row_slice(&s.q),
                SVector::<f32, M>::from_row_slice(&s.v),
                None,
            ),
        };
        let follows = self
            .previous
            .is_some_and(|p| p.checked_add(1) == Some(s.seq));
        // the failures told and found before the law, as the pair's controller does: the
        // failsafe manager asks whether the actuators still span every wrench
        let r_hat = G::rotation(&q);
        let mut detection = None;
        if let Some(control) = &mut self.vehicle {
            tell_failures(control, &self.failures, &mut self.told, s.t, period);
            if let Some(w) = &mut self.watcher {
                detection = Some(w.before::<G, N>(
                    control,
                    follows,
                    (&s.applied, &s.wheel_speeds),
                    &v,
                    &r_hat,
                ));
            }
        }
        let nominal = self.reference.desired();
        let (desired, word, disarmed): (_, Option<u32>, _) = match &mut self.manager {
            None => (nominal, None, false),
            Some(m) => {
                // a state lost on the line, or a command the host did not apply
                let as_sent = failsafe::monitor::applied_as_sent(
                    m.sent.as_ref().map(|w| w.as_slice()),
                    &s.applied,
                );
                let flags = failsafe::monitor::Flags {
                    link: (self.previous.is_some() && !follows) || (follows && !as_sent),
                    // the on-board estimator's health, with `gate = true`
                    estimator: self.health != Health::Healthy,
                    actuators: self.vehicle.as_ref().is_some_and(|c| m.span.lost(c)) || m.short,
                };
                let t = self.reference.time();
                m.setpoint
                    .supervise(&mut m.monitor, (&q, &v), (&nominal, t), flags);
                (
                    m.setpoint.desired(&nominal, t),
                    Some(m.monitor.state().word()),
                    m.monitor.disarmed(),
                )
            }
        };
        let out = match &mut self.rejection {
            None => self.controller.compute(&q, &v, &desired),
            Some(r) => {
                let applied = SVector::<f32, M>::from_row_slice(&s.applied);
                self.controller
                    .compute_rejecting(r, &q, &v, &desired, &applied, period, follows)
            }
        }
        .map_err(|_| Dropped::Law)?;
        self.previous = Some(s.seq);
        // the failsafe's thrust-axis law, when `descend` flies it (docs/failsafe.md)
        let thrust = match (&self.manager, word) {
            (Some(m), Some(w)) => m
                .thrust
                .and_then(|law| law.demand_when(w, (&q, &v), (&desired.q, &desired.v))),
            _ => None,
        };
        let (allocation, sent) = match &mut self.vehicle {
            None => (None, out.torque),
            Some(control) => {
                let wrench = (&out.torque, thrust.as_ref());
                let body = (&r_hat, &v, s.wheel_speeds.as_slice());
                let (allocation, accounted, u, (status, residual)) =
                    allocate(control, self.actuators, body, wrench, disarmed);
                if let Some(m) = &mut self.manager {
                    m.short = failsafe::monitor::torque_short(status, residual, m.residual_limit);
                }
                if let Some(w) = &mut self.watcher {
                    w.after(&u, accounted);
                }
                (Some(allocation), accounted)
            }
        };
        if let Some(m) = &mut self.manager {
            m.sent = Some(sent);
        }
        let terms = self.rejection.is_some();
        Ok(CommandFrame {
            seq: s.seq,
            law: self.law,
            tau: vec(out.torque.as_slice()),
            lyapunov: out.lyapunov.total,
            observer: if terms {
                vec(out.observer.as_slice())
            } else {
                Vec::new()
            },
            integral: if terms {
                vec(out.integral.as_slice())
            } else {
                Vec::new()
            },
            estimate: estimate.map(|e| Estimate {
                q: SMatrix::<f32, N, N>::from(e.q)
                    .transpose()
                    .iter()
                    .copied()
                    .collect(),
                v: vec(e.v.as_slice()),
                bias: [e.bias[0], e.bias[1], e.bias[2]],
            }),
            allocation,
            detection,
            failsafe: word,
        })
    }
}

/// The most periods one filter step spans after states lost on the line (a longer gap is a
/// restart of the samples, not a span to integrate over).
const MAX_FILTER_GAP: u64 = 100;

/// One step of the estimator on a tick's samples (docs/maths.md, "Estimators"), behind the
/// innovation gate when there is one, and the health after it
/// (docs/estimators.md, "The innovation gate and health").
fn estimate<const N: usize, const M: usize>(
    filter: &mut eqtrack_estimator::Filter<f32>,
    gate: Option<&mut Gate<f32>>,
    samples: &Samples,
    period: f32,
) -> (eqtrack_estimator::Step<f32, N, M>, Health) {
    let mut directions = [Vector3::zeros(); 4];
    for (d, x) in directions.iter_mut().zip(&samples.directions) {
        *d = Vector3::from(*x);
    }
    let accel = samples.accel.map_or_else(Vector3::zeros, Vector3::from);
    let position = samples.position.map(Vector3::from);
    let (gyro, directions) = (
        Vector3::from(samples.gyro),
        &directions[..samples.directions.len()],
    );
    match gate {
        Some(g) => {
            filter.step_gated::<N, M>(g, period, &gyro, directions, &accel, position.as_ref())
        }
        None => (
            filter.step::<N, M>(period, &gyro, directions, &accel, position.as_ref()),
            Health::Healthy,
        ),
    }
}

/// Tells the allocator of the failures the controller is told of that have started at `t`
/// (from the first `t_k ≥ t − h/2`) and are not marked in `told` (marked here: each is told
/// once).
fn tell_failures<const M: usize>(
    control: &mut VehicleControl<f32, M>,
    failures: &[Failure],
    told: &mut [bool],
    t: f64,
    period: f32,
) {
    let h = f64::from(period);
    for (f, told) in failures.iter().zip(told.iter_mut()) {
        if !*told && t >= f.t - h / 2.0 {
            *told = true;
            control.fail(usize::from(f.actuator), f.value);
        }
    }
}

/// The thrust-axis law of a configuration with a failsafe
/// (docs/failsafe.md, "The thrust-axis law"): on SE(3), for a vehicle whose weight exceeds
/// its buoyancy, from the model's mass and inertia, the net weight, the law's translational
/// gains and the actuators' time constant `lag`.
fn thrust_axis(config: &Config, lag: f32) -> Option<failsafe::thrust_axis::ThrustAxis<f32>> {
    let vehicle = config.vehicle.as_ref()?;
    if config.inertia.len() != 36 || config.k.len() != 16 || config.kd.len() != 36 {
        return None;
    }
    let j = |i: usize| config.inertia[i * 6 + i];
    failsafe::thrust_axis::ThrustAxis::new(
        j(3),
        vehicle.weight - vehicle.buoyancy,
        (j(0), j(1), j(2)),
        (config.k[15], config.kd[21]),
        lag,
    )
}

/// The law's wrench `tau` allocated to the vehicle's actuators at the attitude `r_hat`, or the
/// failsafe's `thrust` demand when it flies one (docs/maths.md, "Control allocation"; every
/// actuator at its minimum when `disarmed`, the failsafe's `disarm`), the wrench it
/// accounts for, the commands, and the status and torque residual of what was allocated
/// before any `disarm`. With reaction wheels the law's wrench gains their gyroscopic torque
/// at the body velocity `v` and the wheels' `speeds` (docs/maths.md, "Reaction wheels"),
/// which the wrench accounted for leaves out, as the pair's controller does.
fn allocate<const M: usize>(
    control: &mut VehicleControl<f32, M>,
    count: usize,
    (r_hat, v, speeds): (&nalgebra::Matrix3<f32>, &SVector<f32, M>, &[f32]),
    (tau, thrust): (&SVector<f32, M>, Option<&SVector<f32, M>>),
    disarmed: bool,
) -> (Allocation, SVector<f32, M>, Commands<f32>, (u8, f32)) {
    let mut gyroscopic = SVector::<f32, M>::zeros();
    let mut a = match thrust {
        Some(demand) => control.actuate_demand(*demand),
        None if speeds.is_empty() => control.actuate(tau, r_hat),
        None => {
            let omega = Vector3::new(v[0], v[1], v[2]);
            gyroscopic = control.wheels().gyroscopic(&omega, speeds);
            control.actuate_wheeled(tau, r_hat, &omega, speeds)
        }
    };
    // what the allocation met, before `disarm` sets the actuators to their minimum
    let met = (a.allocation.status.code(), a.torque_residual());
    if disarmed {
        control.disarm(&mut a);
    }
    let accounted = a.applied(&control.restoring(r_hat)) - gyroscopic;
    (
        Allocation {
            status: a.allocation.status.code(),
            u_cmd: Vec::from_slice(&a.allocation.u.as_slice()[..count.min(12)]).unwrap_or_default(),
            demand: vec(a.demand.as_slice()),
            achieved: vec(a.allocation.achieved.as_slice()),
            accounted: vec(accounted.as_slice()),
        },
        accounted,
        a.allocation.u,
        met,
    )
}
