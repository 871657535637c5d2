//! Reaction wheels against closed forms (docs/maths.md, "Reaction wheels"): a free body's
//! world momentum kept while its wheels spin up, a wheel on a principal axis, friction
//! decaying a wheel (Coulomb and viscous exactly, Stribeck against the scalar model), the
//! motor's limits in Basilisk's order, and momentum kept over a whole saturating flight.

use eqtrack_controller::group::{BuiltinGroup, MatrixLieGroup, Se3, So3};
use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, Vector3};
use plant::wheels::{Gyrostat, LIMIT_CYCLE_SPEED, MAX_WHEELS, Wheel, WheelError};

const PERIOD: f64 = 0.01;
const SUBSTEPS: usize = 10;

/// An SO(3) spacecraft's inertia with products of inertia (the repository's spacecraft).
fn spacecraft() -> Matrix3<f64> {
    Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759)
}

/// Four wheels in a pyramid, each 30° off the body's x-y plane.
fn pyramid(w: Wheel) -> Vec<Wheel> {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]]
        .iter()
        .map(|a| Wheel { axis: *a, ..w })
        .collect()
}

/// The total angular momentum in world axes, formed from what the body reports (its velocity
/// and its wheels' relative speeds), not from its state `p`: `R (I ω + Σ J_s Ω_i g_i)`.
fn world_momentum(b: &Gyrostat<So3, 3, 3>) -> Vector3<f64> {
    let omega = b.velocity();
    let speeds = b.wheel_speeds();
    let mut h = b.inertia() * omega;
    for (w, s) in b.wheels().iter().zip(speeds) {
        h += Vector3::from(w.axis) * (w.inertia * s);
    }
    So3::rotation(b.configuration()) * h
}

fn fly(b: &mut Gyrostat<So3, 3, 3>, u: &[f64], seconds: f64) -> usize {
    let mut clamped = 0;
    for _ in 0..(seconds / PERIOD).round() as usize {
        clamped += b.command(u);
        b.advance_with(PERIOD, SUBSTEPS, |_, _, _| SVector::zeros());
    }
    clamped
}

#[test]
fn a_wheel_spun_up_on_a_free_body_keeps_the_world_momentum() {
    let wheels = pyramid(Wheel::ideal([0.0; 3], 0.02, 0.1, 600.0));
    let mut b = Gyrostat::<So3, 3, 3>::new(
        spacecraft(),
        &wheels,
        &[10.0, -20.0, 0.0, 5.0],
        So3::exp(&Vector3::new(0.3, -0.2, 1.1)),
        Vector3::new(0.4, -0.3, 0.2),
    )
    .unwrap();
    let h0 = world_momentum(&b);
    let omega0 = b.velocity();
    fly(&mut b, &[0.05, -0.03, 0.02, 0.0], 5.0);
    let h1 = world_momentum(&b);
    assert!(
        (h1 - h0).norm() < 1e-12 * h0.norm(),
        "world momentum {h1} vs {h0}"
    );
    // the wheels took momentum from the body: its rate changed, the wheels' speeds too
    assert!((b.velocity() - omega0).norm() > 0.05, "{}", b.velocity());
    assert!((b.wheel_speeds()[0] - 10.0).abs() > 5.0);
}

#[test]
fn one_wheel_on_a_principal_axis_gives_the_closed_form_rate() {
    // a body at rest, one wheel along its third principal axis, a constant motor torque u:
    // p stays 0, so ω_z = −u t/(I₃ − J_s), Ω = u t I₃/(J_s (I₃ − J_s)), and the body turns
    // by −u t²/(2 (I₃ − J_s)) about z
    let (i3, js, u) = (4.0, 0.1, 0.05);
    let inertia = Matrix3::from_diagonal(&Vector3::new(2.0, 3.0, i3));
    let wheel = Wheel::ideal([0.0, 0.0, 1.0], js, 1.0, 1e4);
    let mut b = Gyrostat::<So3, 3, 3>::new(
        inertia,
        &[wheel],
        &[0.0],
        Matrix3::identity(),
        Vector3::zeros(),
    )
    .unwrap();
    let t = 3.0;
    fly(&mut b, &[u], t);
    let free = i3 - js;
    let v = b.velocity();
    assert!((v[2] + u * t / free).abs() < 1e-12, "ω_z {}", v[2]);
    assert!(v[0].abs() < 1e-15 && v[1].abs() < 1e-15, "{v}");
    let omega = b.wheel_speeds()[0];
    let expected = u * t * i3 / (js * free);
    assert!(
        (omega - expected).abs() < 1e-10 * expected,
        "Ω {omega} vs {expected}"
    );
    let angle = -u * t * t / (2.0 * free);
    let r = So3::exp(&Vector3::new(0.0, 0.0, angle));
    assert!(
        (b.configuration() - r).amax() < 1e-12,
        "{}",
        b.configuration()
    );
}

/// A body at rest in total (p = 0) with one wheel on its third principal axis spinning at
/// `omega0`: the body counter-rotates, and the wheel's speed obeys the scalar equation
/// `J_eff Ω̇ = u − f(Ω)`, `J_eff = J_s (I₃ − J_s)/I₃`.
fn lone_wheel(wheel: Wheel, omega0: f64) -> (Gyrostat<So3, 3, 3>, f64) {
    let i3 = 1.759;
    let inertia = Matrix3::from_diagonal(&Vector3::new(0.824, 1.135, i3));
    let v = Vector3::new(0.0, 0.0, -wheel.inertia * omega0 / i3);
    let b =
        Gyrostat::<So3, 3, 3>::new(inertia, &[wheel], &[omega0], Matrix3::identity(), v).unwrap();
    assert!(b.momentum().norm() < 1e-15 * (1.0 + wheel.inertia * omega0.abs()));
    (b, wheel.inertia * (i3 - wheel.inertia) / i3)
}

#[test]
fn coulomb_and_viscous_friction_decay_a_free_wheel_exactly() {
    let wheel = Wheel {
        friction_coulomb: 0.002,
        friction_viscous: 1e-3,
        ..Wheel::ideal([0.0, 0.0, 1.0], 0.05, 0.2, 1e3)
    };
    let omega0 = 300.0;
    let (mut b, j) = lone_wheel(wheel, omega0);
    // J Ω̇ = −f_C − c_v Ω: Ω(t) = (Ω₀ + f_C/c_v) e^{−c_v t/J} − f_C/c_v while Ω > 0
    let a = wheel.friction_coulomb / wheel.friction_viscous;
    let mut t = 0.0;
    for _ in 0..6 {
        fly(&mut b, &[0.0], 10.0);
        t += 10.0;
        let exact = (omega0 + a) * (-wheel.friction_viscous * t / j).exp() - a;
        let omega = b.wheel_speeds()[0];
        assert!(
            (omega - exact).abs() < 1e-9 * omega0,
            "t = {t}: Ω {omega} vs {exact}"
        );
    }
    assert!(b.wheel_speeds()[0] < 0.5 * omega0, "the wheel slowed");
}

/// Basilisk's Stribeck curve, written out from its code: `√(2e)(f_S − f_C) e^{−(Ω/β)²/2}
/// Ω/(β√2) + f_C tanh(10Ω/β) + c_v Ω`, linear below the limit-cycle speed.
fn stribeck(w: &Wheel, omega: f64) -> f64 {
    let beta = w.stribeck_speed.unwrap();
    let curve = |x: f64| {
        (2.0 * std::f64::consts::E).sqrt()
            * (w.friction_static - w.friction_coulomb)
            * (-0.5 * (x / beta).powi(2)).exp()
            * x
            / (beta * 2f64.sqrt())
            + w.friction_coulomb * (10.0 * x / beta).tanh()
            + w.friction_viscous * x
    };
    if omega.abs() < LIMIT_CYCLE_SPEED {
        curve(LIMIT_CYCLE_SPEED) / LIMIT_CYCLE_SPEED * omega
    } else {
        curve(omega)
    }
}

#[test]
fn a_wheel_started_from_rest_meets_stribeck_friction_as_the_model_says() {
    let wheel = Wheel {
        friction_coulomb: 0.005,
        friction_static: 0.01,
        stribeck_speed: Some(0.5),
        friction_viscous: 2e-4,
        ..Wheel::ideal([0.0, 0.0, 1.0], 0.05, 0.2, 1e3)
    };
    let u = 0.012;
    let (mut b, j) = lone_wheel(wheel, 0.0);
    fly(&mut b, &[u], 2.0);
    // the scalar model J Ω̇ = u − f(Ω) by RK4 at a far finer step
    let mut omega = 0.0;
    let dt = 1e-5;
    let rate = |x: f64| (u - stribeck(&wheel, x)) / j;
    for _ in 0..200_000 {
        let k1 = rate(omega);
        let k2 = rate(omega + 0.5 * dt * k1);
        let k3 = rate(omega + 0.5 * dt * k2);
        let k4 = rate(omega + dt * k3);
        omega += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    let got = b.wheel_speeds()[0];
    assert!((got - omega).abs() < 1e-6 * omega, "Ω {got} vs {omega}");
    // the Stribeck hump mattered: without it the wheel runs ahead
    let (mut plain, _) = lone_wheel(
        Wheel {
            stribeck_speed: None,
            ..wheel
        },
        0.0,
    );
    fly(&mut plain, &[u], 2.0);
    assert!(
        plain.wheel_speeds()[0] - got > 0.01 * got,
        "{} vs {got}",
        plain.wheel_speeds()[0]
    );
}

#[test]
fn the_stribeck_branch_is_for_starting_from_rest_only() {
    let w = Wheel {
        friction_coulomb: 0.005,
        friction_static: 0.01,
        stribeck_speed: Some(0.5),
        ..Wheel::ideal([1.0, 0.0, 0.0], 0.05, 0.2, 1e3)
    };
    // from rest, speeding up: on; a wheel slowing down or turning fast never starts it
    assert!(w.stribeck(false, 0.0, 0.0));
    assert!(w.stribeck(true, 0.3, 0.1));
    assert!(!w.stribeck(true, 0.3, 0.4), "slowing down ends it");
    assert!(!w.stribeck(false, 0.3, 0.1), "it starts only near rest");
    assert!(w.stribeck(true, -0.3, -0.1), "speeding up the other way");
    assert!(!w.stribeck(true, -0.3, -0.4));
    // off without a Stribeck speed
    let plain = Wheel {
        stribeck_speed: None,
        ..w
    };
    assert!(!plain.stribeck(true, 0.0, 0.0));
    // off the branch: f_C sgn Ω + c_v Ω; linear below the limit-cycle speed
    assert_eq!(plain.friction(2.0, false), 0.005);
    assert_eq!(plain.friction(-2.0, false), -0.005);
    let small = 0.5 * LIMIT_CYCLE_SPEED;
    assert!((plain.friction(small, false) - 0.0025).abs() < 1e-15);
    // on the branch at Ω = β the hump is √e (f_S − f_C)/√2 · e^{−1/2}·… as written out
    assert!((w.friction(0.5, true) - stribeck(&w, 0.5)).abs() < 1e-15);
    assert!(w.friction(0.5, true) > w.friction(0.5, false));
}

#[test]
fn the_motor_limits_come_in_basilisks_order() {
    let w = Wheel {
        max_power: Some(5.0),
        ..Wheel::ideal([0.0, 0.0, 1.0], 0.02, 0.2, 600.0)
    };
    assert_eq!(w.limit(0.1, 10.0), (0.1, false));
    assert_eq!(w.limit(0.5, 10.0), (0.2, true), "torque");
    assert_eq!(w.limit(-0.5, 10.0), (-0.2, true));
    // power: |u Ω| ≥ P gives u = sgn(u) P/|Ω|, whatever the speed's sign
    assert_eq!(w.limit(0.1, 100.0), (0.05, true), "power");
    assert_eq!(w.limit(0.1, -100.0), (0.05, true));
    assert_eq!(w.limit(-0.1, -100.0), (-0.05, true));
    // speed: at the top speed a command that speeds the wheel up is zeroed, one that slows
    // it down passes
    assert_eq!(w.limit(0.001, 600.0), (0.0, true), "speed");
    assert_eq!(w.limit(-0.001, 600.0), (-0.001, false));
    assert_eq!(w.limit(-0.001, -600.0), (0.0, true));
    // not a number: nothing, counted
    let (u, changed) = w.limit(f64::NAN, 0.0);
    assert!(u == 0.0 && changed);
    // in the plant: the torque applied is the limited one, and each clamp is counted
    let mut b = Gyrostat::<So3, 3, 3>::new(
        spacecraft(),
        &pyramid(w),
        &[0.0; 4],
        Matrix3::identity(),
        Vector3::zeros(),
    )
    .unwrap();
    assert_eq!(b.command(&[1.0, -1.0, 0.1, 0.0]), 2);
    assert_eq!(b.applied(), &[0.2, -0.2, 0.1, 0.0]);
}

#[test]
fn the_world_momentum_is_kept_over_a_saturating_flight() {
    // four wheels driven hard back and forth, past their torque limit and into their top
    // speed, with friction (Stribeck included) and without: the world momentum stays put
    for friction in [false, true] {
        let w = Wheel {
            friction_coulomb: if friction { 0.002 } else { 0.0 },
            friction_static: if friction { 0.004 } else { 0.0 },
            stribeck_speed: friction.then_some(0.2),
            friction_viscous: if friction { 5e-5 } else { 0.0 },
            max_power: Some(20.0),
            ..Wheel::ideal([0.0; 3], 0.01, 0.1, 150.0)
        };
        let mut b = Gyrostat::<So3, 3, 3>::new(
            spacecraft(),
            &pyramid(w),
            &[0.0, 30.0, -60.0, 0.0],
            So3::exp(&Vector3::new(-1.0, 0.5, 2.0)),
            Vector3::new(0.2, 0.5, -0.3),
        )
        .unwrap();
        let h0 = world_momentum(&b);
        let (mut clamps, mut top) = (0, 0f64);
        for k in 0..3000 {
            let s = if (k / 500) % 2 == 0 { 1.0 } else { -1.0 };
            clamps += b.command(&[0.3 * s, -0.25 * s, 0.15, -0.05 * s]);
            b.advance_with(PERIOD, SUBSTEPS, |_, _, _| SVector::zeros());
            top = b.wheel_speeds()[..4]
                .iter()
                .fold(top, |a, x| a.max(x.abs()));
        }
        let h1 = world_momentum(&b);
        assert!(
            (h1 - h0).norm() < 1e-9 * h0.norm(),
            "friction {friction}: {h1} vs {h0}"
        );
        assert!(clamps > 3000, "the torque limit acted: {clamps}");
        assert!(top >= 150.0 - 1.0, "a wheel reached its top speed: {top}");
        assert!(top < 155.0, "and stayed near it: {top}");
    }
}

#[test]
fn on_se3_the_wheels_turn_the_body_and_keep_its_spatial_momentum() {
    let mut inertia = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::from([
        0.3, 0.4, 0.5, 4.0, 4.0, 4.0,
    ]));
    // the body origin away from the centre of mass: rotation–translation coupling
    let c = Vector3::new(0.02, -0.01, 0.05);
    let cx = c.cross_matrix() * 4.0;
    inertia.fixed_view_mut::<3, 3>(0, 3).copy_from(&cx);
    inertia
        .fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&cx.transpose());
    let mut q = Matrix4::identity();
    q.fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&Vector3::new(5.0, -3.0, 2.0));
    let wheels = pyramid(Wheel::ideal([0.0; 3], 0.005, 0.05, 400.0));
    let mut b = Gyrostat::<Se3, 4, 6>::new(
        inertia,
        &wheels,
        &[0.0; 4],
        q,
        SVector::from([0.1, 0.0, -0.2, 0.3, 0.1, 0.0]),
    )
    .unwrap();
    let spatial = |b: &Gyrostat<Se3, 4, 6>| {
        Se3::adjoint(&Se3::inverse(b.configuration())).transpose() * b.momentum()
    };
    let mu0 = spatial(&b);
    let w0 = b.velocity();
    for _ in 0..500 {
        b.command(&[0.02, 0.01, -0.03, 0.0]);
        b.advance_with(PERIOD, SUBSTEPS, |_, _, _| SVector::zeros());
    }
    assert!(
        (spatial(&b) - mu0).amax() < 1e-10 * mu0.amax(),
        "{} vs {mu0}",
        spatial(&b)
    );
    assert!((b.velocity() - w0).fixed_rows::<3>(0).norm() > 0.01);
}

#[test]
fn bad_wheels_are_refused_by_name() {
    let good = Wheel::ideal([0.0, 0.0, 1.0], 0.02, 0.1, 600.0);
    let build = |w: Wheel| {
        Gyrostat::<So3, 3, 3>::new(
            spacecraft(),
            &[w],
            &[0.0],
            Matrix3::identity(),
            Vector3::zeros(),
        )
        .err()
    };
    assert_eq!(build(good), None);
    assert_eq!(
        build(Wheel {
            axis: [0.0; 3],
            ..good
        }),
        Some(WheelError::Axis(0))
    );
    assert_eq!(
        build(Wheel {
            axis: [f64::NAN, 0.0, 1.0],
            ..good
        }),
        Some(WheelError::Axis(0))
    );
    for js in [0.0, -1.0, f64::INFINITY] {
        assert_eq!(
            build(Wheel {
                inertia: js,
                ..good
            }),
            Some(WheelError::Inertia(0))
        );
    }
    // a wheel whose spin inertia is the body's about its axis leaves nothing free
    assert_eq!(
        build(Wheel {
            inertia: 1.759,
            ..good
        }),
        Some(WheelError::FreeInertia)
    );
    let field = |w: Wheel| match build(w) {
        Some(WheelError::Parameter(0, f)) => f,
        other => panic!("{other:?}"),
    };
    assert_eq!(
        field(Wheel {
            max_torque: 0.0,
            ..good
        }),
        "max_torque"
    );
    assert_eq!(
        field(Wheel {
            max_torque: f64::NAN,
            ..good
        }),
        "max_torque"
    );
    assert_eq!(
        field(Wheel {
            max_speed: -1.0,
            ..good
        }),
        "max_speed"
    );
    assert_eq!(
        field(Wheel {
            max_power: Some(0.0),
            ..good
        }),
        "max_power"
    );
    assert_eq!(
        field(Wheel {
            friction_coulomb: -0.1,
            ..good
        }),
        "friction_coulomb"
    );
    assert_eq!(
        field(Wheel {
            friction_static: f64::NAN,
            ..good
        }),
        "friction_static"
    );
    assert_eq!(
        field(Wheel {
            friction_viscous: f64::INFINITY,
            ..good
        }),
        "friction_viscous"
    );
    assert_eq!(
        field(Wheel {
            stribeck_speed: Some(0.0),
            ..good
        }),
        "stribeck_speed"
    );
    let many = vec![good; MAX_WHEELS + 1];
    assert_eq!(
        Gyrostat::<So3, 3, 3>::new(
            spacecraft(),
            &many,
            &[0.0; MAX_WHEELS + 1],
            Matrix3::identity(),
            Vector3::zeros()
        )
        .err(),
        Some(WheelError::Count(MAX_WHEELS + 1))
    );
    assert_eq!(
        Gyrostat::<So3, 3, 3>::new(
            spacecraft(),
            &[good],
            &[f64::NAN],
            Matrix3::identity(),
            Vector3::zeros()
        )
        .err(),
        Some(WheelError::Speeds)
    );
}

#[test]
fn the_allocated_wheel_torques_turn_the_body_as_the_law_asks() {
    // a turning body with turning wheels: the controller allocates the law's torque τ with the
    // wheels' gyroscopic torque added, and over a short step the body answers as the rigid
    // body of inertia J = I − Σ J_s g gᵀ would: J ω̇ + ω × J ω = τ
    use eqtrack_allocation::{Allocator, Geometry, Priority, Restoring, Status, VehicleControl};
    let wheels = pyramid(Wheel::ideal([0.0; 3], 0.01, 1.0, 1e4));
    let omega = Vector3::new(0.3, -0.2, 0.4);
    let mut b = Gyrostat::<So3, 3, 3>::new(
        spacecraft(),
        &wheels,
        &[50.0, -30.0, 20.0, 10.0],
        Matrix3::identity(),
        omega,
    )
    .unwrap();
    let seen: Vec<eqtrack_allocation::Wheel<f64>> = b
        .wheels()
        .iter()
        .map(|w| eqtrack_allocation::Wheel {
            axis: w.axis,
            inertia: w.inertia,
            max_torque: w.max_torque,
            max_speed: w.max_speed,
        })
        .collect();
    let g = Geometry::<f64, 3>::with_wheels(&[], &seen).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let mut c = VehicleControl::new(alloc, Restoring::none(), 0.0, 0.01).with_wheels(&seen, 0);
    let tau = SVector::<f64, 3>::from([0.02, -0.01, 0.015]);
    let speeds = b.wheel_speeds();
    let a = c.actuate_wheeled(&tau, &Matrix3::identity(), &omega, &speeds[..4]);
    assert_eq!(a.allocation.status, Status::Met);
    let gyro = a.demand - tau;
    assert!(
        gyro.norm() > 2.0 * tau.norm(),
        "a gyroscopic torque that matters: {gyro}"
    );
    b.command(&a.allocation.u.as_slice()[..4]);
    let dt = 1e-7;
    b.advance_with(dt, 1, |_, _, _| SVector::zeros());
    let rate = (b.velocity() - omega) / dt;
    let mut j = spacecraft();
    for w in b.wheels() {
        let g = Vector3::from(w.axis);
        j -= g * g.transpose() * w.inertia;
    }
    let rigid = j * rate + omega.cross(&(j * omega)) - tau;
    assert!(
        rigid.norm() < 1e-5 * tau.norm(),
        "J ω̇ + ω × Jω − τ = {rigid}"
    );
}
