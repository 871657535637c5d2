//! The closed loop on SO(3) and SE(3): the Lyapunov function along the loop, and the
//! equilibria of the potential on SO(3).

mod common;

use eqtrack_controller::closed_loop::{ClosedLoop, Sample};
use eqtrack_controller::group::{MatrixLieGroup, Se2, Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::reference::{AxisTorque, CosTerm, Feedforward};
use eqtrack_controller::tracking::{potential, potential_gradient};
use eqtrack_controller::{Controller, ControllerConfig, Law, Reference};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// A fully actuated rigid body on SE(3) tracking a moving, accelerating reference.
/// With `feedforward` the reference is also pushed by cosine torques and forces (it wanders
/// off over tens of seconds); without, it flies a circle of radius 1 m at 0.4 m/s, held on it
/// by the centripetal force `ω_d × m v_d = (0, 0.32, 0)` in the body frame.
fn se3_loop(period: f64, substeps: usize, feedforward: bool) -> ClosedLoop<f64, Se3, 4, 6> {
    let mut inertia = SMatrix::<f64, 6, 6>::zeros();
    // a spin about the major principal axis is steady, so the circle below stays a circle
    inertia
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::from_diagonal(&Vector3::new(0.8, 1.0, 1.2)));
    inertia
        .fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * 2.0));
    let k = SMatrix::<f64, 4, 4>::from_diagonal(&nalgebra::Vector4::new(1.6, 1.2, 1.4, 2.0));
    let mut kd = SMatrix::<f64, 6, 6>::identity() * 1.5;
    kd[(0, 1)] = 0.1;
    kd[(1, 0)] = 0.1;
    let config = ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia,
        k,
        kd,
        torque_limit: None,
    };
    let term = |a: f64, w: f64, p: f64| CosTerm {
        amplitude: a,
        frequency: w,
        phase: p,
    };
    let ff = if !feedforward {
        let mut circle = Feedforward::zero();
        circle.axes[4] = AxisTorque::constant(0.32);
        circle
    } else {
        Feedforward {
            axes: [
                AxisTorque::new(0, 0.0, &[term(0.3, 1.0, 0.0)]).unwrap(),
                AxisTorque::new(1, 0.0, &[term(0.2, 0.5, 1.0)]).unwrap(),
                AxisTorque::constant(0.0),
                AxisTorque::new(3, 0.0, &[term(0.5, 0.7, 0.0)]).unwrap(),
                AxisTorque::constant(0.0),
                AxisTorque::new(5, 0.0, &[term(0.4, 1.1, 0.3)]).unwrap(),
            ],
        }
    };
    // On SE(3) V_E = Ad_{Q_d}(V − V_d) carries the x_d×R block, so the law's effective damping
    // grows like |x_d|² and a fixed K_d under 10 ms zero-order hold goes unstable once the
    // reference is ~15 m from the origin: the converging test keeps it on a circle.
    let vd0 = SVector::<f64, 6>::new(0.0, 0.0, 0.4, 0.4, 0.0, 0.0);
    let reference =
        Reference::new(SMatrix::identity(), vd0, inertia, ff, period, substeps).unwrap();
    let q0 = Se3::exp(&SVector::<f64, 6>::new(1.5, -1.0, 0.8, 2.0, -1.0, 1.5));
    let v0 = SVector::<f64, 6>::new(1.0, -0.5, 0.3, 0.0, 0.5, -1.0);
    let plant = RigidBody::new(inertia, q0, v0).unwrap();
    let controller = Controller::new(config).unwrap();
    ClosedLoop::new(controller, reference, plant, substeps).unwrap()
}

/// `V_Eᵀ K_d V_E` with `V_E = Ad_{Q_d}(V − V_d)`.
fn dissipation<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    s: &Sample<f64, N, M>,
    kd: &SMatrix<f64, M, M>,
) -> f64 {
    let ve = G::adjoint(&s.desired.q) * s.output.velocity_error;
    ve.dot(&(kd * ve))
}

/// Runs `steps` cycles and checks (a) L never rises by more than `rise_tol` in a step and
/// (b) the central difference of L matches −V_EᵀK_dV_E to `rate_tol` (relative to the
/// dissipation scale). Returns (L(0), L(end)).
fn check_lyapunov<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    mut sim: ClosedLoop<f64, G, N, M>,
    steps: usize,
    rise_tol: f64,
    rate_tol: f64,
) -> (f64, f64) {
    let kd = sim.controller.config().kd;
    let h = sim.reference.period();
    let samples: Vec<_> = (0..=steps).map(|_| sim.step().unwrap()).collect();
    let l: Vec<f64> = samples.iter().map(|s| s.output.lyapunov.total).collect();
    let scale = samples
        .iter()
        .map(|s| dissipation::<G, N, M>(s, &kd))
        .fold(0.0, f64::max);
    let mut worst_rise = 0.0f64;
    let mut worst_rate = 0.0f64;
    for k in 1..steps {
        worst_rise = worst_rise.max(l[k + 1] - l[k]);
        let fd = (l[k + 1] - l[k - 1]) / (2.0 * h);
        let expect = -dissipation::<G, N, M>(&samples[k], &kd);
        worst_rate = worst_rate.max((fd - expect).abs() / scale);
    }
    eprintln!(
        "{:?}: worst rise {worst_rise:.3e}, worst rate error {worst_rate:.3e} (scale {scale:.3e})",
        G::NAME
    );
    assert!(worst_rise <= rise_tol, "L rose by {worst_rise:e}");
    assert!(
        worst_rate <= rate_tol,
        "dL/dt off by {worst_rate:e} of the scale"
    );
    (l[0], l[steps])
}

// With zero-order hold at period h the torque lags the continuous law by O(h), so dL/dt
// differs from −V_EᵀK_dV_E by O(h) relative to the dissipation scale, and L can rise by O(h²)
// per step only where V_E ≈ 0. h = 1e-4 gives both bounds with a wide margin; a wrong sign in
// any term of the law makes dL/dt wrong by O(1).

#[test]
fn so3_lyapunov_decreases_and_its_rate_is_the_dissipation() {
    let sim = common::seed_loop::<f64>(Law::Eqt, 1e-4, 1);
    let (l0, l1) = check_lyapunov::<So3, 3, 3>(sim, 30_000, 1e-9, 2e-3);
    assert!(l1 < 0.5 * l0);
}

#[test]
fn se3_lyapunov_decreases_and_its_rate_is_the_dissipation() {
    let sim = se3_loop(1e-4, 1, true);
    let (l0, l1) = check_lyapunov::<Se3, 4, 6>(sim, 30_000, 1e-9, 2e-3);
    assert!(l1 < 0.5 * l0);
}

#[test]
fn se3_converges() {
    let mut sim = se3_loop(0.01, 10, false);
    let mut last = None;
    let mut reach = 0.0f64;
    for _ in 0..=6000 {
        let s = sim.step().unwrap();
        reach = reach.max(s.desired.q.fixed_view::<3, 1>(0, 3).norm());
        last = Some(s);
    }
    let s = last.unwrap();
    let n = s.norms::<Se3>();
    eprintln!(
        "SE(3) after 60 s: config error {:.3e}, |x_d| ≤ {reach:.2}",
        n.config_error
    );
    assert!(reach < 2.01, "the reference left its circle: {reach}");
    assert!(n.config_error < 1e-3, "config error {}", n.config_error);
    assert!(n.velocity_error < 1e-3);
}

fn random_spd_with_eigenvectors(
    lambdas: [f64; 3],
    axis: Vector3<f64>,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let u = So3::exp(&axis);
    (
        u * Matrix3::from_diagonal(&Vector3::from(lambdas)) * u.transpose(),
        u,
    )
}

#[test]
fn isotropic_k_every_pi_rotation_is_a_critical_point_and_unstable() {
    let k = Matrix3::identity() * 0.7;
    for i in 0..50 {
        let a = Vector3::new(
            (i as f64 * 0.37).sin(),
            (i as f64 * 1.3).cos(),
            0.3 + (i as f64).sin(),
        );
        let axis = a.normalize();
        let re = So3::exp(&(axis * core::f64::consts::PI));
        assert!((re.trace() + 1.0).abs() < 1e-12);
        let g = potential_gradient::<So3, f64, 3, 3>(&re, &k);
        assert!(g.amax() < 1e-12, "gradient {g:?} at a π-rotation");
        let l = potential(&re, &k);
        // any small rotation lowers L (p_E = 0): the π-rotations are the maxima of Υ
        // No small rotation raises Υ (a maximum); one with a component along the axis lowers
        // it (perpendicular ones move along the set of π-rotations, to second order).
        for w in [Vector3::x(), Vector3::y(), Vector3::z(), a] {
            let moved = re * So3::exp(&(w * 1e-3));
            assert!(potential(&moved, &k) <= l + 1e-15);
        }
        for w in [axis, axis + Vector3::new(0.3, -0.2, 0.1)] {
            assert!(potential(&(re * So3::exp(&(w * 1e-3))), &k) < l - 1e-8);
        }
    }
}

#[test]
fn anisotropic_k_critical_points_are_the_pi_rotations_about_eigenvectors() {
    let (k, u) = random_spd_with_eigenvectors([0.4, 1.0, 1.7], Vector3::new(0.3, -0.8, 0.5));
    for i in 0..3 {
        let e = u.column(i).into_owned();
        let re = So3::exp(&(e * core::f64::consts::PI));
        let g = potential_gradient::<So3, f64, 3, 3>(&re, &k);
        assert!(g.amax() < 1e-12, "eigenvector {i}: gradient {g:?}");
        let l = potential(&re, &k);
        let lowest = [
            Vector3::x(),
            Vector3::y(),
            Vector3::z(),
            u.column(0).into_owned(),
            u.column(1).into_owned(),
            u.column(2).into_owned(),
        ]
        .iter()
        .flat_map(|w| [*w, -*w])
        .map(|w| potential(&(re * So3::exp(&(w * 1e-3))), &k))
        .fold(f64::INFINITY, f64::min);
        assert!(
            lowest < l,
            "no descent direction at the π-rotation about eigenvector {i}"
        );
    }
    // other π-rotations are not critical points
    for a in [
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(0.2, -0.5, 0.9),
        Vector3::new(-1.0, 0.3, 0.3),
    ] {
        let re = So3::exp(&(a.normalize() * core::f64::consts::PI));
        let g = potential_gradient::<So3, f64, 3, 3>(&re, &k);
        assert!(
            g.amax() > 1e-3,
            "gradient vanishes at a non-eigen π-rotation: {g:?}"
        );
    }
}

#[test]
fn identity_is_a_strict_minimum() {
    let (k, _) = random_spd_with_eigenvectors([0.4, 1.0, 1.7], Vector3::new(0.3, -0.8, 0.5));
    let id = Matrix3::identity();
    assert_eq!(potential(&id, &k), 0.0);
    assert!(potential_gradient::<So3, f64, 3, 3>(&id, &k).amax() == 0.0);
    for i in 0..100 {
        let w = Vector3::new(
            (i as f64).sin(),
            (i as f64 * 2.1).cos(),
            (i as f64 * 0.7).sin(),
        ) * 1e-3;
        assert!(potential(&So3::exp(&w), &k) > 0.0);
    }
}

/// A loop flown against a reference recorded once (`Tabulated`) computes, bit for bit, what
/// the loop flown against the reference itself computes: the Monte Carlo study shares one
/// table among its runs on this.
#[test]
fn a_tabulated_reference_flies_the_same_loop_bit_for_bit() {
    use eqtrack_controller::reference::{Tabulated, Trajectory};
    let steps = 300;
    let mut direct = se3_loop(0.01, 4, true);
    let mut source = direct.reference.clone();
    let mut table = Vec::new();
    Tabulated::record(&mut source, steps, &mut table);
    assert_eq!(table.len(), steps + 1);
    let replayed = Tabulated::new(&table, 0.01).unwrap();
    let again = se3_loop(0.01, 4, true);
    let mut tabulated = ClosedLoop::new(again.controller, replayed, again.plant, 4).unwrap();
    for k in 0..=steps {
        let a = direct.step().unwrap();
        let b = tabulated.step().unwrap();
        assert_eq!(a.t.to_bits(), b.t.to_bits(), "t at step {k}");
        assert_eq!(a.desired, b.desired, "desired state at step {k}");
        assert_eq!(a.output, b.output, "torque at step {k}");
        assert_eq!(a.q, b.q, "plant configuration at step {k}");
    }
    assert_eq!(tabulated.reference.step_index(), steps as u64 + 1);
    // an empty table is refused, naming the reference
    let err = Tabulated::<f64, 4, 6>::new(&[], 0.01).unwrap_err();
    assert!(err.to_string().contains("reference"), "{err}");
}

/// A planar body (SE(2), `diag(J, m, m)`) tracking a circle, from initial conditions `xs`
/// (each in [−1, 1]: a heading up to ±3 rad, a position up to 3 m away, a velocity), at a
/// period of 1 ms with one plant substep.
fn se2_loop(xs: &[f64]) -> ClosedLoop<f64, Se2, 3, 3> {
    let inertia = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::new(0.5, 2.0, 2.0));
    let k = SMatrix::<f64, 3, 3>::from_diagonal(&Vector3::new(1.0, 1.0, 2.0));
    let config = ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::Reference,
        inertia,
        k,
        kd: SMatrix::<f64, 3, 3>::identity() * 1.5,
        torque_limit: None,
    };
    // the circle: (ω, v_x, v_y) = (0.4, 0.4, 0) held by the centripetal force −ad_Vᵀ I V
    let mut circle = Feedforward::zero();
    circle.axes[2] = AxisTorque::constant(0.32);
    let vd0 = SVector::<f64, 3>::new(0.4, 0.4, 0.0);
    let reference = Reference::new(SMatrix::identity(), vd0, inertia, circle, 1e-3, 1).unwrap();
    let q0 = eqtrack_controller::group::se2::pose(
        xs[0] * 3.0,
        &nalgebra::Vector2::new(xs[1] * 3.0, xs[2] * 3.0),
    );
    let v0 = SVector::<f64, 3>::new(xs[3], xs[4], xs[5]);
    let plant = RigidBody::new(inertia, q0, v0).unwrap();
    ClosedLoop::new(Controller::new(config).unwrap(), reference, plant, 1).unwrap()
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]

    /// SE(2) from random initial conditions: within 40 s the error falls below a millionth of
    /// where it started, and `L` never rises by more than 1e-9 in a step (with the torque held
    /// over 1 ms, `L` may rise by O(h²) only where the velocity error vanishes).
    #[test]
    fn se2_converges_from_random_initial_conditions_and_l_never_rises(
        xs in proptest::collection::vec(-1.0..1.0f64, 6),
    ) {
        let mut sim = se2_loop(&xs);
        let mut last = f64::INFINITY;
        let (mut first, mut worst_rise) = (f64::NAN, 0.0f64);
        for k in 0..40_000 {
            let l = sim.step().unwrap().output.lyapunov.total;
            if k == 0 {
                first = l;
            } else {
                worst_rise = worst_rise.max(l - last);
            }
            last = l;
        }
        proptest::prop_assert!(worst_rise <= 1e-9 * (1.0 + first), "L rose by {worst_rise:e}");
        proptest::prop_assert!(last < 1e-6 * first, "L from {first} to {last}");
    }
}
