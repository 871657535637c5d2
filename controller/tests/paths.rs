//! Paths through waypoints (docs/maths.md, "Desired trajectories as inputs"): through every
//! waypoint at its time, at rest at both ends, `V_d` and `V̇_d` equal to finite differences of
//! `Q_d` and `V_d`, `V̇_d` continuous across every knot, and the feedforward `τ_d` driving the
//! Euler–Poincaré equations along the path — on SO(3) and SE(3), in f64 and f32, with more
//! than π of rotation between two waypoints.

mod common;

use controller::closed_loop::ClosedLoop;
use controller::group::{MatrixLieGroup, Se3, So3};
use controller::integrator::{RigidBody, physical_step};
use controller::semidirect::Phase;
use controller::{Controller, ControllerConfig, Law, Path, PathReference, Real, Trajectory, real};
use nalgebra::{SMatrix, SVector, Vector3};
use proptest::prelude::*;

/// A pose from a rotation vector and a position (SO(3): the rotation alone).
fn pose<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>(
    r: [f64; 3],
    x: [f64; 3],
) -> SMatrix<T, N, N> {
    let mut v = SVector::<T, M>::zeros();
    for i in 0..3 {
        v[i] = real(r[i]);
        if M == 6 {
            v[3 + i] = real(x[i]);
        }
    }
    G::exp(&v)
}

/// The slew used throughout: four attitudes, one step of 3.5 rad (> π) about x, one of
/// 2 rad (> π/2) about a tilted axis; on SE(3) with translations of a few metres.
fn slew<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>()
-> (Vec<T>, Vec<SMatrix<T, N, N>>) {
    let times = [0.5, 2.0, 4.5, 6.0, 8.0].map(real::<T>).to_vec();
    let poses = [
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
        ([1.2, 0.3, -0.4], [1.0, 0.5, 0.0]),
        ([1.2 - 3.5, 0.3, -0.4], [2.0, -1.0, 1.5]),
        ([-0.9, 1.6, 0.7], [-1.0, 0.0, 2.0]),
        ([0.1, -0.2, 2.9], [0.0, 0.0, 0.0]),
    ]
    .iter()
    .map(|(r, x)| pose::<G, T, N, M>(*r, *x))
    .collect();
    (times, poses)
}

fn to_f64<T: Real, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> SMatrix<f64, R, C> {
    m.map(|x| nalgebra::try_convert::<T, f64>(x).unwrap())
}

/// The checks on one scalar type: `tol` bounds the waypoint and rest errors, `fd` the
/// finite-difference disagreement (relative to the largest velocity or acceleration).
fn check_path<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>(
    times: &[T],
    poses: &[SMatrix<T, N, N>],
    tol: f64,
    h: f64,
    fd: f64,
) {
    let path = Path::<T, G, N, M>::through(times, poses).unwrap();
    let f = |t: f64| path.sample(real::<T>(t));
    // through every waypoint at its time
    for (t, q) in times.iter().zip(poses) {
        let s = path.sample(*t);
        let e = to_f64(&(s.q - q)).norm();
        assert!(e < tol, "waypoint at t = {t:?}: |Q_d − Q_i| = {e:e}");
    }
    // at rest at both ends, and beyond them
    let (t0, tn) = (times[0], *times.last().unwrap());
    for t in [t0, tn, t0 - real(0.3), tn + real(1.0)] {
        let s = path.sample(t);
        assert!(
            to_f64(&s.v).norm() < tol && to_f64(&s.v_dot).norm() < tol,
            "rest at {t:?}"
        );
    }
    // V_d against central differences of Q_d, V̇_d against those of V_d, on a grid
    let t0 = nalgebra::try_convert::<T, f64>(t0).unwrap();
    let tn = nalgebra::try_convert::<T, f64>(tn).unwrap();
    let (mut vmax, mut amax, mut ev, mut ea) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let knots: Vec<f64> = times
        .iter()
        .map(|t| nalgebra::try_convert::<T, f64>(*t).unwrap())
        .collect();
    for i in 1..400 {
        let t = t0 + (tn - t0) * i as f64 / 400.0;
        // V̇_d is continuous but has a corner at a knot (the jerk jumps): a difference
        // straddling it is O(h) off, so the grid keeps 2h away from the knots
        if knots.iter().any(|k| (t - k).abs() < 2.0 * h) {
            continue;
        }
        let (a, b, c) = (f(t - h), f(t), f(t + h));
        let v_fd = to_f64(&G::log(&G::compose(&G::inverse(&a.q), &c.q))) / (2.0 * h);
        let a_fd = to_f64(&(c.v - a.v)) / (2.0 * h);
        vmax = vmax.max(to_f64(&b.v).norm());
        amax = amax.max(to_f64(&b.v_dot).norm());
        ev = ev.max((v_fd - to_f64(&b.v)).norm());
        ea = ea.max((a_fd - to_f64(&b.v_dot)).norm());
    }
    assert!(
        ev < fd * vmax,
        "V_d vs finite differences: {ev:e} (max |V_d| {vmax})"
    );
    assert!(
        ea < fd * amax,
        "V̇_d vs finite differences: {ea:e} (max |V̇_d| {amax})"
    );
    // V̇_d continuous across every knot: the jump over ±ε shrinks with ε
    for t in times {
        let t = nalgebra::try_convert::<T, f64>(*t).unwrap();
        for eps in [1e-3, 1e-4] {
            let jump = to_f64(&(f(t + eps).v_dot - f(t - eps).v_dot)).norm();
            assert!(
                jump < 200.0 * amax * eps,
                "V̇_d jumps {jump:e} across the knot at {t}"
            );
        }
    }
}

#[test]
fn the_slew_passes_its_waypoints_smoothly_on_both_groups_in_f64_and_f32() {
    // f64: waypoints to 1e-9; h = 1e-4 s, central differences agree to 1e-6 of the peak
    let (t, q) = slew::<So3, f64, 3, 3>();
    check_path::<So3, f64, 3, 3>(&t, &q, 1e-9, 1e-4, 1e-6);
    let (t, q) = slew::<Se3, f64, 4, 6>();
    check_path::<Se3, f64, 4, 6>(&t, &q, 1e-9, 1e-4, 1e-6);
    // f32: waypoints to 1e-5; h = 1e-2 s, agreement to 1e-2 of the peak
    let (t, q) = slew::<So3, f32, 3, 3>();
    check_path::<So3, f32, 3, 3>(&t, &q, 1e-5, 1e-2, 1e-2);
    let (t, q) = slew::<Se3, f32, 4, 6>();
    check_path::<Se3, f32, 4, 6>(&t, &q, 1e-5, 1e-2, 1e-2);
}

#[test]
fn more_than_pi_between_two_waypoints_goes_the_short_way_round() {
    // 3.5 rad about x: flown as 2π − 3.5 about −x, through both waypoints
    let a = pose::<So3, f64, 3, 3>([0.0; 3], [0.0; 3]);
    let b = pose::<So3, f64, 3, 3>([3.5, 0.0, 0.0], [0.0; 3]);
    let path = Path::<f64, So3, 3, 3>::through(&[0.0, 2.0], &[a, b]).unwrap();
    let seg = path.segments().next().unwrap();
    assert!((seg.twist - Vector3::new(3.5 - 2.0 * core::f64::consts::PI, 0.0, 0.0)).norm() < 1e-12);
    assert!((path.sample(2.0).q - b).norm() < 1e-12);
    // exactly π: still through the waypoint
    let b = pose::<So3, f64, 3, 3>([0.0, core::f64::consts::PI, 0.0], [0.0; 3]);
    let path = Path::<f64, So3, 3, 3>::through(&[0.0, 2.0], &[a, b]).unwrap();
    assert!((path.sample(2.0).q - b).norm() < 1e-9);
}

#[test]
fn bad_paths_are_typed_errors() {
    let q = pose::<So3, f64, 3, 3>([0.0; 3], [0.0; 3]);
    let e = Path::<f64, So3, 3, 3>::through(&[0.0, 1.0, 1.0], &[q, q, q]).unwrap_err();
    assert_eq!(e, controller::Error::NotIncreasing { index: 2 });
    let times: Vec<f64> = (0..=controller::path::MAX_SEGMENTS + 1)
        .map(|i| i as f64)
        .collect();
    let poses = vec![q; times.len()];
    let e = Path::<f64, So3, 3, 3>::through(&times, &poses).unwrap_err();
    assert!(matches!(e, controller::Error::TooManySegments { .. }));
    let e = Path::<f64, So3, 3, 3>::through(&[0.0, f64::NAN], &[q, q]).unwrap_err();
    assert!(matches!(e, controller::Error::NonFinite(_)));
}

/// Integrates `ṗ = ad_Vᵀp + τ_d(t)` with τ_d evaluated at every RKMK4 stage, from the
/// path's initial state, and returns the largest `|Q − Q_d|` along the way.
fn open_loop_drift<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    times: &[f64],
    poses: &[SMatrix<f64, N, N>],
    inertia: SMatrix<f64, M, M>,
    h: f64,
) -> f64 {
    let path = Path::<f64, G, N, M>::through(times, poses).unwrap();
    let inv = inertia.try_inverse().unwrap();
    let start = path.sample(0.0);
    let mut x = Phase {
        q: start.q,
        p: inertia * start.v,
    };
    let steps = ((times.last().unwrap() + 1.0) / h).round() as usize;
    let mut worst = 0.0f64;
    for k in 0..steps {
        let t = k as f64 * h;
        x = physical_step::<G, f64, _, N, M>(&x, t, h, &inv, |s| {
            path.sample(s).desired::<G>(&inertia).tau
        });
        worst = worst.max((x.q - path.sample(t + h).q).norm());
    }
    worst
}

#[test]
fn the_feedforward_drives_the_body_along_the_path_open_loop() {
    let i3 = common::fixed_wing::<f64>();
    let (t, q) = slew::<So3, f64, 3, 3>();
    let d = open_loop_drift::<So3, 3, 3>(&t, &q, i3, 1e-3);
    eprintln!("SO(3) open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
    let mut i6 = SMatrix::<f64, 6, 6>::zeros();
    i6.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    i6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(SMatrix::<f64, 3, 3>::identity() * 2.5));
    let (t, q) = slew::<Se3, f64, 4, 6>();
    let d = open_loop_drift::<Se3, 4, 6>(&t, &q, i6, 1e-3);
    eprintln!("SE(3) open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
}

/// The closed loop from a perturbed start: L never rises by more than 1e-9 in a step and the
/// error at the end is small. With a zero-order hold at period h, L may rise by O(h²) per step
/// where V_E ≈ 0 (as in tests/closed_loop.rs); h = 1e-4 s makes that negligible.
fn converges<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    times: &[f64],
    poses: &[SMatrix<f64, N, N>],
    inertia: SMatrix<f64, M, M>,
    start: SMatrix<f64, N, N>,
) -> (f64, f64) {
    let path = Path::<f64, G, N, M>::through(times, poses).unwrap();
    let controller = Controller::<f64, G, N, M>::new(ControllerConfig {
        law: Law::Eqt,
        inertia,
        k: SMatrix::identity() * 2.0,
        kd: SMatrix::identity() * 2.0,
        torque_limit: None,
    })
    .unwrap();
    let reference = PathReference::new(path, inertia, 1e-4).unwrap();
    let plant = RigidBody::new(inertia, start, SVector::zeros()).unwrap();
    let mut sim = ClosedLoop::new(controller, reference, plant, 1).unwrap();
    let (mut last, mut first, mut rise) = (f64::INFINITY, None, 0.0f64);
    while sim.reference.time() < times.last().unwrap() + 10.0 {
        let s = sim.step().unwrap();
        let l = s.output.lyapunov.total;
        first.get_or_insert(l);
        rise = rise.max(l - last);
        last = l;
    }
    assert!(rise < 1e-9, "L rose by {rise:e} in one step");
    (first.unwrap(), last)
}

#[test]
fn the_closed_loop_converges_to_a_waypoint_path_and_l_never_rises() {
    let i3 = common::fixed_wing::<f64>();
    let (t, q) = slew::<So3, f64, 3, 3>();
    let start = pose::<So3, f64, 3, 3>([0.6, -0.5, 0.4], [0.0; 3]);
    let (l0, l1) = converges::<So3, 3, 3>(&t, &q, i3, start);
    eprintln!("SO(3): L from {l0:e} to {l1:e}");
    assert!(l1 < 1e-4 * l0, "L from {l0:e} to {l1:e}");
    let mut i6 = SMatrix::<f64, 6, 6>::zeros();
    i6.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    i6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(SMatrix::<f64, 3, 3>::identity() * 2.5));
    let (t, q) = slew::<Se3, f64, 4, 6>();
    let start = pose::<Se3, f64, 4, 6>([0.6, -0.5, 0.4], [0.5, -0.5, 0.3]);
    let (l0, l1) = converges::<Se3, 4, 6>(&t, &q, i6, start);
    eprintln!("SE(3): L from {l0:e} to {l1:e}");
    assert!(l1 < 1e-4 * l0, "L from {l0:e} to {l1:e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random waypoints (any rotation, spacing 0.5–3 s) on SO(3): all the checks above.
    #[test]
    fn random_paths_pass_their_waypoints_smoothly(
        rs in prop::collection::vec(prop::array::uniform3(-4.0f64..4.0), 2..6),
        gaps in prop::collection::vec(0.5f64..3.0, 6),
    ) {
        let mut t = 0.0;
        let times: Vec<f64> = gaps.iter().take(rs.len()).map(|g| { t += g; t }).collect();
        let poses: Vec<_> = rs.iter().map(|r| pose::<So3, f64, 3, 3>(*r, [0.0; 3])).collect();
        check_path::<So3, f64, 3, 3>(&times, &poses, 1e-9, 1e-4, 1e-6);
    }
}

#[test]
fn a_set_point_holds_its_pose_with_no_feedforward() {
    let q = pose::<Se3, f64, 4, 6>([0.3, 0.2, -2.0], [1.0, 2.0, 3.0]);
    let r = PathReference::new(
        Path::<f64, Se3, 4, 6>::hold(q).unwrap(),
        SMatrix::<f64, 6, 6>::identity(),
        0.01,
    )
    .unwrap();
    let d = r.desired();
    assert_eq!(d.q, q);
    assert_eq!(d.v, SVector::<f64, 6>::zeros());
    assert_eq!(d.tau, SVector::<f64, 6>::zeros());
    let _ = Vector3::<f64>::zeros();
}
