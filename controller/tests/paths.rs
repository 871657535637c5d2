//! Paths through waypoints (docs/maths.md, "Desired trajectories as inputs"): through every
//! waypoint at its time, at rest at both ends, `V_d` and `V̇_d` equal to finite differences of
//! `Q_d` and `V_d`, `V̇_d` continuous across every knot, and the feedforward `τ_d` driving the
//! Euler–Poincaré equations along the path — on SO(3) and SE(3), in f64 and f32, with more
//! than π of rotation between two waypoints. The same for paths that fly through their
//! waypoints (`Path::flying`), and their own properties: C² knots, moving at every interior
//! waypoint, the rest-to-rest path as the zero-data case, the scalar spline profile about one
//! axis, given velocities honoured.

mod common;

use eqtrack_controller::closed_loop::ClosedLoop;
use eqtrack_controller::group::{MatrixLieGroup, Se3, So3};
use eqtrack_controller::integrator::{RigidBody, physical_step};
use eqtrack_controller::semidirect::Phase;
use eqtrack_controller::{
    Controller, ControllerConfig, Law, Path, PathReference, PathSample, Real, Segment, Trajectory,
    real,
};
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
    check_samples(&path, times, poses, tol, h, fd);
}

/// The checks of [`check_path`] on a given path through `poses` at `times`.
fn check_samples<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>(
    path: &Path<T, G, N, M>,
    times: &[T],
    poses: &[SMatrix<T, N, N>],
    tol: f64,
    h: f64,
    fd: f64,
) {
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
    let eqtrack_controller::path::Shape::Rest { twist } = seg.shape else {
        panic!("a stop path is made of rest-to-rest pieces")
    };
    assert!((twist - Vector3::new(3.5 - 2.0 * core::f64::consts::PI, 0.0, 0.0)).norm() < 1e-12);
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
    assert_eq!(e, eqtrack_controller::Error::NotIncreasing { index: 2 });
    let times: Vec<f64> = (0..=eqtrack_controller::path::MAX_SEGMENTS + 1)
        .map(|i| i as f64)
        .collect();
    let poses = vec![q; times.len()];
    let e = Path::<f64, So3, 3, 3>::through(&times, &poses).unwrap_err();
    assert!(matches!(
        e,
        eqtrack_controller::Error::TooManySegments { .. }
    ));
    let e = Path::<f64, So3, 3, 3>::through(&[0.0, f64::NAN], &[q, q]).unwrap_err();
    assert!(matches!(e, eqtrack_controller::Error::NonFinite(_)));
}

/// Integrates `ṗ = ad_Vᵀp + τ_d(t)` with τ_d evaluated at every RKMK4 stage, from the
/// path's initial state, and returns the largest `|Q − Q_d|` along the way.
fn open_loop_drift<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    path: &Path<f64, G, N, M>,
    end: f64,
    inertia: SMatrix<f64, M, M>,
    h: f64,
) -> f64 {
    let inv = inertia.try_inverse().unwrap();
    let start = path.sample(0.0);
    let mut x = Phase {
        q: start.q,
        p: inertia * start.v,
    };
    let steps = ((end + 1.0) / h).round() as usize;
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
    let path = Path::through(&t, &q).unwrap();
    let d = open_loop_drift::<So3, 3, 3>(&path, t[t.len() - 1], i3, 1e-3);
    eprintln!("SO(3) open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
    let mut i6 = SMatrix::<f64, 6, 6>::zeros();
    i6.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    i6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(SMatrix::<f64, 3, 3>::identity() * 2.5));
    let (t, q) = slew::<Se3, f64, 4, 6>();
    let path = Path::through(&t, &q).unwrap();
    let d = open_loop_drift::<Se3, 4, 6>(&path, t[t.len() - 1], i6, 1e-3);
    eprintln!("SE(3) open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
}

/// The closed loop from a perturbed start: L never rises by more than 1e-9 in a step and the
/// error at the end is small. With a zero-order hold at period h, L may rise by O(h²) per step
/// where V_E ≈ 0 (as in tests/closed_loop.rs); h = 1e-4 s makes that negligible.
fn converges<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    path: Path<f64, G, N, M>,
    end: f64,
    inertia: SMatrix<f64, M, M>,
    start: SMatrix<f64, N, N>,
) -> (f64, f64) {
    let controller = Controller::<f64, G, N, M>::new(ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
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
    while sim.reference.time() < end + 10.0 {
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
    let (l0, l1) = converges::<So3, 3, 3>(Path::through(&t, &q).unwrap(), t[4], i3, start);
    eprintln!("SO(3): L from {l0:e} to {l1:e}");
    assert!(l1 < 1e-4 * l0, "L from {l0:e} to {l1:e}");
    let mut i6 = SMatrix::<f64, 6, 6>::zeros();
    i6.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    i6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(SMatrix::<f64, 3, 3>::identity() * 2.5));
    let (t, q) = slew::<Se3, f64, 4, 6>();
    let start = pose::<Se3, f64, 4, 6>([0.6, -0.5, 0.4], [0.5, -0.5, 0.3]);
    let (l0, l1) = converges::<Se3, 4, 6>(Path::through(&t, &q).unwrap(), t[4], i6, start);
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

// ---- paths that fly through their waypoints ----
// docs/maths.md, "Paths that fly through their waypoints"

/// The path of `path = "through"` with every velocity chosen.
fn flying<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>(
    times: &[T],
    poses: &[SMatrix<T, N, N>],
) -> Path<T, G, N, M> {
    Path::flying(times, poses, &vec![None; times.len()]).unwrap()
}

/// Left limit against right limit at every interior knot (`Q`, `V`, `V̇`; the largest
/// difference), and the smallest `|V_d|` at an interior waypoint.
fn knots<G: MatrixLieGroup<N, M>, T: Real, const N: usize, const M: usize>(
    path: &Path<T, G, N, M>,
) -> (f64, f64) {
    let segs: Vec<_> = path.segments().copied().collect();
    let (mut worst, mut slowest) = (0.0f64, f64::INFINITY);
    for w in segs.windows(2) {
        let (l, r) = (w[0].sample::<G>(w[0].t1), w[1].sample::<G>(w[1].t0));
        worst = worst
            .max(to_f64(&(l.q - r.q)).norm())
            .max(to_f64(&(l.v - r.v)).norm())
            .max(to_f64(&(l.v_dot - r.v_dot)).norm());
        slowest = slowest.min(to_f64(&r.v).norm());
    }
    (worst, slowest)
}

#[test]
fn a_through_path_passes_its_waypoints_smoothly_without_stopping() {
    // f64 on both groups: through every waypoint to 1e-9, C² across every knot to 1e-9,
    // finite differences as for the stop path, and moving at every interior waypoint
    let (t, q) = slew::<So3, f64, 3, 3>();
    let path = flying::<So3, f64, 3, 3>(&t, &q);
    check_samples(&path, &t, &q, 1e-9, 1e-4, 1e-6);
    let (jump, slowest) = knots(&path);
    eprintln!("SO(3) through: knot jump {jump:e}, slowest interior |V_d| {slowest}");
    assert!(jump < 1e-9, "{jump:e}");
    assert!(slowest > 0.1, "it stops at a waypoint: |V_d| = {slowest}");
    let (t, q) = slew::<Se3, f64, 4, 6>();
    let path = flying::<Se3, f64, 4, 6>(&t, &q);
    check_samples(&path, &t, &q, 1e-9, 1e-4, 1e-6);
    let (jump, slowest) = knots(&path);
    eprintln!("SE(3) through: knot jump {jump:e}, slowest interior |V_d| {slowest}");
    assert!(jump < 1e-9, "{jump:e}");
    assert!(slowest > 0.1, "it stops at a waypoint: |V_d| = {slowest}");
    // f32: looser
    let (t, q) = slew::<So3, f32, 3, 3>();
    let path = flying::<So3, f32, 3, 3>(&t, &q);
    check_samples(&path, &t, &q, 1e-5, 1e-2, 1e-2);
    let (jump, _) = knots(&path);
    assert!(jump < 1e-4, "f32 SO(3) knot jump {jump:e}");
    let (t, q) = slew::<Se3, f32, 4, 6>();
    let path = flying::<Se3, f32, 4, 6>(&t, &q);
    check_samples(&path, &t, &q, 1e-5, 1e-2, 1e-2);
    let (jump, _) = knots(&path);
    assert!(jump < 1e-4, "f32 SE(3) knot jump {jump:e}");
}

#[test]
fn zero_waypoint_velocities_and_accelerations_give_the_rest_to_rest_path() {
    fn compare<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>() -> f64 {
        let (t, q) = slew::<G, f64, N, M>();
        let stop = Path::<f64, G, N, M>::through(&t, &q).unwrap();
        let mut hermite = Path::<f64, G, N, M>::hold(q[0]).unwrap();
        for i in 1..t.len() {
            let (a, b) = (PathSample::rest(q[i - 1]), PathSample::rest(q[i]));
            hermite
                .push(Segment::hermite::<G>(t[i - 1], &a, t[i], &b))
                .unwrap();
        }
        let mut worst = 0.0f64;
        for k in 0..=4000 {
            let time = k as f64 * 9.0 / 4000.0;
            let (a, b) = (stop.sample(time), hermite.sample(time));
            worst = worst
                .max((a.q - b.q).norm())
                .max((a.v - b.v).norm())
                .max((a.v_dot - b.v_dot).norm());
        }
        worst
    }
    let so3 = compare::<So3, 3, 3>();
    let se3 = compare::<Se3, 4, 6>();
    eprintln!("rest-to-rest vs Hermite with zero knots: SO(3) {so3:e}, SE(3) {se3:e}");
    assert!(so3 < 1e-12 && se3 < 1e-12, "{so3:e} {se3:e}");
}

/// The clamped cubic spline through `(t_i, θ_i)` with zero end slopes, solved as a dense
/// system, and the scalar quintic Hermite of (θ, θ', θ'') on each leg, with the spline's
/// slopes and second derivatives at interior knots and zero second derivative at the ends:
/// `(θ, θ', θ'')` at `t`. Written from the textbook formulas, not from the library.
fn scalar_profile(times: &[f64], angles: &[f64], t: f64) -> (f64, f64, f64) {
    let n = times.len();
    let h: Vec<f64> = (0..n - 1).map(|i| times[i + 1] - times[i]).collect();
    let d: Vec<f64> = (0..n - 1)
        .map(|i| (angles[i + 1] - angles[i]) / h[i])
        .collect();
    // A m = b for all slopes, the end slopes pinned to zero
    let mut a = vec![vec![0.0; n + 1]; n];
    a[0][0] = 1.0;
    a[n - 1][n - 1] = 1.0;
    for i in 1..n - 1 {
        a[i][i - 1] = h[i];
        a[i][i] = 2.0 * (h[i - 1] + h[i]);
        a[i][i + 1] = h[i - 1];
        a[i][n] = 3.0 * (h[i] * d[i - 1] + h[i - 1] * d[i]);
    }
    for c in 0..n {
        let p = (c..n)
            .max_by(|x, y| a[*x][c].abs().total_cmp(&a[*y][c].abs()))
            .unwrap();
        a.swap(c, p);
        let pivot = a[c].clone();
        for (r, row) in a.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / pivot[c];
                for (x, p) in row.iter_mut().zip(&pivot).skip(c) {
                    *x -= f * p;
                }
            }
        }
    }
    let m: Vec<f64> = (0..n).map(|i| a[i][n] / a[i][i]).collect();
    let acc: Vec<f64> = (0..n)
        .map(|i| {
            if i == 0 || i == n - 1 {
                0.0
            } else {
                (6.0 * d[i] - 4.0 * m[i] - 2.0 * m[i + 1]) / h[i]
            }
        })
        .collect();
    let i = (0..n - 1)
        .find(|i| t <= times[i + 1])
        .unwrap_or(n - 2)
        .min(n - 2);
    let u = ((t - times[i]) / h[i]).clamp(0.0, 1.0);
    // quintic Hermite basis as coefficient lists in u (lowest power first)
    let basis: [[f64; 6]; 6] = [
        [1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
        [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
        [0.0, 0.0, 0.5, -1.5, 1.5, -0.5],
        [0.0, 0.0, 0.0, 0.5, -1.0, 0.5],
        [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
        [0.0, 0.0, 0.0, 10.0, -15.0, 6.0],
    ];
    let hh = h[i];
    let weights = [
        angles[i],
        hh * m[i],
        hh * hh * acc[i],
        hh * hh * acc[i + 1],
        hh * m[i + 1],
        angles[i + 1],
    ];
    let (mut p, mut dp, mut ddp) = (0.0, 0.0, 0.0);
    for (b, w) in basis.iter().zip(weights) {
        for (k, c) in b.iter().enumerate() {
            let k = k as i32;
            p += w * c * u.powi(k);
            if k >= 1 {
                dp += w * c * k as f64 * u.powi(k - 1);
            }
            if k >= 2 {
                ddp += w * c * (k * (k - 1)) as f64 * u.powi(k - 2);
            }
        }
    }
    (p, dp / hh, ddp / (hh * hh))
}

#[test]
fn waypoints_about_one_axis_follow_the_scalar_spline_profile() {
    // legs of 1.0, 1.5 (> π/2), 1.3 (across π: 2.5 → 3.8), 1.2 and −1.0 rad about one axis
    let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
    let times = [0.5, 1.7, 3.0, 4.1, 5.6, 7.0];
    let angles = [0.0, 1.0, 2.5, 3.8, 5.0, 4.0];
    let poses: Vec<_> = angles.iter().map(|a| So3::exp(&(axis * *a))).collect();
    let path = flying::<So3, f64, 3, 3>(&times, &poses);
    let mut worst = 0.0f64;
    for k in 0..=2000 {
        let t = 0.5 + 6.5 * k as f64 / 2000.0;
        let (theta, w, a) = scalar_profile(&times, &angles, t);
        let s = path.sample(t);
        worst = worst
            .max((s.q - So3::exp(&(axis * theta))).norm())
            .max((s.v - axis * w).norm())
            .max((s.v_dot - axis * a).norm());
    }
    eprintln!("one axis: group path vs scalar profile, largest difference {worst:e}");
    assert!(worst < 1e-9, "{worst:e}");
}

#[test]
fn given_velocities_are_honoured_and_holds_rest() {
    let (t, q) = slew::<So3, f64, 3, 3>();
    let mut given = vec![None; t.len()];
    let w = Vector3::new(0.2, -0.4, 0.1);
    given[2] = Some(w);
    given[3] = Some(Vector3::zeros());
    let path = Path::<f64, So3, 3, 3>::flying(&t, &q, &given).unwrap();
    assert!((path.sample(t[2]).v - w).norm() < 1e-12);
    assert!(path.sample(t[3]).v.norm() < 1e-12);
    check_samples(&path, &t, &q, 1e-9, 1e-4, 1e-6);
    assert!(knots(&path).0 < 1e-9);
    // a repeated waypoint holds: at rest all along the leg between the two
    let times = [0.0, 1.0, 2.0, 3.0, 4.0];
    let r = [0.0, 0.8, 0.8, 1.6, 2.0].map(|a| So3::exp(&Vector3::new(0.0, 0.0, a)));
    let path = flying::<So3, f64, 3, 3>(&times, &r);
    for k in 0..=10 {
        let s = path.sample(1.0 + k as f64 / 10.0);
        assert!(
            (s.q - r[1]).norm() < 1e-12 && s.v.norm() < 1e-12,
            "moves in the hold"
        );
    }
    assert!(path.sample(0.5).v.norm() > 0.1 && path.sample(2.5).v.norm() > 0.1);
    // a moving first or last waypoint is refused
    given[0] = Some(w);
    let e = Path::<f64, So3, 3, 3>::flying(&t, &q, &given).unwrap_err();
    assert_eq!(e, eqtrack_controller::Error::NotAtRest { index: 0 });
    given[0] = None;
    given[4] = Some(w);
    let e = Path::<f64, So3, 3, 3>::flying(&t, &q, &given).unwrap_err();
    assert_eq!(e, eqtrack_controller::Error::NotAtRest { index: 4 });
    given[4] = Some(Vector3::new(f64::NAN, 0.0, 0.0));
    let e = Path::<f64, So3, 3, 3>::flying(&t, &q, &given).unwrap_err();
    assert!(matches!(e, eqtrack_controller::Error::NonFinite(_)));
    let e = Path::<f64, So3, 3, 3>::flying(&[0.0, 1.0, 1.0], &q[..3], &[None; 3]).unwrap_err();
    assert_eq!(e, eqtrack_controller::Error::NotIncreasing { index: 2 });
}

#[test]
fn a_through_path_is_flown_by_its_feedforward_and_by_the_closed_loop() {
    let i3 = common::fixed_wing::<f64>();
    let (t, q) = slew::<So3, f64, 3, 3>();
    let d = open_loop_drift::<So3, 3, 3>(&flying(&t, &q), t[4], i3, 1e-3);
    eprintln!("SO(3) through: open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
    let mut i6 = SMatrix::<f64, 6, 6>::zeros();
    i6.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    i6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(SMatrix::<f64, 3, 3>::identity() * 2.5));
    let (t6, q6) = slew::<Se3, f64, 4, 6>();
    let d = open_loop_drift::<Se3, 4, 6>(&flying(&t6, &q6), t6[4], i6, 1e-3);
    eprintln!("SE(3) through: open-loop drift over 9 s at h = 1 ms: {d:e}");
    assert!(d < 1e-8, "drift {d:e}");
    let start = pose::<So3, f64, 3, 3>([0.6, -0.5, 0.4], [0.0; 3]);
    let (l0, l1) = converges::<So3, 3, 3>(flying(&t, &q), t[4], i3, start);
    eprintln!("SO(3) through: L from {l0:e} to {l1:e}");
    assert!(l1 < 1e-4 * l0, "L from {l0:e} to {l1:e}");
    let start = pose::<Se3, f64, 4, 6>([0.6, -0.5, 0.4], [0.5, -0.5, 0.3]);
    let (l0, l1) = converges::<Se3, 4, 6>(flying(&t6, &q6), t6[4], i6, start);
    eprintln!("SE(3) through: L from {l0:e} to {l1:e}");
    assert!(l1 < 1e-4 * l0, "L from {l0:e} to {l1:e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random waypoints on SO(3) flown through: every check of the stop path, and C² knots.
    #[test]
    fn random_through_paths_pass_their_waypoints_smoothly(
        rs in prop::collection::vec(prop::array::uniform3(-4.0f64..4.0), 2..6),
        gaps in prop::collection::vec(0.5f64..3.0, 6),
    ) {
        let mut t = 0.0;
        let times: Vec<f64> = gaps.iter().take(rs.len()).map(|g| { t += g; t }).collect();
        let poses: Vec<_> = rs.iter().map(|r| pose::<So3, f64, 3, 3>(*r, [0.0; 3])).collect();
        let path = flying::<So3, f64, 3, 3>(&times, &poses);
        check_samples(&path, &times, &poses, 1e-9, 1e-4, 1e-6);
        let (jump, _) = knots(&path);
        prop_assert!(jump < 1e-9, "knot jump {:e}", jump);
    }
}
