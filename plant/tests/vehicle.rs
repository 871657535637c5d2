//! Vehicle physics against closed forms (docs/maths.md, "Vehicle physics"): free fall, an
//! exact hover, neutral buoyancy with the centre of buoyancy above the centre of mass (a
//! pendulum), terminal velocity under drag, and Kirchhoff's equations with added mass
//! (energy and spatial momentum conserved).

use eqtrack_allocation::{Allocator, Commands, Geometry, Priority, Restoring, presets};
use eqtrack_controller::group::{BuiltinGroup, MatrixLieGroup, Se3};
use eqtrack_controller::integrator::RigidBody;
use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3};
use plant::vehicle::{Actuators, Environment, step};

const G: f64 = 9.81;
const H: f64 = 0.01;

fn inertia(j: [f64; 3], m: f64) -> SMatrix<f64, 6, 6> {
    SMatrix::from_diagonal(&SVector::<f64, 6>::from([j[0], j[1], j[2], m, m, m]))
}

fn body(i: SMatrix<f64, 6, 6>, q: Matrix4<f64>, v: [f64; 6]) -> RigidBody<f64, Se3, 4, 6> {
    RigidBody::new(i, q, SVector::from(v)).unwrap()
}

/// Gravity on a body of mass `m`, nothing else.
fn falling(m: f64) -> Environment<6> {
    Environment {
        restoring: Restoring {
            weight: m * G,
            ..Restoring::none()
        },
        ..Environment::none()
    }
}

fn no_actuators() -> Actuators<6> {
    Actuators::new(SMatrix::zeros(), 0.0)
}

fn position(b: &RigidBody<f64, Se3, 4, 6>) -> Vector3<f64> {
    b.configuration().fixed_view::<3, 1>(0, 3).into_owned()
}

#[test]
fn free_fall_follows_half_g_t_squared() {
    let m = 2.0;
    let env = falling(m);
    let mut b = body(inertia([0.1, 0.2, 0.3], m), Matrix4::identity(), [0.0; 6]);
    let mut act = no_actuators();
    for _ in 0..100 {
        step(&mut b, &env, &mut act, &SVector::zeros(), H, 10);
    }
    // t = 1 s: z = −g/2, v_z = −g (the body does not turn: no torque)
    let t = 1.0;
    assert!(
        (position(&b) - Vector3::new(0.0, 0.0, -0.5 * G * t * t)).amax() < 1e-12,
        "{}",
        position(&b)
    );
    let v = b.velocity();
    assert!(
        (v - SVector::<f64, 6>::from([0.0, 0.0, 0.0, 0.0, 0.0, -G * t])).amax() < 1e-12,
        "{v}"
    );
}

#[test]
fn the_hexarotor_hovers_exactly_on_the_allocated_commands() {
    let m = 1.5;
    let env = falling(m);
    let rotors = presets::hexarotor(0.25, 0.5, 0.016, 8.0);
    let geometry = Geometry::<f64, 6>::new(&rotors).unwrap();
    let alloc = Allocator::new(geometry, &[], &[], Priority::Torque).unwrap();
    // tilted by 0.3 rad about x: the demand is minus the known wrench at that attitude
    let r = Se3::rotation(&tilted(0.3));
    let demand = -env.restoring(&r);
    let a = alloc.allocate(&demand);
    for lag in [0.0, 0.05] {
        let mut act = Actuators::new(*geometry.effectiveness(), lag);
        let mut b = body(inertia([0.02, 0.02, 0.04], m), tilted(0.3), [0.0; 6]);
        for _ in 0..200 {
            act.command(&a.u);
            step(&mut b, &env, &mut act, &SVector::zeros(), H, 10);
        }
        assert!(
            position(&b).amax() < 1e-10,
            "lag {lag}: drifted to {}",
            position(&b)
        );
        assert!(b.velocity().amax() < 1e-10, "lag {lag}: {}", b.velocity());
    }
}

fn tilted(angle: f64) -> Matrix4<f64> {
    let mut q = Matrix4::identity();
    q.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::new(
        1.0,
        0.0,
        0.0,
        0.0,
        angle.cos(),
        -angle.sin(),
        0.0,
        angle.sin(),
        angle.cos(),
    ));
    q
}

#[test]
fn neutral_buoyancy_above_the_centre_of_mass_is_a_pendulum() {
    let (m, h, jx) = (10.0, 0.05, 0.4);
    let env = Environment {
        restoring: Restoring {
            weight: m * G,
            buoyancy: m * G,
            centre: Vector3::new(0.0, 0.0, h),
        },
        ..Environment::<6>::none()
    };
    // the restoring torque at a tilt θ about x is −B h sin θ, and no net force
    for theta in [0.1, 0.7, 2.0] {
        let w = env.restoring(&Se3::rotation(&tilted(theta)));
        let want = SVector::<f64, 6>::from([-m * G * h * theta.sin(), 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert!((w - want).amax() < 1e-12, "θ = {theta}: {w}");
    }
    // small oscillations: the period 2π √(J / (B h)), the energy ½Jθ̇² + Bh(1 − cos θ) kept
    let theta0: f64 = 0.01;
    let mut b = body(inertia([jx, 0.5, 0.6], m), tilted(theta0), [0.0; 6]);
    let mut act = no_actuators();
    let energy = |b: &RigidBody<f64, Se3, 4, 6>| {
        let r = Se3::rotation(b.configuration());
        0.5 * jx * b.velocity()[0].powi(2) + m * G * h * (1.0 - r[(2, 2)])
    };
    let e0 = energy(&b);
    let (mut crossings, mut last_sign, mut first, mut last) = (0, 1.0, 0.0, 0.0);
    let mut t = 0.0;
    while crossings < 9 {
        let before = b.velocity()[0];
        step(&mut b, &env, &mut act, &SVector::zeros(), H, 10);
        t += H;
        let after = b.velocity()[0];
        // the angular velocity changes sign at each turning point (every half period)
        if after.signum() != last_sign && before != 0.0 {
            let at = t - H * after / (after - before);
            if crossings == 0 {
                first = at;
            }
            last = at;
            crossings += 1;
            last_sign = after.signum();
        }
        assert!(
            (energy(&b) - e0).abs() < 1e-9 * e0,
            "energy {} drifted from {e0}",
            energy(&b)
        );
    }
    let period = 2.0 * (last - first) / (crossings - 1) as f64;
    let want = 2.0 * std::f64::consts::PI * (jx / (m * G * h)).sqrt();
    assert!(
        (period / want - 1.0).abs() < 1e-4,
        "period {period} s, small-angle {want} s"
    );
    assert!(
        position(&b).amax() < 1e-12,
        "no net force: the centre of mass stays put"
    );
}

#[test]
fn drag_brings_a_falling_body_to_its_terminal_velocity() {
    let m = 3.0;
    for (linear, quadratic, want) in [
        (6.0, 0.0, -m * G / 6.0),
        (0.0, 4.0, -(m * G / 4.0_f64).sqrt()),
    ] {
        let mut env = falling(m);
        env.damping_linear[5] = linear;
        env.damping_quadratic[5] = quadratic;
        let mut b = body(inertia([0.1, 0.1, 0.1], m), Matrix4::identity(), [0.0; 6]);
        let mut act = no_actuators();
        for _ in 0..3000 {
            step(&mut b, &env, &mut act, &SVector::zeros(), H, 4);
        }
        let v = b.velocity()[5];
        assert!(
            (v - want).abs() < 1e-6 * want.abs(),
            "terminal velocity {v}, closed form {want}"
        );
    }
}

#[test]
fn with_added_mass_energy_and_spatial_momentum_are_conserved() {
    // a rigid body plus a symmetric positive-definite added mass with rotation–translation
    // coupling: Kirchhoff's equations, Euler–Poincaré with the total inertia
    let rigid = inertia([0.3, 0.4, 0.5], 5.0);
    let mut added = SMatrix::<f64, 6, 6>::zeros();
    for (i, x) in [0.05, 0.08, 0.1, 2.0, 4.0, 6.0].iter().enumerate() {
        added[(i, i)] = *x;
    }
    added[(0, 4)] = 0.3;
    added[(4, 0)] = 0.3;
    added[(2, 3)] = -0.2;
    added[(3, 2)] = -0.2;
    let total = rigid + added;
    let mut b = body(total, tilted(0.4), [0.3, -0.5, 0.8, 0.6, 0.2, -0.4]);
    let env = Environment::<6>::none();
    let mut act = no_actuators();
    let energy = |b: &RigidBody<f64, Se3, 4, 6>| 0.5 * b.velocity().dot(&(total * b.velocity()));
    let spatial = |b: &RigidBody<f64, Se3, 4, 6>| {
        // Ad*_{Q⁻¹} p: the momentum in the world frame
        Se3::adjoint(&Se3::inverse(b.configuration())).transpose() * b.state().p
    };
    let (e0, mu0) = (energy(&b), spatial(&b));
    for _ in 0..500 {
        step(&mut b, &env, &mut act, &SVector::zeros(), H, 10);
    }
    assert!(
        (energy(&b) - e0).abs() < 1e-9 * e0,
        "energy {} vs {e0}",
        energy(&b)
    );
    assert!(
        (spatial(&b) - mu0).amax() < 1e-9 * mu0.amax(),
        "spatial momentum {} vs {mu0}",
        spatial(&b)
    );
}

#[test]
fn the_lag_follows_the_exact_first_order_response_and_a_failure_sticks() {
    let mut b = SMatrix::<f64, 6, 12>::zeros();
    b[(5, 0)] = 1.0;
    let mut act = Actuators::<6>::new(b, 0.1);
    let mut cmd = Commands::zeros();
    cmd[0] = 2.0;
    act.command(&cmd);
    // the first command is the output at t = 0
    assert_eq!(act.output()[0], 2.0);
    cmd[0] = 5.0;
    act.command(&cmd);
    let want = 5.0 + (2.0 - 5.0) * (-0.03_f64 / 0.1).exp();
    assert!((act.output_at(0.03)[0] - want).abs() < 1e-15);
    act.end_period(0.03);
    assert!((act.output()[0] - want).abs() < 1e-15);
    act.fail(0, 0.5);
    assert_eq!(act.output()[0], 0.5);
    act.command(&cmd);
    assert_eq!(act.output_at(0.07)[0], 0.5, "a failed actuator stays stuck");
}

#[test]
fn a_lagging_thrust_gives_the_impulse_of_its_exact_response() {
    // a free body, one thruster along +x through the centre, from 0 to F with time constant T:
    // over the period h the impulse is F (h − T(1 − e^{−h/T})), evaluated at every stage's time
    let (m, f, tc) = (2.0, 3.0, 0.004);
    let mut b6 = SMatrix::<f64, 6, 12>::zeros();
    b6[(3, 0)] = 1.0;
    let mut act = Actuators::<6>::new(b6, tc);
    act.command(&Commands::zeros());
    act.end_period(H);
    let mut cmd = Commands::zeros();
    cmd[0] = f;
    act.command(&cmd);
    let mut b = body(inertia([0.1, 0.1, 0.1], m), Matrix4::identity(), [0.0; 6]);
    step(
        &mut b,
        &Environment::none(),
        &mut act,
        &SVector::zeros(),
        H,
        10,
    );
    let want = f * (H - tc * (1.0 - (-H / tc).exp())) / m;
    // RK4 integrates the exponential to its own accuracy (h/T = 1/4 per substep here)
    assert!(
        (b.velocity()[3] - want).abs() < 1e-5 * want,
        "{} vs {want}",
        b.velocity()[3]
    );
}
