//! Reaction wheels as columns of `B` (docs/maths.md, "Reaction wheels"): their columns and
//! bounds, wheels alone turning a spacecraft, the gyroscopic torque, and bounds that close at
//! a wheel's top speed.

use eqtrack_allocation::{
    Actuator, Allocator, Geometry, GeometryError, MAX_ACTUATORS, Momentum, Priority, Restoring,
    Status, VehicleControl, Wheel, presets,
};
use nalgebra::{Matrix3, SVector, Vector3};

/// Four wheels in a pyramid, 30° off the x-y plane.
fn pyramid() -> Vec<Wheel<f64>> {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]]
        .iter()
        .map(|a| Wheel {
            axis: *a,
            inertia: 0.01,
            max_torque: 0.1,
            max_speed: 600.0,
        })
        .collect()
}

#[test]
fn a_wheel_is_a_pure_torque_column_after_the_thrusters() {
    let thrusters = presets::rov_heavy(0.4, 0.3, 0.1, 0.2, 40.0);
    let wheels = [Wheel {
        axis: [0.0, 0.0, 2.0],
        inertia: 0.01,
        max_torque: 0.2,
        max_speed: 600.0,
    }];
    let g = Geometry::<f64, 6>::with_wheels(&thrusters, &wheels).unwrap();
    let j = thrusters.len();
    assert_eq!(g.count(), j + 1);
    let b = g.effectiveness();
    // the motor's torque u on the wheel puts −u g on the body, no force
    assert_eq!(
        b.column(j).into_owned(),
        SVector::<f64, 6>::from([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])
    );
    let (lo, hi) = g.bounds();
    assert_eq!((lo[j], hi[j]), (-0.2, 0.2));
    // the thrusters' columns are those of the geometry without wheels
    let plain = Geometry::<f64, 6>::new(&thrusters).unwrap();
    assert_eq!(
        b.columns(0, j).into_owned(),
        plain.effectiveness().columns(0, j).into_owned()
    );
}

#[test]
fn wheels_alone_turn_a_spacecraft_but_cannot_push_it() {
    let g = Geometry::<f64, 3>::with_wheels(&[], &pyramid()).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let tau = SVector::<f64, 3>::from([0.05, -0.03, 0.08]);
    let a = alloc.allocate(&tau);
    assert_eq!(a.status, Status::Met);
    assert!((a.achieved - tau).amax() < 1e-12);
    // more than four wheels give: the torque's direction is kept as near as they can
    let far = alloc.allocate(&(tau * 10.0));
    assert_ne!(far.status, Status::Met);
    assert!(far.u.iter().take(4).all(|u| u.abs() <= 0.1 + 1e-15));
    // on SE(3) wheels give no force
    match Geometry::<f64, 6>::with_wheels(&[], &pyramid()) {
        Err(GeometryError::DoesNotSpan(lost)) => assert_eq!(lost.directions().len(), 3),
        other => panic!("{other:?}"),
    }
    // three coplanar wheels leave a torque out
    let flat: Vec<Wheel<f64>> = pyramid()
        .into_iter()
        .map(|w| Wheel {
            axis: [w.axis[0], w.axis[1], 0.0],
            ..w
        })
        .collect();
    assert!(matches!(
        Geometry::<f64, 3>::with_wheels(&[], &flat),
        Err(GeometryError::DoesNotSpan(_))
    ));
}

#[test]
fn bad_wheel_columns_are_refused_by_column() {
    let thrusters = presets::spacecraft_twelve(0.5, 3.0);
    let mut w = pyramid();
    assert!(matches!(
        Geometry::<f64, 3>::with_wheels(&thrusters, &w),
        Err(GeometryError::Count { count: 16 })
    ));
    w[2].axis = [0.0; 3];
    assert!(matches!(
        Geometry::<f64, 3>::with_wheels(&thrusters[..4], &w),
        Err(GeometryError::ZeroAxis { index: 6 })
    ));
    w[2].axis = [1.0, 0.0, 0.0];
    w[1].max_torque = f64::NAN;
    assert!(matches!(
        Geometry::<f64, 3>::with_wheels(&thrusters[..4], &w),
        Err(GeometryError::NonFinite { index: 5, .. })
    ));
    assert!(matches!(
        Geometry::<f64, 3>::with_wheels(&[] as &[Actuator<f64>], &[]),
        Err(GeometryError::Count { count: 0 })
    ));
    assert!(thrusters.len() + 4 > MAX_ACTUATORS);
}

fn wheeled() -> VehicleControl<f64, 3> {
    let g = Geometry::<f64, 3>::with_wheels(&[], &pyramid()).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    VehicleControl::new(alloc, Restoring::none(), 0.0, 0.01).with_wheels(&pyramid(), 0)
}

#[test]
fn the_demand_cancels_the_wheels_gyroscopic_torque() {
    let mut c = wheeled();
    let omega = Vector3::new(0.1, -0.05, 0.08);
    let speeds = [30.0, -20.0, 10.0, 0.0];
    // by hand: h_i = J_s (g_iᵀω + Ω_i), τ_g = ω × Σ h_i g_i
    let mut h = Vector3::zeros();
    for (w, s) in pyramid().iter().zip(speeds) {
        let g = Vector3::from(w.axis);
        h += g * (w.inertia * (g.dot(&omega) + s));
    }
    let gyro = omega.cross(&h);
    assert!(gyro.norm() > 1e-3, "a torque worth cancelling: {gyro}");
    let tau = SVector::<f64, 3>::from([0.01, 0.02, -0.01]);
    let a = c.actuate_wheeled(&tau, &Matrix3::identity(), &omega, &speeds);
    assert!((a.demand - tau - gyro).amax() < 1e-15, "{}", a.demand);
    assert_eq!(a.allocation.status, Status::Met);
    assert!((a.allocation.achieved - a.demand).amax() < 1e-12);
    // without wheels nothing is added
    let plain = Allocator::new(
        Geometry::<f64, 3>::with_wheels(&[], &pyramid()).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap();
    let mut none = VehicleControl::new(plain, Restoring::none(), 0.0, 0.01);
    let b = none.actuate_wheeled(&tau, &Matrix3::identity(), &omega, &speeds);
    assert_eq!(b.demand, tau);
}

#[test]
fn a_wheel_at_its_top_speed_is_not_sped_up() {
    let mut c = wheeled();
    let omega = Vector3::zeros();
    // wheel 0 at its top speed, wheel 2 just below it the other way round
    let speeds = [600.0, 0.0, -599.99, 0.0];
    // ask for a torque that would want wheel 0 faster (u₀ > 0 gives −u₀ g₀ on the body)
    let g0 = Vector3::from(pyramid()[0].axis);
    let tau = -g0 * 0.05;
    let a = c.actuate_wheeled(
        &SVector::from([tau[0], tau[1], tau[2]]),
        &Matrix3::identity(),
        &omega,
        &speeds,
    );
    let u = a.allocation.u;
    assert!(u[0] <= 0.0, "wheel 0 sped up past its top speed: {}", u[0]);
    // wheel 2 may speed up (more negative) only by what one period leaves,
    // J_s (Ω_max − |Ω|)/h = 0.01 × 0.01 / 0.01, and the demand holds it there
    assert!((u[2] + 0.01).abs() < 1e-12, "{}", u[2]);
    assert_ne!(a.allocation.status, Status::Met);
    // at rest the same demand takes wheel 2 further: the bound was what held it
    let mut rested = wheeled();
    let b = rested.actuate_wheeled(
        &SVector::from([tau[0], tau[1], tau[2]]),
        &Matrix3::identity(),
        &omega,
        &[0.0; 4],
    );
    assert!(b.allocation.u[2] < -0.011, "{}", b.allocation.u[2]);
    // a speed that is not a number holds its wheel at 0
    let b = c.actuate_wheeled(
        &SVector::from([0.05, 0.0, 0.0]),
        &Matrix3::identity(),
        &omega,
        &[f64::NAN, 0.0, 0.0, 0.0],
    );
    assert_eq!(b.allocation.u[0], 0.0);
    assert!(b.allocation.u.iter().all(|x| x.is_finite()));
}

#[test]
fn the_null_space_moves_the_wheels_and_leaves_the_torque() {
    let omega = Vector3::new(0.02, -0.01, 0.03);
    let speeds = [120.0, -40.0, 10.0, 60.0];
    let tau = SVector::<f64, 3>::from([0.004, -0.002, 0.003]);
    let mut plain = wheeled();
    let mut managed = wheeled().with_momentum(Momentum {
        null_gain: 0.05,
        bias: [100.0, -100.0, 100.0, -100.0, 0.0, 0.0],
        dump_threshold: 0.0,
        dump_gain: 0.0,
    });
    let a = plain.actuate_wheeled(&tau, &Matrix3::identity(), &omega, &speeds);
    let b = managed.actuate_wheeled(&tau, &Matrix3::identity(), &omega, &speeds);
    assert_eq!(a.allocation.status, Status::Met);
    assert_eq!(b.allocation.status, Status::Met);
    // the same torque on the body, to rounding
    assert!((a.allocation.achieved - b.allocation.achieved).amax() < 1e-15);
    let g = Geometry::<f64, 3>::with_wheels(&[], &pyramid()).unwrap();
    assert!((g.wrench(&b.allocation.u) - g.wrench(&a.allocation.u)).amax() < 1e-15);
    // the difference lies along the null space (1, −1, 1, −1) and pushes the speeds'
    // null-space error toward the bias: e = Ω − Ω_bias = (20, 60, −90, 160), whose part
    // along n is (20 − 60 − 90 − 160)/4 = −72.5 per wheel: the wheels speed up along n
    let d = b.allocation.u - a.allocation.u;
    let n = [1.0, -1.0, 1.0, -1.0];
    for i in 0..4 {
        assert!((d[i] - d[0] * n[i]).abs() < 1e-15, "{d}");
    }
    // −k J_s P e = −0.05 × 0.01 × (−72.5) n (within the bounds: nothing saturates)
    assert!((d[0] - 0.05 * 0.01 * 72.5).abs() < 1e-12, "{}", d[0]);
}

#[test]
fn a_dump_puts_the_thrusters_against_the_wheels_momentum() {
    // six one-way thrusters, one per signed axis, and the pyramid
    let thrusters: Vec<Actuator<f64>> = presets::spacecraft_twelve(0.5, 0.01)[..6].to_vec();
    let g = Geometry::<f64, 3>::with_wheels(&thrusters, &pyramid()).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let m = Momentum {
        null_gain: 0.0,
        bias: [0.0; 6],
        dump_threshold: 0.05,
        dump_gain: 0.2,
    };
    let mut c = VehicleControl::new(alloc, Restoring::none(), 0.0, 0.01)
        .with_wheels(&pyramid(), 6)
        .with_momentum(m);
    // wheels holding 0.06 N·m·s along +z, the body still
    let speeds = [3.0, 3.0, 3.0, 3.0];
    let h = pyramid()
        .iter()
        .zip(speeds)
        .fold(Vector3::zeros(), |h, (w, s)| {
            h + Vector3::from(w.axis) * (w.inertia * s)
        });
    assert!(h.norm() > 0.05);
    let tau = SVector::<f64, 3>::from([0.001, 0.0, 0.0]);
    let a = c.actuate_wheeled(&tau, &Matrix3::identity(), &Vector3::zeros(), &speeds);
    let b = *g.effectiveness();
    let mut thrust = a.allocation.u;
    thrust.rows_mut(6, 6).fill(0.0);
    let dump = b * thrust;
    // the thrusters' torque is −k_d (|h| − h_thr) ĥ
    let want = -h * (0.2 * (h.norm() - 0.05) / h.norm());
    assert!(
        (dump - SVector::<f64, 3>::from([want.x, want.y, want.z])).amax() < 1e-12,
        "{dump} vs {want}"
    );
    // and the body still gets the law's torque: the wheels cancel the thrusters'
    assert!((a.allocation.achieved - tau).amax() < 1e-12);
    // below the threshold, the thrusters rest
    let slow = [1.0; 4];
    let quiet = c.actuate_wheeled(&tau, &Matrix3::identity(), &Vector3::zeros(), &slow);
    assert!(
        quiet.allocation.u.iter().take(6).all(|x| *x == 0.0),
        "{}",
        quiet.allocation.u
    );
}
