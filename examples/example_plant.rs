//! Bring your own plant: a plant process written only against `link`'s public API, shaped
//! like a hardware driver. Its "sensor" is a simulated rigid body — on SO(3) the seed
//! scenario's fixed-wing body, on SE(3) the se3_circle scenario's — so its lockstep run can be
//! compared with `plant_sim sim` bit for bit. On a board, `read_sensors` reads the IMU and
//! `drive_motors` writes the actuators. It sends no scenario fingerprint, as a board would.
//!
//! ```text
//! example_plant [RUN] [so3|se3|spacecraft] [lockstep|realtime] [SECONDS] [truth|complementary|eqf]
//!                                                  # eqtrack so3 lockstep 20 truth
//! controller_node --name RUN [--builtin se3_circle]            # in another terminal
//! ```
//!
//! `spacecraft` is a vehicle: the seed's body flown by twelve one-way thrusters (those of
//! `scenarios/spacecraft.toml`, which the controller must run: `controller_node --scenario
//! scenarios/spacecraft.toml`). The controller allocates and each command carries the
//! thrusters' commands `u_cmd`; `drive_thrusters` applies them, each within its range (on a
//! board: writes the valve or ESC outputs). The state's `applied` is the command's `accounted`.
//!
//! With `complementary` (SO(3)) the plant publishes what a board would: not the body's state
//! but the `eqtrack-estimator` crate's complementary filter run on its IMU — a gyro and two direction
//! sensors, "up" `(0, 0, 1)` and "north" `(1, 0, 0)` (`k_P = 1`, `k_I = 0.3`, unit weights,
//! TRIAD start). With `eqf` (SO(3)) the filter is the equivariant filter instead, its noise
//! model that of a common MEMS IMU (gyro 0.002 rad/s/√Hz, bias walk 1e-5 rad/s²/√Hz,
//! direction noise 0.01; TRIAD start, 0.1 rad and 0.05 rad/s initial deviations). The
//! simulated IMU is exact; on a board `read_imu` reads the real one.
//! One CSV line per tick on stdout: `k, t, Q (row-major), V, τ, status` (0 fresh, 1 held,
//! 2 safe mode).
#![cfg_attr(not(test), warn(clippy::too_many_lines))]
use eqtrack_controller::GroupKind;
use eqtrack_controller::group::{BuiltinGroup, MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::safe_mode_torque;
use link::{
    Command, DeadlinePolicy, Decision, NoCommand, PlantEndpoint, PlantEndpointConfig, Step, clock,
};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

const PERIOD: f64 = 0.01; // s: 100 Hz, the scenarios' control period
const SUBSTEPS: usize = 10; // RKMK4 steps per period, as in the scenarios
const MISS_LIMIT: u32 = 3; // consecutive misses before safe mode
const TORQUE_LIMIT: f64 = 5.0; // per axis, for the safe-mode torque: what the actuators do
const KD_SAFE: f64 = 0.5; // safe-mode damping
/// The complementary filter's world directions: "up", then "north".
const NORTH_UP: [Vector3<f64>; 2] = [Vector3::new(0.0, 0.0, 1.0), Vector3::new(1.0, 0.0, 0.0)];

/// The attitude filter run on the IMU.
enum Filter {
    /// The `complementary` variant.
    Complementary(Box<eqtrack_estimator::ComplementaryFilter<f64>>),
    /// The `eqf` variant.
    Eqf(Box<eqtrack_estimator::EquivariantFilter<f64>>),
}

impl Filter {
    fn complementary() -> Filter {
        let cfg = eqtrack_estimator::ComplementaryConfig::new(1.0, 0.3, &NORTH_UP, &[1.0, 1.0])
            .expect("valid gains and directions");
        Filter::Complementary(Box::new(eqtrack_estimator::ComplementaryFilter::new(cfg)))
    }

    fn eqf() -> Filter {
        let cfg = eqtrack_estimator::EqfConfig::new(0.002, 1e-5, &NORTH_UP, &[0.01, 0.01])
            .expect("valid noise and directions");
        Filter::Eqf(Box::new(eqtrack_estimator::EquivariantFilter::new(cfg)))
    }

    fn step(
        &mut self,
        gyro: &Vector3<f64>,
        directions: &[Vector3<f64>],
    ) -> (Matrix3<f64>, Vector3<f64>) {
        let e = match self {
            Filter::Complementary(f) => f.step(PERIOD, gyro, directions),
            Filter::Eqf(f) => f.step(PERIOD, gyro, directions),
        };
        (e.r, e.rate)
    }
}

/// The "hardware": a rigid body integrated over each period under the held torque.
struct Body<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(RigidBody<f64, G, N, M>);

impl<G: BuiltinGroup<N, M>, const N: usize, const M: usize> Body<G, N, M> {
    /// Attitude (pose) and gyro rates (on a board: read the IMU and the position fix).
    fn read_sensors(&self) -> (SMatrix<f64, N, N>, SVector<f64, M>) {
        (*self.0.configuration(), self.0.velocity())
    }
    /// The IMU: the gyro and the body-frame directions of "up" and "north" (on a board: read
    /// them from the sensors).
    fn read_imu(&self) -> (Vector3<f64>, [Vector3<f64>; 2]) {
        let q = self.0.configuration();
        let r = Matrix3::from_fn(|i, j| q[(i, j)]);
        let v = self.0.velocity();
        let unit = |d: Vector3<f64>| {
            let y = r.tr_mul(&d);
            y / y.norm()
        };
        (Vector3::new(v[0], v[1], v[2]), NORTH_UP.map(unit))
    }
    /// Applies the torque for one period (on a board: write the motor drivers).
    fn drive_motors(&mut self, torque: &SVector<f64, M>) {
        self.0.advance(torque, PERIOD, SUBSTEPS);
    }
    /// Applies the thrusters' wrench `B u` for one period (on a board: write the thruster
    /// outputs; the wrench is then the world's doing).
    fn drive_thrusters(&mut self, wrench: &SVector<f64, M>) {
        self.0.advance_with(PERIOD, SUBSTEPS, |_, _, _| *wrench);
    }
}

/// The spacecraft's twelve one-way thrusters, 0 to 3 N, 0.5 m out, two per signed body axis
/// (`scenarios/spacecraft.toml`'s).
fn thrusters() -> Vec<eqtrack_allocation::Actuator<f64>> {
    let arm = |p: [f64; 3], a: [f64; 3]| eqtrack_allocation::Actuator {
        position: p,
        axis: a,
        torque_per_thrust: 0.0,
        min: 0.0,
        max: 3.0,
    };
    let (h, z) = (0.5, 0.0);
    vec![
        arm([z, h, z], [0.0, 0.0, 1.0]),
        arm([z, -h, z], [0.0, 0.0, 1.0]),
        arm([z, z, h], [1.0, 0.0, 0.0]),
        arm([z, z, -h], [1.0, 0.0, 0.0]),
        arm([h, z, z], [0.0, 1.0, 0.0]),
        arm([-h, z, z], [0.0, 1.0, 0.0]),
        arm([z, -h, z], [0.0, 0.0, -1.0]),
        arm([z, h, z], [0.0, 0.0, -1.0]),
        arm([z, z, -h], [-1.0, 0.0, 0.0]),
        arm([z, z, h], [-1.0, 0.0, 0.0]),
        arm([-h, z, z], [0.0, -1.0, 0.0]),
        arm([h, z, z], [0.0, -1.0, 0.0]),
    ]
}

/// A vehicle's actuators: their allocator (for the safe mode's damping) and the commands held.
struct Thrusters {
    allocator: eqtrack_allocation::Allocator<f64, 3>,
    u: eqtrack_allocation::Commands<f64>,
    /// What the law counts as applied (the next state's `applied`).
    accounted: Vector3<f64>,
}

impl Thrusters {
    fn new() -> Thrusters {
        let geometry =
            eqtrack_allocation::Geometry::new(&thrusters()).expect("a spanning geometry");
        Thrusters {
            allocator: eqtrack_allocation::Allocator::new(
                geometry,
                &[],
                &[],
                eqtrack_allocation::Priority::Torque,
            )
            .expect("default weights"),
            u: eqtrack_allocation::Commands::zeros(),
            accounted: Vector3::zeros(),
        }
    }

    /// The decision's thruster commands: a fresh command's (each within its range), the held
    /// ones, or the safe-mode damping allocated here. Returns the wrench `B u`.
    fn decide(
        &mut self,
        decision: Decision,
        got: Option<Command>,
        v: &Vector3<f64>,
    ) -> Vector3<f64> {
        let (lo, hi) = self.allocator.geometry().bounds();
        match (decision, got) {
            (Decision::Fresh, Some(c)) => {
                self.u = eqtrack_allocation::Commands::from_fn(|j, _| {
                    c.msg.u_cmd[j].clamp(lo[j], hi[j])
                });
                self.accounted = Vector3::from_fn(|i, _| c.msg.accounted[i]);
            }
            (Decision::Safe, _) => {
                let kd = Matrix3::identity() * KD_SAFE;
                let limit = Vector3::repeat(TORQUE_LIMIT);
                let a = self
                    .allocator
                    .allocate(&safe_mode_torque(&kd, v, Some(&limit)));
                self.u = a.u;
                self.accounted = a.achieved;
            }
            _ => {}
        }
        self.allocator.geometry().effectiveness() * self.u
    }
}

fn main() -> std::process::ExitCode {
    let arg = |i: usize, default: &str| std::env::args().nth(i).unwrap_or(default.to_owned());
    let (run, group, mode) = (arg(1, "eqtrack"), arg(2, "so3"), arg(3, "lockstep"));
    let steps = (arg(4, "20").parse::<f64>().unwrap_or(20.0) / PERIOD).round() as u64;
    let realtime = mode == "realtime";
    let filter = match arg(5, "truth").as_str() {
        "truth" => None,
        "complementary" if group == "so3" => Some(Filter::complementary()),
        "eqf" if group == "so3" => Some(Filter::eqf()),
        other => {
            eprintln!(
                "example_plant: the 5th argument is truth, complementary or eqf (so3 only), got `{other}`"
            );
            return std::process::ExitCode::from(2);
        }
    };
    let r = |x: f64, y: f64, z: f64| Vector3::new(x, y, z);
    let result = if group == "spacecraft" {
        let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759);
        let q0 = So3::exp(&(r(0.8, 0.6, 0.0) * (std::f64::consts::PI - 0.1)));
        let body = Body::<So3, 3, 3>(RigidBody::new(inertia, q0, r(4.0, -3.0, 2.0)).expect("ok"));
        fly_vehicle(&run, realtime, steps, body)
    } else if group == "se3" {
        let inertia = SMatrix::<f64, 6, 6>::from_diagonal(&[0.8, 1.0, 1.2, 2.0, 2.0, 2.0].into());
        let mut q0 = SMatrix::<f64, 4, 4>::identity();
        q0.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&So3::exp(&r(1.2, -0.9, 1.3)));
        q0.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&r(2.0, -1.0, 1.2));
        let v0 = [1.0, -0.5, 0.3, 0.0, 0.5, -1.0].into();
        let body = Body::<Se3, 4, 6>(RigidBody::new(inertia, q0, v0).expect("a valid body"));
        fly(&run, GroupKind::Se3, realtime, steps, body, None)
    } else {
        let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759);
        let q0 = So3::exp(&(r(0.8, 0.6, 0.0) * (std::f64::consts::PI - 0.1)));
        let body = Body::<So3, 3, 3>(RigidBody::new(inertia, q0, r(4.0, -3.0, 2.0)).expect("ok"));
        fly(&run, GroupKind::So3, realtime, steps, body, filter)
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("example_plant: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn fly<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    run: &str,
    group: GroupKind,
    realtime: bool,
    steps: u64,
    mut body: Body<G, N, M>,
    mut filter: Option<Filter>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut plant = PlantEndpoint::open(PlantEndpointConfig::new(run, group, PERIOD))?;
    let mut ticks = Ticks::new(realtime);
    let kd = SMatrix::<f64, M, M>::identity() * KD_SAFE;
    let limit = SVector::<f64, M>::repeat(TORQUE_LIMIT);
    let mut torque = SVector::<f64, M>::zeros();
    for k in 0..=steps {
        // 1. Read the sensors and publish the state: the exact one, or the filter's estimate
        //    from the IMU (SO(3): n = m = 3), with the torque applied over the last period.
        let (q, v) = body.read_sensors();
        match &mut filter {
            None => {
                plant.publish(k, &q, &v, &torque)?;
            }
            Some(f) => {
                let (gyro, directions) = body.read_imu();
                let (r, rate) = f.step(&gyro, &directions);
                let q_hat = SMatrix::<f64, N, N>::from_fn(|i, j| r[(i, j)]);
                let v_hat = SVector::<f64, M>::from_fn(|i, _| rate[i]);
                plant.publish(k, &q_hat, &v_hat, &torque)?;
            }
        }
        // 2. Wait for the torque (until the tick ends in real time; in lockstep as long as it
        //    takes, up to 10 s), then apply it, hold the last one, or fall back to the
        //    safe-mode torque (real time; lockstep applies every command it waited for).
        let (got, step) = ticks.command(&mut plant, k)?;
        torque = match (step.decision, got) {
            (Decision::Fresh, Some(cmd)) => cmd.torque(),
            (Decision::Safe, _) => safe_mode_torque(&kd, &v, Some(&limit)),
            _ => torque,
        };
        let (t, qs, vs, ts) = (k as f64 * PERIOD, q.transpose(), csv(&v), csv(&torque));
        println!("{k},{t:?},{},{vs},{ts},{}", csv(&qs), step.decision.code());
        // 4. Drive the motors over [t_k, t_k+1), then wait for the next tick.
        if k < steps {
            body.drive_motors(&torque);
        }
        ticks.end(k);
    }
    plant.shutdown();
    Ok(())
}

/// The plant's clock and deadline policy: when a tick ends, and what it applies.
struct Ticks {
    realtime: bool,
    policy: DeadlinePolicy,
    /// The clock starts with the controller's first answer.
    t0: u64,
}

impl Ticks {
    fn new(realtime: bool) -> Ticks {
        Ticks {
            realtime,
            policy: DeadlinePolicy::new(MISS_LIMIT),
            t0: 0,
        }
    }

    fn period_ns() -> u64 {
        (PERIOD * 1e9) as u64
    }

    /// Command k: waited for until the tick ends in real time; in lockstep (and for the
    /// first command) as long as it takes, up to 10 s. With the policy's decision (lockstep
    /// applies every command it waited for).
    fn command(
        &mut self,
        plant: &mut PlantEndpoint,
        k: u64,
    ) -> Result<(Option<Command>, Step), Box<dyn std::error::Error>> {
        let deadline = if self.realtime && k > 0 {
            self.t0 + (k + 1) * Self::period_ns()
        } else {
            clock::monotonic_ns() + 10_000_000_000
        };
        let got = match plant.wait_command(k, deadline) {
            Ok(cmd) => Some(cmd),
            Err(NoCommand::Missed) if self.realtime && k > 0 => None,
            Err(NoCommand::Missed) => return Err(format!("no command for tick {k}").into()),
            Err(NoCommand::Refused(r)) => return Err(r.to_string().into()),
        };
        if k == 0 {
            self.t0 = clock::monotonic_ns();
        }
        let step = if self.realtime {
            self.policy
                .step(k, deadline, got.as_ref().map(|c| c.arrival()))
        } else {
            Step::LOCKSTEP
        };
        Ok((got, step))
    }

    /// Waits for tick k's end (real time only).
    fn end(&self, k: u64) {
        if self.realtime {
            clock::sleep_until(self.t0 + (k + 1) * Self::period_ns());
        }
    }
}

/// [`fly`] for the spacecraft: the commands carry thruster commands, which drive the
/// thrusters; the state's `applied` is what the law counts as applied.
fn fly_vehicle(
    run: &str,
    realtime: bool,
    steps: u64,
    mut body: Body<So3, 3, 3>,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut thrusters = Thrusters::new();
    let mut config = PlantEndpointConfig::new(run, GroupKind::So3, PERIOD);
    config.actuators = thrusters.allocator.geometry().count() as u32;
    let mut plant = PlantEndpoint::open(config)?;
    let mut ticks = Ticks::new(realtime);
    for k in 0..=steps {
        let (q, v) = body.read_sensors();
        plant.publish(k, &q, &v, &thrusters.accounted)?;
        let (got, step) = ticks.command(&mut plant, k)?;
        let wrench = thrusters.decide(step.decision, got, &v);
        let (t, qs, vs, ts) = (k as f64 * PERIOD, q.transpose(), csv(&v), csv(&wrench));
        println!("{k},{t:?},{},{vs},{ts},{}", csv(&qs), step.decision.code());
        if k < steps {
            body.drive_thrusters(&wrench);
        }
        ticks.end(k);
    }
    plant.shutdown();
    Ok(())
}

/// Numbers in full round-trip precision, comma-separated (column-major: transpose first).
fn csv<const R: usize, const C: usize>(xs: &SMatrix<f64, R, C>) -> String {
    xs.iter()
        .map(|x| format!("{x:?}"))
        .collect::<Vec<_>>()
        .join(",")
}
