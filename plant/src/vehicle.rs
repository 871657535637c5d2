//! Vehicle physics on the plant side (docs/maths.md, "Vehicle physics"): what the world does
//! to the body — gravity, buoyancy, drag — and its actuators' lag and failures, integrated
//! inside the RKMK4 substeps with the rigid body (whose inertia includes any added mass:
//! Kirchhoff's equations are Euler–Poincaré on SE(3) with the total inertia).

use crate::SimError;
use crate::trajectory::{EstimateRow, Row, SimulatedTrajectory, Terms, VehicleRow, input};
use crate::wheels::{MAX_WHEELS, Wheel, Wheels};
use eqtrack_allocation::{Actuation, Commands, MAX_ACTUATORS, Restoring, VehicleControl};
use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::integrator::RigidBody;
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use scenario::Scenario;
use scenario::vehicle::{FailureKind, FailureSpec};
use serde::Serialize;

/// What the world does to the body: gravity and buoyancy (known to the controller, which
/// compensates them) and drag. `M` is the group's dimension: 3 (SO(3), torques only) or 6
/// (SE(3), torque then force).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Environment<const M: usize> {
    /// Gravity and buoyancy.
    pub restoring: Restoring<f64>,
    /// Fossen's linear damping `D_l` (diagonal), in `(ω, v)` order.
    pub damping_linear: SVector<f64, M>,
    /// Fossen's quadratic damping `D_q` (diagonal), in `(ω, v)` order.
    pub damping_quadratic: SVector<f64, M>,
}

impl<const M: usize> Environment<M> {
    /// No gravity, no buoyancy, no drag: the ideal floating body.
    pub fn none() -> Self {
        Environment {
            restoring: Restoring::none(),
            damping_linear: SVector::zeros(),
            damping_quadratic: SVector::zeros(),
        }
    }

    /// Gravity and buoyancy as a body wrench at rotation `r` ([`Restoring::wrench`]).
    pub fn restoring(&self, r: &Matrix3<f64>) -> SVector<f64, M> {
        self.restoring.wrench(r)
    }

    /// Drag at body velocity `v`, in Fossen's diagonal form: `−(D_l v + D_q |v|∘v)`.
    pub fn drag(&self, v: &SVector<f64, M>) -> SVector<f64, M> {
        -(self.damping_linear.component_mul(v)
            + self
                .damping_quadratic
                .component_mul(&v.abs().component_mul(v)))
    }

    /// Everything the world does: [`Environment::restoring`] plus [`Environment::drag`].
    pub fn wrench(&self, r: &Matrix3<f64>, v: &SVector<f64, M>) -> SVector<f64, M> {
        self.restoring(r) + self.drag(v)
    }
}

/// The actuators as the plant drives them: the command held over a period, the output
/// following it with a first-order lag, failed ones stuck.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuators<const M: usize> {
    /// The effectiveness matrix (`eqtrack_allocation::Geometry::effectiveness`).
    b: SMatrix<f64, M, MAX_ACTUATORS>,
    /// The lag's time constant `T` (s); 0: the output is the command.
    time_constant: f64,
    /// The output at the start of the period, `u(t_k)`.
    output: Commands<f64>,
    /// The command held over the period, `u_cmd`.
    command: Commands<f64>,
    /// Whether a command has come (at `t = 0` the output starts at the first command).
    started: bool,
    /// Failed actuators: their stuck values.
    stuck: [Option<f64>; MAX_ACTUATORS],
    /// Each actuator's effectiveness: its thrust is its output times this (1 until a loss of
    /// effectiveness; `x × 1` is `x` exactly, so a healthy run's numbers are unchanged).
    factor: Commands<f64>,
}

impl<const M: usize> Actuators<M> {
    /// Actuators with effectiveness `b` and lag time constant `time_constant` (s, ≥ 0).
    pub fn new(b: SMatrix<f64, M, MAX_ACTUATORS>, time_constant: f64) -> Self {
        Actuators {
            b,
            time_constant: time_constant.max(0.0),
            output: Commands::zeros(),
            command: Commands::zeros(),
            started: false,
            stuck: [None; MAX_ACTUATORS],
            factor: Commands::from_element(1.0),
        }
    }

    /// Actuator `j` loses effectiveness from now on: its thrust becomes `factor` times its
    /// output, which still follows its command.
    pub fn lose(&mut self, j: usize, factor: f64) {
        if j < MAX_ACTUATORS {
            self.factor[j] = factor;
        }
    }

    /// Actuator `j` fails, stuck at `value` from now on: its output jumps there and stays.
    pub fn fail(&mut self, j: usize, value: f64) {
        if j < MAX_ACTUATORS {
            self.stuck[j] = Some(value);
            self.output[j] = value;
            self.command[j] = value;
        }
    }

    /// Holds command `u_cmd` over the period that starts now (a failed actuator keeps its
    /// stuck value). The first command is also the output at `t = 0`.
    pub fn command(&mut self, u_cmd: &Commands<f64>) {
        self.command = *u_cmd;
        for (j, s) in self.stuck.iter().enumerate() {
            if let Some(v) = s {
                self.command[j] = *v;
            }
        }
        // without lag the output jumps to the command at t_k; with lag it starts there
        if !self.started || self.time_constant <= 0.0 {
            self.output = self.command;
            self.started = true;
        }
    }

    /// The output `s` seconds into the period: the exact first-order response
    /// `u(s) = u_cmd + (u(t_k) − u_cmd) e^{−s/T}` (the command itself when `T` = 0).
    pub fn output_at(&self, s: f64) -> Commands<f64> {
        if self.time_constant <= 0.0 {
            return self.command;
        }
        let decay = (-s / self.time_constant).exp();
        self.command + (self.output - self.command) * decay
    }

    /// The output at the start of the period, `u(t_k)`.
    pub fn output(&self) -> &Commands<f64> {
        &self.output
    }

    /// The thrust the actuators produce at the start of the period: the output times each
    /// actuator's effectiveness.
    pub fn produced(&self) -> Commands<f64> {
        self.output.component_mul(&self.factor)
    }

    /// The actuators' wrench `B (f ∘ u(s))`, `s` seconds into the period (`f` each
    /// actuator's effectiveness).
    pub fn wrench_at(&self, s: f64) -> SVector<f64, M> {
        self.b * self.output_at(s).component_mul(&self.factor)
    }

    /// Ends a period of length `h`: the output moves on to `u(t_k + h)`.
    pub fn end_period(&mut self, h: f64) {
        self.output = self.output_at(h);
    }
}

/// Advances `body` by one period `h` in `substeps` RKMK4 steps under the actuators' wrench
/// (lagging inside the period), the environment's (at every stage's state) and a further
/// body wrench `extra` held over the period; then ends the actuators' period.
pub fn step<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    body: &mut RigidBody<f64, G, N, M>,
    environment: &Environment<M>,
    actuators: &mut Actuators<M>,
    extra: &SVector<f64, M>,
    h: f64,
    substeps: usize,
) {
    step_in_world::<G, N, M>(body, environment, actuators, extra, None, h, substeps);
}

/// [`step`] with a wrench `world` constant in world axes at the body's origin as well
/// (rotated into the body at every stage).
pub fn step_in_world<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    body: &mut RigidBody<f64, G, N, M>,
    environment: &Environment<M>,
    actuators: &mut Actuators<M>,
    extra: &SVector<f64, M>,
    world: Option<&SVector<f64, M>>,
    h: f64,
    substeps: usize,
) {
    advance::<G, N, M>(
        body,
        None,
        environment,
        actuators,
        (extra, world),
        h,
        substeps,
    );
}

/// [`step_in_world`], with the reaction wheels `wheels` integrated beside the body when given
/// (docs/maths.md, "Reaction wheels").
fn advance<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    body: &mut RigidBody<f64, G, N, M>,
    wheels: Option<&mut Wheels>,
    environment: &Environment<M>,
    actuators: &mut Actuators<M>,
    (extra, world): (&SVector<f64, M>, Option<&SVector<f64, M>>),
    h: f64,
    substeps: usize,
) {
    let a = *actuators;
    let outside = |s: f64, q: &SMatrix<f64, N, N>, v: &SVector<f64, M>| {
        let r = G::rotation(q);
        let mut w = a.wrench_at(s) + environment.wrench(&r, v) + extra;
        if let Some(world) = world {
            w += G::rotate_coordinates(&r.transpose(), world);
        }
        w
    };
    match wheels {
        None => body.advance_with(h, substeps, outside),
        Some(wheels) => wheels.advance(body, h, substeps, outside),
    }
    actuators.end_period(h);
}

/// A scenario's vehicle, both sides, as the simulation drives it: the controller's
/// allocation and the plant's actuators and environment, and the failures still to come.
pub struct VehicleRun<const M: usize> {
    /// The controller's side.
    pub control: VehicleControl<f64, M>,
    /// The plant's actuators.
    pub actuators: Actuators<M>,
    /// What the world does.
    pub environment: Environment<M>,
    effectiveness: SMatrix<f64, M, MAX_ACTUATORS>,
    failures: Vec<FailureSpec>,
    next_failure: usize,
    period: f64,
    count: usize,
    /// Which actuators have failed so far (the plant's).
    failed: [bool; MAX_ACTUATORS],
    /// The controller's failure detector (`[fault_detection]`; `None`: off).
    pub detector: Option<detection::Detector<f64, M>>,
    /// What it found, as `summary.json` has it.
    pub detections: Vec<DetectionReport>,
    /// `[failsafe] actuators_residual` (N·m), and whether the last allocation fell short of
    /// its torque by more (the `actuators` cause's second condition).
    residual_limit: Option<f64>,
    short: bool,
    /// The reaction wheels (`None`: the vehicle has none), the count of actuators before
    /// them, the gyroscopic torque the last demand cancelled, and how many wheel commands
    /// the plant's limits changed.
    wheels: Option<Wheels>,
    thrusters: usize,
    gyroscopic: SVector<f64, M>,
    wheel_clamps: usize,
    /// The wheels' speeds at the start of the present period.
    speeds_at_start: [f64; MAX_WHEELS],
}

impl<const M: usize> VehicleRun<M> {
    /// The vehicle of scenario `s` (`None`: it has none).
    pub fn of(s: &Scenario) -> Result<Option<Self>, SimError> {
        let Some(v) = &s.vehicle else {
            return Ok(None);
        };
        let bad = |e: String| SimError::Input(format!("scenario `{}`: {e}", s.name));
        let geometry = v.geometry::<M>().map_err(bad)?;
        // the wheels' torque on the body is integrated with them, not as a thrust
        let mut thrust = *geometry.effectiveness();
        for j in v.actuators.len()..v.count() {
            thrust.column_mut(j).fill(0.0);
        }
        Ok(Some(VehicleRun {
            control: v.control(s.control_period).map_err(bad)?,
            actuators: Actuators::new(thrust, v.actuator_time_constant),
            environment: Environment {
                restoring: v.restoring(),
                damping_linear: SVector::from_row_slice(&v.damping_linear),
                damping_quadratic: SVector::from_row_slice(&v.damping_quadratic),
            },
            effectiveness: *geometry.effectiveness(),
            failures: v.failures.clone(),
            next_failure: 0,
            period: s.control_period,
            count: geometry.count(),
            failed: [false; MAX_ACTUATORS],
            detector: s
                .detector_config::<M>()
                .map(detection::Detector::new)
                .transpose()
                .map_err(|e| bad(format!("fault_detection: {e}")))?,
            detections: Vec::new(),
            residual_limit: s.failsafe.and_then(|f| f.actuators_residual),
            short: false,
            wheels: plant_wheels(s, v).map_err(bad)?,
            thrusters: v.actuators.len(),
            gyroscopic: SVector::zeros(),
            wheel_clamps: 0,
            speeds_at_start: [0.0; MAX_WHEELS],
        }))
    }

    /// The wrench the law takes as applied over the period (its rejection terms'): the
    /// allocation's `B u_cmd` and the restoring wrench at `r_hat`, less the gyroscopic torque
    /// the demand added to cancel (the body with its wheels answers to the rest as the
    /// rigid body of inertia `J`).
    pub fn applied(&self, a: &Actuation<f64, M>, r_hat: &Matrix3<f64>) -> SVector<f64, M> {
        let applied = a.applied(&self.control.restoring(r_hat));
        match self.wheels {
            None => applied,
            Some(_) => applied - self.gyroscopic,
        }
    }

    /// The reaction wheels, if any.
    pub fn wheels(&self) -> Option<&Wheels> {
        self.wheels.as_ref()
    }

    /// Sets the wheels spinning at scenario `s`'s initial speeds relative to the body as the
    /// run starts it, at velocity `v` (a Monte Carlo draw starts elsewhere than `[initial]`).
    pub fn spin_wheels(&mut self, s: &Scenario, v: &SVector<f64, M>) {
        if let (Some(w), Some(spec)) = (self.wheels.as_mut(), &s.vehicle) {
            let speeds: Vec<f64> = spec.wheels.iter().map(|w| w.speed).collect();
            w.spin(&speeds, &Vector3::new(v[0], v[1], v[2]));
        }
    }

    /// The wheels' speeds relative to the body (their tachometers) at body velocity `v`, and
    /// how many there are (`0`: none).
    pub fn wheel_speeds(&self, v: &SVector<f64, M>) -> ([f64; MAX_WHEELS], usize) {
        match &self.wheels {
            None => ([0.0; MAX_WHEELS], 0),
            Some(w) => (w.speeds(v), w.wheels().len()),
        }
    }

    /// The law's `wrench` allocated at the estimated attitude `r_hat` and velocity `v_hat`;
    /// with wheels, their gyroscopic torque added at the speeds their tachometers read at the
    /// body's true velocity `v` (docs/maths.md, "Reaction wheels"), which
    /// [`VehicleRun::applied`] then takes out again.
    pub fn actuate(
        &mut self,
        wrench: &SVector<f64, M>,
        r_hat: &Matrix3<f64>,
        v_hat: &SVector<f64, M>,
        v: &SVector<f64, M>,
    ) -> Actuation<f64, M> {
        let Some(wheels) = &self.wheels else {
            return self.control.actuate(wrench, r_hat);
        };
        let all = wheels.speeds(v);
        let speeds = &all[..wheels.wheels().len()];
        let omega = Vector3::new(v_hat[0], v_hat[1], v_hat[2]);
        self.gyroscopic = self.control.wheels().gyroscopic(&omega, speeds);
        self.control.actuate_wheeled(wrench, r_hat, &omega, speeds)
    }

    /// Drives the wheels' motors with the wheel entries of `u_cmd` (after the thrusters), at
    /// body velocity `v` as the period starts: the plant's torque, speed and power limits
    /// clamp them (counted in `wheel_clamps`). Nothing without wheels.
    pub fn command_wheels(&mut self, u_cmd: &Commands<f64>, v: &SVector<f64, M>) {
        if let Some(wheels) = &mut self.wheels {
            self.speeds_at_start = wheels.speeds(v);
            let count = wheels.wheels().len();
            let motors = &u_cmd.as_slice()[self.thrusters..self.thrusters + count];
            self.wheel_clamps += wheels.command(motors, v);
        }
    }

    /// Integrates the body (with its wheels) over `h` in `substeps` under the actuators, the
    /// environment and the body and world disturbances (docs/maths.md, "Vehicle physics" and
    /// "Reaction wheels").
    pub fn step<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        plant: &mut RigidBody<f64, G, N, M>,
        (body, world): (&SVector<f64, M>, Option<&SVector<f64, M>>),
        h: f64,
        substeps: usize,
    ) {
        advance::<G, N, M>(
            plant,
            self.wheels.as_mut(),
            &self.environment,
            &mut self.actuators,
            (body, world),
            h,
            substeps,
        );
    }

    /// What the actuators produce at the start of the period (their outputs times their
    /// effectiveness), the wheels' entries the motor torques their drives apply after the
    /// plant's limits and failures (docs/maths.md, "Reaction wheels").
    pub fn produced(&self) -> Commands<f64> {
        let mut u = self.actuators.produced();
        if let Some(w) = &self.wheels {
            for (i, x) in w.applied().iter().enumerate() {
                u[self.thrusters + i] = *x;
            }
        }
        u
    }

    /// The failures due at `t_k` (from the first tick `t_k ≥ t − h/2`): the plant's actuator
    /// sticks, dies (stuck at 0) or loses effectiveness, and the controller is told when the
    /// failure says `reconfigure`.
    pub fn failures_at(&mut self, t_k: f64) {
        while let Some(f) = self.failures.get(self.next_failure) {
            if !f.active(t_k, self.period) {
                break;
            }
            match f.kind {
                FailureKind::Stuck | FailureKind::Dead => {
                    self.actuators.fail(f.actuator, f.value);
                    self.failed[f.actuator] = true;
                }
                FailureKind::Effectiveness { factor } => self.actuators.lose(f.actuator, factor),
            }
            // a wheel's motor fails in the wheel's own model
            if let Some(w) = &mut self.wheels
                && let Some(i) = f.actuator.checked_sub(self.thrusters)
            {
                match f.kind {
                    FailureKind::Stuck | FailureKind::Dead => w.fail(i, f.value),
                    FailureKind::Effectiveness { factor } => w.lose(i, factor),
                }
            }
            if f.reconfigure {
                match f.kind {
                    FailureKind::Effectiveness { factor } => {
                        self.control.weaken(f.actuator, factor)
                    }
                    FailureKind::Stuck | FailureKind::Dead => {
                        self.control.fail(f.actuator, f.value)
                    }
                }
            }
            self.next_failure += 1;
        }
    }

    /// The actuator count.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The detector's cycle at tick `t` (docs/maths.md, "Failure detection"), before the
    /// allocation: the state the controller sees (`v`, `r`) and the wheels' speeds at the
    /// body's true velocity `v_true` (their tachometers), and on a detection the
    /// allocator told and the detection recorded, with its latency where the scenario
    /// scripted a failure of that actuator before `t`.
    pub fn detect<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        t: f64,
        (v, r): (&SVector<f64, M>, &Matrix3<f64>),
        v_true: &SVector<f64, M>,
    ) {
        let (all, count) = self.wheel_speeds(v_true);
        let Some(d) = &mut self.detector else {
            return;
        };
        if let Some(found) = d.observe_wheeled::<G, N>(v, r, &all[..count], &mut self.control) {
            self.found(t, &found);
        }
    }

    /// Records detection `found` at tick `t`, with its latency where the scenario scripted a
    /// failure of that actuator before `t` (the pair's plant records what the commands
    /// carry).
    pub fn found(&mut self, t: f64, found: &detection::Detection<f64>) {
        let scripted = self
            .failures
            .iter()
            .rev()
            .find(|f| f.actuator == found.actuator && f.active(t, self.period))
            .map(|f| f.t);
        self.detections
            .push(DetectionReport::of(t, found, scripted));
    }

    /// `summary.json` → `vehicle` over `rows`, `h` apart, with the detections recorded and
    /// `alarms` when the scenario runs the detector (`[fault_detection]`).
    pub fn report(&self, rows: &[Row], h: f64, alarms: Option<u32>) -> VehicleReport {
        let on = self.detector.is_some();
        let mut report = VehicleReport::of(rows, &self.failures, h)
            .with_detections(on.then(|| self.detections.clone()), alarms.filter(|_| on));
        report.wheel_clamps = self.wheels.map(|_| self.wheel_clamps);
        report
    }

    /// The failures, as the scenario gives them.
    pub fn failures(&self) -> &[FailureSpec] {
        &self.failures
    }

    /// Drives the actuators with commands received from a controller, each clamped to its
    /// actuator's physical range `[min, max]` first (an allocator's answer is within it
    /// already, so this changes nothing in a healthy pair). Returns the commands applied.
    pub fn command_received(&mut self, u_cmd: &Commands<f64>) -> Commands<f64> {
        let range = self.control.allocator().bounds();
        let u = Commands::from_fn(|j, _| {
            let x = u_cmd[j];
            if j < self.count {
                x.clamp(range.lo[j], range.hi[j])
            } else {
                0.0
            }
        });
        self.actuators.command(&u);
        u
    }

    /// The actuators' wrench `B u`.
    pub fn wrench_of(&self, u: &Commands<f64>) -> SVector<f64, M> {
        self.effectiveness * u
    }

    /// The row's wheel columns: the speeds at the start of the period and the torques the
    /// motors apply over it (nothing without wheels).
    pub fn wheel_columns(&self, row: &mut VehicleRow) {
        if let Some(w) = &self.wheels {
            row.wheels = w.wheels().len();
            row.wheel_speed = self.speeds_at_start;
            row.wheel_cmd[..row.wheels].copy_from_slice(w.applied());
        }
    }

    /// The row's vehicle columns: the demand, `u_cmd`, the output `u(t_k)`, `B u_cmd`, the
    /// status.
    pub fn row(&self, a: &Actuation<f64, M>, u: &Commands<f64>) -> VehicleRow {
        let (lo, hi) = self.control.bounds();
        let mut row = VehicleRow {
            demand: [0.0; 6],
            u_cmd: [0.0; 12],
            u: [0.0; 12],
            achieved: [0.0; 6],
            status: a.allocation.status.code(),
            count: self.count,
            saturated: [false; 12],
            wheels: 0,
            wheel_speed: [0.0; 6],
            wheel_cmd: [0.0; 6],
        };
        self.wheel_columns(&mut row);
        for i in 0..M {
            row.demand[i] = a.demand[i];
            row.achieved[i] = a.allocation.achieved[i];
        }
        for j in 0..MAX_ACTUATORS {
            row.u_cmd[j] = a.allocation.u[j];
            row.u[j] = u[j];
            let x = a.allocation.u[j];
            let tol = 1e-9 * (1.0 + lo[j].abs().max(hi[j].abs()));
            row.saturated[j] =
                j < self.count && !self.failed[j] && (x <= lo[j] + tol || x >= hi[j] - tol);
        }
        row
    }
}

/// The in-process closed loop of a scenario with a `[vehicle]`
/// (docs/maths.md, "Vehicle physics"): each tick the law's wrench (with its rejection terms) goes through the
/// controller's allocation, and the plant integrates the actuators' output with gravity,
/// buoyancy, drag and the disturbances. The rows carry the vehicle columns.
pub fn simulate<G, const N: usize, const M: usize, R>(
    s: &Scenario,
    plant: RigidBody<f64, G, N, M>,
    reference: R,
    mut run: VehicleRun<M>,
    faults: &[(u64, crate::sensors::SampleFault)],
    on_step: &(dyn Fn(u64) -> Result<(), SimError> + Sync),
) -> Result<SimulatedTrajectory, SimError>
where
    G: BuiltinGroup<N, M>,
    R: eqtrack_controller::reference::Trajectory<f64, N, M>,
{
    let mut estimation = crate::estimation::Estimation::new(s, s.control_period, faults)?;
    let controller = s.controller::<G, N, M>().map_err(input(s))?;
    run.spin_wheels(s, &plant.velocity());
    let mut supervision = crate::failsafe::Supervision::of(s);
    let reference = crate::failsafe::Supervision::supervise::<G, R, N, M>(s, reference);
    let mut sim = ClosedLoop::new(controller, reference, plant, s.plant_substeps)
        .and_then(|l| l.with_rejection(s.rejection_config()))
        .map_err(input(s))?;
    let world = s.world_disturbance::<M>();
    let terms = s.rejection_config::<M>().any();
    let steps = s.steps();
    let mut rows = Vec::with_capacity(steps as usize + 1);
    let mut held = SVector::<f64, M>::zeros();
    for k in 0..=steps {
        let t = sim.time();
        run.failures_at(t);
        let (q_hat, v_hat, estimate) = match &mut estimation {
            None => (*sim.plant.configuration(), sim.plant.velocity(), None),
            Some(e) => {
                let (q, v, row) = e.measure(k, &sim.plant, &held);
                (q, v, Some(row))
            }
        };
        let r_hat = G::rotation(&q_hat);
        run.detect::<G, N>(t, (&v_hat, &r_hat), &sim.plant.velocity());
        let disarmed = supervision.as_mut().is_some_and(|sup| {
            let flags = run.failsafe_flags(estimate.as_ref());
            sup.tick(t, (&q_hat, &v_hat), flags, &mut sim.reference);
            sup.disarmed()
        });
        let body = s.disturbance_at::<M>(k);
        let mut record = None;
        let thrust = (supervision.as_ref())
            .and_then(|sup| sup.thrust_demand((&q_hat, &v_hat), &sim.reference));
        let sample = sim
            .step_actuated(&q_hat, &v_hat, |plant, wrench, h| {
                let (a, u) = run.cycle::<G, N>(
                    plant,
                    (wrench, thrust.as_ref(), (&r_hat, &v_hat), disarmed),
                    (&body, world.as_ref()),
                    (h, s.plant_substeps),
                );
                record = Some((a, u));
                run.applied(&a, &r_hat)
            })
            .map_err(|e| SimError::Run(format!("closed loop stopped at t = {t} s: {e}")))?;
        let Some((a, u)) = record else {
            return Err(SimError::Run(format!(
                "t = {t} s: the plant was not advanced"
            )));
        };
        // what the plant holds at the next tick, for its accelerometer
        let r = G::rotation(sim.plant.configuration());
        held = run.wrench_of(&run.produced())
            + run.environment.wrench(&r, &sim.plant.velocity())
            + s.disturbance_wrench::<G, N, M>(k, &r);
        let c = sim.controller.config();
        rows.push(
            Row::from_sample::<G, N, M>(&sample, c)
                .with_estimate(estimate)
                .with_terms(
                    terms.then(|| Terms::of(&sample.output.observer, &sample.output.integral)),
                )
                .with_vehicle(run.row(&a, &u), &run.wrench_of(&u)),
        );
        on_step(k)?;
    }
    Ok(SimulatedTrajectory {
        group: s.group,
        control_period: s.control_period,
        duration: s.duration,
        estimator: estimation.as_ref().map(|e| e.report(&rows)),
        vehicle: Some(run.report(
            &rows,
            s.control_period,
            run.detector.as_ref().map(|d| d.alarms()),
        )),
        rows,
        status: Vec::new(),
        failsafe: supervision,
    })
}

impl<const M: usize> VehicleRun<M> {
    /// The failsafe's flags of this tick (docs/failsafe.md, "Causes"): the estimator's health
    /// after the tick, and whether the actuators still span every wrench (after the detector's
    /// cycle). The simulation has no link.
    fn failsafe_flags(&self, estimate: Option<&EstimateRow>) -> ::failsafe::monitor::Flags {
        ::failsafe::monitor::Flags {
            link: false,
            estimator: crate::trajectory::unhealthy(estimate),
            actuators: !self.control.lost_directions().directions().is_empty() || self.short,
        }
    }

    /// One period of the vehicle: the law's `wrench` allocated at the estimated attitude
    /// `r_hat`, or the failsafe's `thrust` demand when it flies one (every actuator at its
    /// minimum when `disarmed`), the detector told the command,
    /// the actuators commanded and the plant advanced over `h` in `substeps` with the body and
    /// world disturbances. Returns the actuation and what the actuators produced at its start.
    fn cycle<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        plant: &mut RigidBody<f64, G, N, M>,
        (wrench, thrust, (r_hat, v_hat), disarmed): Asked<'_, M>,
        (body, world): (&SVector<f64, M>, Option<&SVector<f64, M>>),
        (h, substeps): (f64, usize),
    ) -> (Actuation<f64, M>, Commands<f64>) {
        let mut a = match thrust {
            Some(demand) => {
                // the thrust-axis law's demand has no gyroscopic torque in it
                self.gyroscopic = SVector::zeros();
                self.control.actuate_demand(*demand)
            }
            None => self.actuate(wrench, r_hat, v_hat, &plant.velocity()),
        };
        self.short = ::failsafe::monitor::torque_short(
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
        self.actuators.command(&a.allocation.u);
        self.command_wheels(&a.allocation.u, &plant.velocity());
        let u = self.produced();
        self.step(plant, (body, world), h, substeps);
        (a, u)
    }
}

/// What a cycle of [`VehicleRun`] is asked: the law's wrench, the failsafe's thrust demand
/// when it flies one, the estimated attitude and velocity, and whether it is disarmed.
type Asked<'a, const M: usize> = (
    &'a SVector<f64, M>,
    Option<&'a SVector<f64, M>>,
    (&'a Matrix3<f64>, &'a SVector<f64, M>),
    bool,
);

/// `summary.json` → `vehicle`: how long each actuator's command sat at a bound, how far the
/// achieved wrench fell short of the demand, and the failures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct VehicleReport {
    /// Per actuator: the time its command spent at its lower or upper bound (s), over
    /// `t_k < T` (a failed actuator's time after its failure is not counted).
    pub saturated_time_s: Vec<f64>,
    /// `‖demand − B u_cmd‖` over the rows.
    pub residual: Residual,
    /// The allocations the budget stopped before their optimum (`alloc_status` 3;
    /// docs/vehicles.md, "Bounded time"). Written only when there were some, so a run none
    /// stopped keeps the summary it wrote before the budget existed.
    #[serde(skip_serializing_if = "is_zero")]
    pub allocation_stopped: usize,
    /// The failures, as the scenario gives them.
    pub failures: Vec<FailureReport>,
    /// What the failure detector found (`[fault_detection]`; absent when it is off).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detections: Option<Vec<DetectionReport>>,
    /// The detector's alarms: each time its best hypothesis crossed the threshold, named or
    /// not (absent when it is off). In nominal flight, at most the stated rate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alarms: Option<u32>,
    /// The reaction wheels' commands the plant's limits changed (absent without wheels;
    /// docs/maths.md, "Reaction wheels").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wheel_clamps: Option<usize>,
}

/// One detection in `summary.json` (docs/vehicles.md, "Failures nobody announces").
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DetectionReport {
    /// When it was found (s).
    pub t: f64,
    /// The actuator (0-based).
    pub actuator: usize,
    /// `"dead"`, `"stuck"` or `"effectiveness"`.
    pub kind: &'static str,
    /// The stuck value estimated (0 when dead; absent for a loss of effectiveness).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// The factor estimated (a loss of effectiveness only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub factor: Option<f64>,
    /// Seconds from the scripted failure of this actuator to its detection (absent when the
    /// scenario scripted none before, or for a refinement).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency: Option<f64>,
    /// Whether it refines an earlier detection of the same actuator (its kind estimated
    /// again after a window of watching it).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub refined: bool,
}

impl DetectionReport {
    /// The report of `found` at `t`, the actuator's scripted failure at `scripted` (if any).
    pub fn of(t: f64, found: &detection::Detection<f64>, scripted: Option<f64>) -> Self {
        let (value, factor) = match found.kind {
            detection::Kind::Dead => (Some(0.0), None),
            detection::Kind::Stuck(v) => (Some(v), None),
            detection::Kind::Weak(k) => (None, Some(k)),
        };
        DetectionReport {
            t,
            actuator: found.actuator,
            kind: found.kind.name(),
            value,
            factor,
            latency: scripted.filter(|_| !found.refined).map(|at| t - at),
            refined: found.refined,
        }
    }

    /// The line `plant_sim sim` prints for it.
    pub fn line(&self) -> String {
        let what = match (self.value, self.factor) {
            (_, Some(k)) => format!("{} (factor {k:.3})", self.kind),
            (Some(v), _) if self.kind == "stuck" => format!("stuck at {v:.3}"),
            _ => self.kind.to_owned(),
        };
        let late = self
            .latency
            .map(|l| format!(", {l:.3} s after it failed"))
            .unwrap_or_default();
        let again = if self.refined { " (refined)" } else { "" };
        format!(
            "detected at t = {:.3} s: actuator {} {what}{again}{late}",
            self.t, self.actuator
        )
    }
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// The allocation residual's statistics.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Residual {
    /// The largest.
    pub max: f64,
    /// The root mean square.
    pub rms: f64,
}

/// One failure in `summary.json`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FailureReport {
    /// The actuator (0-based).
    pub actuator: usize,
    /// When (s).
    pub t: f64,
    /// How it failed, when not stuck (`"dead"`, `"effectiveness"`; absent: stuck, as before
    /// the kinds).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kind: Option<&'static str>,
    /// The stuck value (0 when dead).
    pub value: f64,
    /// A loss of effectiveness's factor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub factor: Option<f64>,
    /// Whether the allocator was told.
    pub reconfigure: bool,
}

impl VehicleReport {
    /// The same report with the detector's findings and alarms (`None`: it was off).
    pub fn with_detections(
        mut self,
        detections: Option<Vec<DetectionReport>>,
        alarms: Option<u32>,
    ) -> Self {
        self.detections = detections;
        self.alarms = alarms;
        self
    }

    /// The lines `plant_sim` prints of the detector's findings (none when it is off).
    pub fn detection_lines(&self) -> Vec<String> {
        match &self.detections {
            None => Vec::new(),
            Some(found) if found.is_empty() => {
                vec!["fault detection: no actuator failure detected".to_owned()]
            }
            Some(found) => found.iter().map(DetectionReport::line).collect(),
        }
    }

    /// The report over the rows of a run with period `h`.
    pub fn of(rows: &[Row], failures: &[FailureSpec], h: f64) -> VehicleReport {
        let count = rows
            .iter()
            .find_map(|r| r.vehicle.map(|v| v.count))
            .unwrap_or(0);
        let held = rows.len().saturating_sub(1);
        let mut saturated = vec![0.0; count];
        let (mut max, mut sum, mut n, mut stopped) = (0.0_f64, 0.0, 0usize, 0);
        for (k, v) in rows.iter().filter_map(|r| r.vehicle).enumerate() {
            stopped += usize::from(v.status == eqtrack_allocation::Status::Stopped.code());
            if k < held {
                for (j, s) in saturated.iter_mut().enumerate() {
                    if v.saturated[j] {
                        *s += h;
                    }
                }
            }
            let r: f64 = (0..6)
                .map(|i| (v.demand[i] - v.achieved[i]).powi(2))
                .sum::<f64>();
            max = max.max(r.sqrt());
            sum += r;
            n += 1;
        }
        VehicleReport {
            saturated_time_s: saturated,
            residual: Residual {
                max,
                rms: (sum / n.max(1) as f64).sqrt(),
            },
            allocation_stopped: stopped,
            detections: None,
            alarms: None,
            wheel_clamps: None,
            failures: failures
                .iter()
                .map(|f| FailureReport {
                    actuator: f.actuator,
                    t: f.t,
                    kind: (f.kind != FailureKind::Stuck).then(|| f.kind.name()),
                    value: f.value,
                    factor: match f.kind {
                        FailureKind::Effectiveness { factor } => Some(factor),
                        _ => None,
                    },
                    reconfigure: f.reconfigure,
                })
                .collect(),
        }
    }
}

/// The plant's reaction wheels of scenario `s`'s vehicle `v` (`None`: it has none), at the
/// initial body rate.
fn plant_wheels(
    s: &Scenario,
    v: &scenario::vehicle::VehicleSpec,
) -> Result<Option<Wheels>, String> {
    if v.wheels.is_empty() {
        return Ok(None);
    }
    let wheels: Vec<Wheel> = v
        .wheels
        .iter()
        .map(|w| Wheel {
            axis: w.axis,
            inertia: w.inertia,
            max_torque: w.max_torque,
            max_speed: w.max_speed,
            max_power: w.max_power,
            friction_coulomb: w.friction_coulomb,
            friction_static: w.friction_static,
            stribeck_speed: w.stribeck_speed,
            friction_viscous: w.friction_viscous,
        })
        .collect();
    let speeds: Vec<f64> = v.wheels.iter().map(|w| w.speed).collect();
    let omega = &s.initial.velocity;
    let omega = Vector3::new(omega[0], omega[1], omega[2]);
    Wheels::new(&wheels, &speeds, &omega)
        .map(Some)
        .map_err(|e| format!("vehicle.wheel: {e}"))
}
