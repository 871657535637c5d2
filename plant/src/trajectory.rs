//! The in-process closed loop and what it records per control step.

use crate::SimError;
use eqtrack_controller::GroupKind;
use eqtrack_controller::closed_loop::{ClosedLoop, Sample};
use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::{ControllerConfig, Desired};
use eqtrack_controller::reference::Trajectory;
use eqtrack_controller::tracking::{error_norms, lyapunov};
use nalgebra::{SMatrix, SVector};
use scenario::Scenario;

/// One row of `trajectory.csv`: the state and what the controller did at `t_k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// `t_k = k·control_period`.
    pub t: f64,
    /// Lyapunov function (controller's model inertia).
    pub lyapunov: f64,
    /// `‖Q_E − I‖_F`.
    pub config_error: f64,
    /// `‖p_E‖`.
    pub momentum_error: f64,
    /// `‖I − R_dᵀR‖_F`.
    pub attitude_error: f64,
    /// `‖V − V_d‖`.
    pub velocity_error: f64,
    /// `‖τ_k‖` (after saturation, without the disturbance).
    pub torque_norm: f64,
    /// `τ_k` (first m entries used).
    pub tau: [f64; 6],
    /// `Q` row-major (first n² entries used).
    pub q: [f64; 16],
    /// Body velocity (first m entries used).
    pub v: [f64; 6],
    /// The samples and the estimate the law was handed (`None`: the law saw the exact
    /// state and no sensors were simulated).
    pub estimate: Option<EstimateRow>,
    /// The disturbance-rejection terms of the command applied (`None`: the scenario has
    /// none).
    pub terms: Option<Terms>,
    /// A vehicle's allocation and actuators at `t_k` (`None`: no `[vehicle]`).
    pub vehicle: Option<VehicleRow>,
}

/// What a vehicle's allocation and actuators did at `t_k`
/// (docs/maths.md, "Control allocation"; first m wrench entries and the actuator count used).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleRow {
    /// The wrench asked of the allocator (body axes).
    pub demand: [f64; 6],
    /// The allocator's answer `u_cmd`.
    pub u_cmd: [f64; 12],
    /// The actuators' output `u` at `t_k`, after lag, limits and failures.
    pub u: [f64; 12],
    /// `B u_cmd`.
    pub achieved: [f64; 6],
    /// The allocator's status code (`eqtrack_allocation::Status`).
    pub status: u8,
    /// The number of actuators.
    pub count: usize,
    /// Which healthy actuators' commands are at a bound.
    pub saturated: [bool; 12],
    /// The number of reaction wheels (the last of the actuators).
    pub wheels: usize,
    /// The wheels' speeds relative to the body at `t_k` (rad/s).
    pub wheel_speed: [f64; 6],
    /// The motor torque each wheel's drive applied over the period from `t_k`, after the
    /// plant's limits (N·m; the command `u_cmd` unless a limit changed it).
    pub wheel_cmd: [f64; 6],
}

/// The disturbance-rejection terms of a command (body frame, first m entries used).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms {
    /// The observer's estimate `d̂` (subtracted from the law's torque).
    pub observer: [f64; 6],
    /// The integral's torque `−K_I z` (added).
    pub integral: [f64; 6],
}

impl Terms {
    /// The terms from their vectors.
    pub fn of<const M: usize>(observer: &SVector<f64, M>, integral: &SVector<f64, M>) -> Terms {
        let mut t = Terms {
            observer: [0.0; 6],
            integral: [0.0; 6],
        };
        for i in 0..M.min(6) {
            t.observer[i] = observer[i];
            t.integral[i] = integral[i];
        }
        t
    }
}

/// What the sensors read at `t_k` and what the estimator made of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimateRow {
    /// The samples.
    pub samples: crate::sensors::Samples,
    /// The estimate `Q̂` row-major (first n² entries used; the exact `Q` when the law sees
    /// the truth).
    pub q_hat: [f64; 16],
    /// The estimated body velocity `V̂` (first m entries used).
    pub v_hat: [f64; 6],
    /// The estimated gyro bias.
    pub bias_hat: [f64; 3],
    /// The attitude angle of `R̂ᵀR` (rad).
    pub estimate_error: f64,
    /// EqF: the diagonal of its covariance `Σ` (attitude rad², bias (rad/s)²).
    pub covariance: Option<[f64; 6]>,
    /// EqF: the normalised estimation error squared of the true `(R, b)`
    /// (docs/maths.md, "Consistency").
    pub nees: Option<f64>,
    /// `[estimator] gate = true`: the estimator's health after this tick.
    pub health: Option<eqtrack_estimator::health::Health>,
}

impl EstimateRow {
    /// The tick's sensor block for the flight recording: the samples and what the estimator
    /// said, beside the true state the samples were drawn from (`truth`'s `q` and `v`).
    pub fn sensor_record(&self, truth: &ipc_types::StateMsg) -> recorder::SensorRecord {
        recorder::SensorRecord {
            samples: self.samples,
            q_true: truth.q,
            v_true: truth.v,
            bias_hat: self.bias_hat,
            estimate_error: self.estimate_error,
            covariance: self.covariance,
            nees: self.nees,
        }
    }
}

impl Row {
    /// The row at `t` for the plant state `(q, v)`, the desired state and the torque held
    /// over `[t_k, t_{k+1})`. The tracking error and L are the ones the controller of
    /// configuration `c` forms (its error frame, model inertia and K), through the same
    /// functions the controller uses, so the in-process simulation and the plant process of
    /// the pair record identical numbers.
    pub fn new<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        t: f64,
        q: &SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
        desired: &Desired<f64, N, M>,
        torque: &SVector<f64, M>,
        c: &ControllerConfig<f64, N, M>,
    ) -> Row {
        let (model_inertia, k) = (&c.inertia, &c.k);
        let (error, velocity_error) = c.errors::<G>(q, v, desired);
        let n = error_norms::<G, f64, N, M>(q, &desired.q, &error, &velocity_error);
        let mut tau = [0.0; 6];
        let mut vv = [0.0; 6];
        let mut qq = [0.0; 16];
        for i in 0..M {
            tau[i] = torque[i];
            vv[i] = v[i];
        }
        for i in 0..N {
            for j in 0..N {
                qq[i * N + j] = q[(i, j)];
            }
        }
        Row {
            t,
            lyapunov: lyapunov(&error.q, &velocity_error, model_inertia, k).total,
            config_error: n.config_error,
            momentum_error: n.momentum_error,
            attitude_error: n.attitude_error,
            velocity_error: n.velocity_error,
            torque_norm: torque.norm(),
            tau,
            q: qq,
            v: vv,
            estimate: None,
            terms: None,
            vehicle: None,
        }
    }

    /// The row with the disturbance-rejection terms attached.
    pub fn with_terms(mut self, terms: Option<Terms>) -> Row {
        self.terms = terms;
        self
    }

    /// The row of a vehicle: its allocation and actuators attached, and `τ` the actuators'
    /// wrench `B u(t_k)`.
    pub fn with_vehicle<const M: usize>(
        mut self,
        vehicle: VehicleRow,
        wrench: &SVector<f64, M>,
    ) -> Row {
        for i in 0..M {
            self.tau[i] = wrench[i];
        }
        self.torque_norm = wrench.norm();
        self.vehicle = Some(vehicle);
        self
    }

    /// The row with the sensors' samples and the estimate attached.
    pub fn with_estimate(mut self, estimate: Option<EstimateRow>) -> Row {
        self.estimate = estimate;
        self
    }

    /// The row of a closed-loop sample.
    pub fn from_sample<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        s: &Sample<f64, N, M>,
        c: &ControllerConfig<f64, N, M>,
    ) -> Row {
        Row::new::<G, N, M>(s.t, &s.q, &s.v, &s.desired, &s.output.torque, c)
    }
}

/// A recorded closed-loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedTrajectory {
    /// The group (decides n and m).
    pub group: GroupKind,
    /// The control period.
    pub control_period: f64,
    /// The duration T (rows cover t = 0..T).
    pub duration: f64,
    /// One row per control step k = 0..N.
    pub rows: Vec<Row>,
    /// Real-time runs: per row, 0 = fresh command, 1 = deadline missed (torque held),
    /// 2 = safe mode. Empty otherwise (and then no `command_status` column is written).
    pub status: Vec<u8>,
    /// The estimator's report (`None`: no sensors were simulated).
    pub estimator: Option<crate::estimation::EstimatorReport>,
    /// The vehicle's report (`None`: no `[vehicle]`).
    pub vehicle: Option<crate::vehicle::VehicleReport>,
    /// The failsafe manager's run (`None`: no `[failsafe]`).
    pub failsafe: Option<crate::failsafe::Supervision>,
}

/// The time of the first row whose state, torque or Lyapunov value is not finite (`None`: the
/// run stayed finite). A run that has diverged must not end as if it had flown.
pub fn first_non_finite(traj: &SimulatedTrajectory) -> Option<f64> {
    traj.rows
        .iter()
        .find(|r| {
            !(r.lyapunov.is_finite() && r.q.iter().chain(&r.v).chain(&r.tau).all(|x| x.is_finite()))
        })
        .map(|r| r.t)
}

/// A run of the papers' world-frame law on SE(3): the first time `t_k` (k ≤ `steps`), and the
/// reference's distance from the world origin then, at which the law's damping, held over a
/// control period, stops being stable ([`eqtrack_controller::law::world_damping_holds`];
/// docs/maths.md, "Where the world-frame law breaks"). `None` for any other run, or when the
/// reference stays where the damping holds. It steps the scenario's own reference again, off
/// the control loop.
pub fn world_frame_finding(s: &Scenario, steps: u64) -> Option<(f64, f64)> {
    (s.group == eqtrack_controller::GroupKind::Se3
        && s.law == eqtrack_controller::Law::Eqt
        && s.error_frame == eqtrack_controller::ErrorFrame::World)
        .then(|| s.group.dispatch(WorldFrameFinding { s, steps }))
        .flatten()
}

struct WorldFrameFinding<'a> {
    s: &'a Scenario,
    steps: u64,
}

impl OnGroup for WorldFrameFinding<'_> {
    type Output = Option<(f64, f64)>;
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let s = self.s;
        let mut reference = s.reference_source::<G, N, M>().ok()?;
        let inertia = SMatrix::<f64, M, M>::from_row_slice(&s.model_inertia);
        let kd = SMatrix::<f64, M, M>::from_row_slice(&s.kd);
        for _ in 0..=self.steps {
            let q_d = reference.desired().q;
            if !eqtrack_controller::law::world_damping_holds::<G, f64, N, M>(
                &q_d,
                &inertia,
                &kd,
                s.control_period,
            ) {
                let x = q_d.fixed_view::<3, 1>(0, N - 1).norm();
                return Some((reference.time(), x));
            }
            reference.advance();
        }
        None
    }
}

/// Prints [`world_frame_warning`] to stderr when scenario `s`, flown for `steps` periods, has a
/// [`world_frame_finding`] (the one place `sim`, `run` and the PIL run warn from).
pub fn warn_world_frame(s: &Scenario, steps: u64) {
    if let Some(found) = world_frame_finding(s, steps) {
        eprintln!("{}", world_frame_warning(found));
    }
}

/// The one-line warning of a [`world_frame_finding`].
pub fn world_frame_warning((t, distance): (f64, f64)) -> String {
    format!(
        "warning: t = {t} s: the reference is {distance:.3} m from the world origin, where error_frame = \"world\" loses stability (see docs/maths.md); error_frame = \"reference\" does not depend on it"
    )
}

impl SimulatedTrajectory {
    /// `(n, m)` of the group.
    pub fn dims(&self) -> (usize, usize) {
        self.group.dims()
    }
}

/// Runs the scenario's closed loop in this process. `on_step(k)` is called after each step
/// (progress display; an error from it, such as [`SimError::Interrupted`], stops the run).
pub fn simulate(
    s: &Scenario,
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError> {
    simulate_planted(s, &[], on_step)
}

/// [`simulate`] with faults planted in the sensors' samples (test builds' `--fault-sample`).
pub fn simulate_planted(
    s: &Scenario,
    faults: &[(u64, crate::sensors::SampleFault)],
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError> {
    s.group.dispatch(Simulate { s, faults, on_step })
}

struct Simulate<'a> {
    s: &'a Scenario,
    faults: &'a [(u64, crate::sensors::SampleFault)],
    on_step: &'a (dyn Fn(u64) -> Result<(), SimError> + Sync),
}

impl OnGroup for Simulate<'_> {
    type Output = Result<SimulatedTrajectory, SimError>;
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let plant = self.s.plant_body::<G, N, M>().map_err(input(self.s))?;
        simulate_with_planted::<G, N, M>(self.s, plant, self.faults, self.on_step)
    }
}

/// Maps a `eqtrack-controller` error met while building scenario `s`'s parts to bad input naming the scenario.
pub fn input(s: &Scenario) -> impl Fn(eqtrack_controller::Error) -> SimError + '_ {
    move |e| SimError::Input(format!("scenario `{}`: {e}", s.name))
}

/// Runs the scenario's controller and reference against a given plant body.
pub fn simulate_with<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
    plant: RigidBody<f64, G, N, M>,
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError> {
    simulate_with_planted::<G, N, M>(s, plant, &[], on_step)
}

/// [`simulate_with`], with faults planted in the sensors' samples at the given ticks (test
/// builds' `--fault-sample`). With `[sensors]`, each tick samples the sensors from the true
/// body, steps the estimator and hands the law its estimate
/// (docs/architecture.md, "Sensors and the estimator").
pub fn simulate_with_planted<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
    plant: RigidBody<f64, G, N, M>,
    faults: &[(u64, crate::sensors::SampleFault)],
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError> {
    let reference = s.reference_source::<G, N, M>().map_err(input(s))?;
    simulate_against::<G, N, M, _>(s, plant, reference, faults, on_step)
}

/// [`simulate_with_planted`] against a given desired trajectory instead of the scenario's
/// own source: a reference computed once and shared by many runs
/// ([`eqtrack_controller::reference::Tabulated`]; the Monte Carlo study) gives the same numbers as
/// the source it was recorded from.
pub fn simulate_against<G, const N: usize, const M: usize, R>(
    s: &Scenario,
    plant: RigidBody<f64, G, N, M>,
    reference: R,
    faults: &[(u64, crate::sensors::SampleFault)],
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError>
where
    G: BuiltinGroup<N, M>,
    R: Trajectory<f64, N, M>,
{
    if let Some(run) = crate::vehicle::VehicleRun::<M>::of(s)? {
        return crate::vehicle::simulate::<G, N, M, R>(s, plant, reference, run, faults, on_step);
    }
    let mut estimation = crate::estimation::Estimation::new(s, s.control_period, faults)?;
    let controller = s.controller::<G, N, M>().map_err(input(s))?;
    let mut supervision = crate::failsafe::Supervision::of(s);
    let reference = crate::failsafe::Supervision::supervise::<G, R, N, M>(s, reference);
    let mut sim = ClosedLoop::new(controller, reference, plant, s.plant_substeps)
        .and_then(|l| l.with_disturbance(s.disturbance_vector()))
        .and_then(|l| l.with_rejection(s.rejection_config()))
        .and_then(|l| match s.world_disturbance::<M>() {
            Some(w) => l.with_world_disturbance(w),
            None => Ok(l),
        })
        .map_err(input(s))?;
    let steps = s.steps();
    let mut rows = Vec::with_capacity(steps as usize + 1);
    let mut held = SVector::<f64, M>::zeros();
    let terms = s.rejection_config::<M>().any();
    for k in 0..=steps {
        let t = sim.time();
        if !s.disturbance_steps.is_empty() {
            sim.set_disturbance(s.disturbance_at(k)).map_err(input(s))?;
        }
        let (q_hat, v_hat, estimate) = match &mut estimation {
            None => (*sim.plant.configuration(), sim.plant.velocity(), None),
            Some(e) => {
                let (q_hat, v_hat, row) = e.measure(k, &sim.plant, &held);
                (q_hat, v_hat, Some(row))
            }
        };
        if let Some(sup) = &mut supervision {
            let flags = ::failsafe::monitor::Flags {
                estimator: unhealthy(estimate.as_ref()),
                ..Default::default()
            };
            sup.tick(t, (&q_hat, &v_hat), flags, &mut sim.reference);
        }
        // (the exact state when no estimator runs: `step` itself)
        let sample = sim
            .step_measured(&q_hat, &v_hat)
            .map_err(|e| SimError::Run(format!("closed loop stopped at t = {t} s: {e}")))?;
        held = sample.output.torque
            + s.disturbance_wrench::<G, N, M>(k, &G::rotation(sim.plant.configuration()));
        let c = sim.controller.config();
        rows.push(
            Row::from_sample::<G, N, M>(&sample, c)
                .with_estimate(estimate)
                .with_terms(
                    terms.then(|| Terms::of(&sample.output.observer, &sample.output.integral)),
                ),
        );
        on_step(k)?;
    }
    Ok(SimulatedTrajectory {
        group: s.group,
        control_period: s.control_period,
        duration: s.duration,
        estimator: estimation.as_ref().map(|e| e.report(&rows)),
        rows,
        status: Vec::new(),
        vehicle: None,
        failsafe: supervision,
    })
}

/// Whether the estimator's health after this tick is anything but `healthy` (the failsafe's
/// `estimator` cause; never without the gate).
pub(crate) fn unhealthy(estimate: Option<&EstimateRow>) -> bool {
    estimate
        .and_then(|e| e.health)
        .is_some_and(|h| h != eqtrack_estimator::health::Health::Healthy)
}

/// Number of control steps with `t_k < horizon`: `Σ_{t_k < T}` ranges over these.
pub fn steps_before(horizon: f64, control_period: f64) -> usize {
    ((horizon / control_period) - 1e-9).ceil().max(0.0) as usize
}

/// Control effort over `[0, horizon)`: `Σ_{t_k < horizon} ‖τ_k‖·control_period`, over the
/// torques actually held within the run (the last row's torque at `t_N = T` is not).
pub fn effort(rows: &[Row], control_period: f64, horizon: f64) -> f64 {
    let held = rows.len().saturating_sub(1);
    rows.iter()
        .take(steps_before(horizon, control_period).min(held))
        .map(|r| r.torque_norm * control_period)
        .sum()
}

/// The first time after which `attitude_error` stays below 0.1; `None` if it does not settle
/// by the end.
pub fn settling_time(rows: &[Row]) -> Option<f64> {
    match rows.iter().rposition(|r| r.attitude_error >= 0.1) {
        None => rows.first().map(|r| r.t),
        Some(i) if i + 1 < rows.len() => Some(rows[i + 1].t),
        Some(_) => None,
    }
}
