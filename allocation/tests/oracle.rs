//! The allocator against an independent solver: an exhaustive enumeration of active sets
//! (every actuator at its lower bound, its upper bound, or free), each solved as an
//! equality-constrained least-squares problem by the SVD, the best feasible one kept. Each
//! stage's optimum must be met to 1e-9 (docs/maths.md, "Control allocation").

use eqtrack_allocation::{
    Actuator, Allocator, Bounds, Geometry, MAX_ACTUATORS, Priority, Status, presets,
};
use nalgebra::{DMatrix, DVector, SVector};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

/// A stage: minimise `½‖A u − b‖²` (or, with `w`, `½ (u − up)ᵀ W (u − up)`) subject to
/// `C u = d` and `lo ≤ u ≤ hi`.
struct Problem {
    a: DMatrix<f64>,
    b: DVector<f64>,
    w: Option<(DVector<f64>, DVector<f64>)>,
    c: DMatrix<f64>,
    d: DVector<f64>,
    lo: DVector<f64>,
    hi: DVector<f64>,
}

impl Problem {
    fn value(&self, u: &DVector<f64>) -> f64 {
        match &self.w {
            Some((w, up)) => 0.5 * (u - up).component_mul(&(u - up)).dot(w),
            None => 0.5 * (&self.a * u - &self.b).norm_squared(),
        }
    }
}

/// The optimum by enumeration: `(u, value)`.
fn oracle(p: &Problem) -> (DVector<f64>, f64) {
    let m = p.lo.len();
    let mut best: Option<(DVector<f64>, f64)> = None;
    for code in 0..3usize.pow(m as u32) {
        let mut u = DVector::zeros(m);
        let mut free = Vec::new();
        let mut c = code;
        for j in 0..m {
            match c % 3 {
                0 => u[j] = p.lo[j],
                1 => u[j] = p.hi[j],
                _ => free.push(j),
            }
            c /= 3;
        }
        if let Some(x) = solve_free(p, &u, &free) {
            for (k, j) in free.iter().enumerate() {
                u[*j] = x[k];
            }
            let tol = 1e-9 * (1.0 + p.lo.amax().max(p.hi.amax()));
            if (0..m).any(|j| u[j] < p.lo[j] - tol || u[j] > p.hi[j] + tol) {
                continue;
            }
            let v = p.value(&u);
            if best.as_ref().is_none_or(|(_, bv)| v < *bv) {
                best = Some((u, v));
            }
        }
    }
    best.expect("some active set is feasible")
}

/// The free actuators' values with the others fixed at `u`: unique, or `None` (no unique
/// solution, or the equalities cannot hold). Plain Gaussian elimination, nothing of the
/// allocator's (or nalgebra's) factorisations: the equalities' independent rows by row
/// reduction, then the KKT system `[H C_Fᵀ; C_F 0]`.
fn solve_free(p: &Problem, u: &DVector<f64>, free: &[usize]) -> Option<DVector<f64>> {
    let f = free.len();
    let cols = |mat: &DMatrix<f64>| DMatrix::from_fn(mat.nrows(), f, |i, k| mat[(i, free[k])]);
    let (cf, af) = (cols(&p.c), cols(&p.a));
    let rc = &p.d - &p.c * u;
    let scale = 1.0 + p.d.amax() + p.c.amax() * (1.0 + p.lo.amax().max(p.hi.amax()));
    // the equalities' independent rows (consistent, or no solution)
    let (cf, rc) = independent_rows(&cf, &rc, 1e-10 * scale)?;
    if f == 0 {
        return Some(DVector::zeros(0));
    }
    let (h, rhs) = match &p.w {
        Some((w, up)) => (
            DMatrix::from_diagonal(&DVector::from_fn(f, |k, _| w[free[k]])),
            DVector::from_fn(f, |k, _| w[free[k]] * up[free[k]]),
        ),
        None => (af.transpose() * &af, af.transpose() * (&p.b - &p.a * u)),
    };
    let k = cf.nrows();
    let mut kkt = DMatrix::zeros(f + k, f + k);
    kkt.view_mut((0, 0), (f, f)).copy_from(&h);
    kkt.view_mut((0, f), (f, k)).copy_from(&cf.transpose());
    kkt.view_mut((f, 0), (k, f)).copy_from(&cf);
    let mut b = DVector::zeros(f + k);
    b.rows_mut(0, f).copy_from(&rhs);
    b.rows_mut(f, k).copy_from(&rc);
    let x = gauss(kkt, b)?;
    Some(x.rows(0, f).into_owned())
}

/// The rows of `[C | r]` that row reduction keeps (full pivoting); `None` if a dependent row
/// has a right-hand side the others do not give (the equalities cannot hold).
fn independent_rows(
    c: &DMatrix<f64>,
    r: &DVector<f64>,
    tol: f64,
) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let (rows, n) = (c.nrows(), c.ncols());
    let mut m = DMatrix::from_fn(rows, n + 1, |i, j| if j < n { c[(i, j)] } else { r[i] });
    let mut keep = Vec::new();
    let mut used = vec![false; rows];
    for _ in 0..rows.min(n) {
        // the largest remaining entry among unused rows
        let mut best = (0.0, 0, 0);
        for i in (0..rows).filter(|i| !used[*i]) {
            for j in 0..n {
                if m[(i, j)].abs() > best.0 {
                    best = (m[(i, j)].abs(), i, j);
                }
            }
        }
        if best.0 <= tol {
            break;
        }
        let (_, pi, pj) = best;
        used[pi] = true;
        keep.push(pi);
        for i in (0..rows).filter(|i| !used[*i]) {
            let factor = m[(i, pj)] / m[(pi, pj)];
            for j in 0..=n {
                m[(i, j)] -= factor * m[(pi, j)];
            }
        }
    }
    // what is left of the dropped rows must read 0 = 0
    if (0..rows)
        .filter(|i| !used[*i])
        .any(|i| m[(i, n)].abs() > tol * 10.0)
    {
        return None;
    }
    keep.sort_unstable();
    Some((
        DMatrix::from_fn(keep.len(), n, |a, j| c[(keep[a], j)]),
        DVector::from_fn(keep.len(), |a, _| r[keep[a]]),
    ))
}

/// `A x = b` by Gaussian elimination with partial pivoting; `None` when `A` is singular.
fn gauss(mut a: DMatrix<f64>, mut b: DVector<f64>) -> Option<DVector<f64>> {
    let n = a.nrows();
    let scale = a.amax().max(1e-300);
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[(i, col)].abs().total_cmp(&a[(j, col)].abs()))?;
        if a[(piv, col)].abs() <= 1e-11 * scale {
            return None;
        }
        a.swap_rows(col, piv);
        b.swap_rows(col, piv);
        for i in col + 1..n {
            let factor = a[(i, col)] / a[(col, col)];
            for j in col..n {
                a[(i, j)] -= factor * a[(col, j)];
            }
            b[i] -= factor * b[col];
        }
    }
    let mut x = DVector::zeros(n);
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|j| a[(i, j)] * x[j]).sum();
        x[i] = (b[i] - s) / a[(i, i)];
    }
    Some(x)
}

/// Rows `r` of `B`'s first `m` columns, and of the demand.
fn part(
    b: &DMatrix<f64>,
    v: &DVector<f64>,
    r: std::ops::Range<usize>,
) -> (DMatrix<f64>, DVector<f64>) {
    (
        b.rows(r.start, r.len()).into_owned(),
        v.rows(r.start, r.len()).into_owned(),
    )
}

/// Checks one allocation of `demand` against the oracle, stage by stage.
fn check<const K: usize>(
    actuators: &[Actuator<f64>],
    demand: SVector<f64, K>,
    priority: Priority,
    weights: &[f64],
    preferred: &[f64],
) {
    check_within(actuators, demand, priority, weights, preferred, &|_| ());
}

/// [`check`] within the actuators' bounds as `narrow` leaves them (failed actuators held).
fn check_within<const K: usize>(
    actuators: &[Actuator<f64>],
    demand: SVector<f64, K>,
    priority: Priority,
    weights: &[f64],
    preferred: &[f64],
    narrow: &dyn Fn(&mut Bounds<f64>),
) {
    let geometry = Geometry::<f64, K>::new(actuators).unwrap();
    check_on(geometry, demand, priority, weights, preferred, narrow);
}

/// [`check_within`] on a geometry built by the caller (with wheels, say); returns the
/// allocation checked.
fn check_on<const K: usize>(
    geometry: Geometry<f64, K>,
    demand: SVector<f64, K>,
    priority: Priority,
    weights: &[f64],
    preferred: &[f64],
    narrow: &dyn Fn(&mut Bounds<f64>),
) -> eqtrack_allocation::Allocation<f64, K> {
    let alloc = Allocator::new(geometry, weights, preferred, priority).unwrap();
    let mut bounds = alloc.bounds();
    narrow(&mut bounds);
    let got = alloc.allocate_within(&demand, &bounds);
    let m = geometry.count();
    assert!(
        got.status != Status::Stopped,
        "the iteration cap stopped it: {got:?}"
    );
    assert!(got.u.iter().all(|x| x.is_finite()));
    let b = DMatrix::from_fn(K, m, |i, j| geometry.effectiveness()[(i, j)]);
    let v = DVector::from_fn(K, |i, _| demand[i]);
    let lo = DVector::from_fn(m, |j, _| bounds.lo[j]);
    let hi = DVector::from_fn(m, |j, _| bounds.hi[j]);
    let u = DVector::from_fn(m, |j, _| got.u[j]);
    let scale = 1.0 + v.amax() + b.amax() * hi.amax().max(lo.amax());
    let tol = 1e-9 * scale;
    for j in 0..m {
        assert!(
            u[j] >= lo[j] - tol && u[j] <= hi[j] + tol,
            "u[{j}] = {} outside [{}, {}]",
            u[j],
            lo[j],
            hi[j]
        );
    }
    let none = DMatrix::zeros(0, m);
    let stage = |a: DMatrix<f64>, bb: DVector<f64>, c: DMatrix<f64>, d: DVector<f64>| Problem {
        a,
        b: bb,
        w: None,
        c,
        d,
        lo: lo.clone(),
        hi: hi.clone(),
    };
    let split = K == 6 && priority == Priority::Torque;
    let first = if split { 3 } else { K };
    // stage 1
    let (a1, b1) = part(&b, &v, 0..first);
    let (o1, _) = oracle(&stage(
        a1.clone(),
        b1.clone(),
        none.clone(),
        DVector::zeros(0),
    ));
    let star1 = &a1 * &o1;
    assert!(
        (&a1 * &u - &star1).amax() <= tol,
        "stage 1: achieved {} where the optimum is {} (demand {})",
        &a1 * &u,
        star1,
        b1
    );
    // stage 2
    let mut c_all = a1.clone();
    let mut d_all = star1.clone();
    if split {
        let (a2, b2) = part(&b, &v, 3..6);
        let (o2, _) = oracle(&stage(a2.clone(), b2, a1.clone(), star1.clone()));
        let star2 = &a2 * &o2;
        assert!(
            (&a2 * &u - &star2).amax() <= tol,
            "stage 2: force {} where the optimum is {}",
            &a2 * &u,
            star2
        );
        c_all = b.clone();
        d_all = DVector::from_iterator(6, star1.iter().chain(star2.iter()).copied());
    }
    // stage 3: unique
    let w = if weights.is_empty() {
        DVector::from_element(m, 1.0)
    } else {
        DVector::from_row_slice(weights)
    };
    let up = if preferred.is_empty() {
        DVector::zeros(m)
    } else {
        DVector::from_row_slice(preferred)
    };
    let up = up.zip_zip_map(&lo, &hi, |p, l, h| p.max(l).min(h));
    let p3 = Problem {
        a: DMatrix::zeros(0, m),
        b: DVector::zeros(0),
        w: Some((w, up)),
        c: c_all,
        d: d_all,
        lo: lo.clone(),
        hi: hi.clone(),
    };
    let (o3, v3) = oracle(&p3);
    assert!(
        (p3.value(&u) - v3).abs() <= tol * (1.0 + v3.abs()),
        "stage 3: value {} where the optimum is {v3}: u {u}, oracle {o3}, demand {v}, B u {}, oracle B u {}",
        p3.value(&u),
        &b * &u,
        &b * &o3
    );
    assert!(
        (&u - &o3).amax() <= 1e-7 * scale,
        "stage 3: u = {u} where the optimum is {o3}"
    );
    let achieved: SVector<f64, K> = got.achieved;
    assert!((achieved - geometry.wrench(&got.u)).amax() == 0.0);
    got
}

fn hexarotor() -> [Actuator<f64>; 6] {
    presets::hexarotor(0.25, 0.5, 0.016, 8.0)
}

fn rov() -> [Actuator<f64>; 8] {
    presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)
}

fn random_geometry(rng: &mut ChaCha8Rng, m: usize) -> Vec<Actuator<f64>> {
    let mut x = || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    (0..m)
        .map(|_| {
            let max = 1.0 + 4.0 * (x() + 1.0);
            let min = if x() > 0.0 {
                0.0
            } else {
                -max * (x() + 1.0) / 2.0
            };
            Actuator {
                position: [x(), x(), x() * 0.3],
                axis: [x(), x(), x()],
                torque_per_thrust: 0.05 * x(),
                min,
                max,
            }
        })
        .collect()
}

fn random_wrench<const K: usize>(rng: &mut ChaCha8Rng, size: f64) -> SVector<f64, K> {
    SVector::from_fn(|_, _| size * ((rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0))
}

#[test]
fn the_presets_meet_each_stage_optimum_on_feasible_and_infeasible_wrenches() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    // the hexarotor's hover wrench, a tilted hover, and wrenches up to well past its reach
    let hover = SVector::<f64, 6>::from([0.0, 0.0, 0.0, 0.0, 0.0, 20.0]);
    check(&hexarotor(), hover, Priority::Torque, &[], &[]);
    for size in [0.5, 2.0, 10.0, 40.0] {
        for _ in 0..4 {
            let mut w = random_wrench::<6>(&mut rng, size);
            w[5] += 20.0;
            check(&hexarotor(), w, Priority::Torque, &[], &[]);
            check(&hexarotor(), w, Priority::None, &[], &[]);
        }
    }
    for size in [5.0, 50.0, 200.0] {
        for _ in 0..3 {
            let w = random_wrench::<6>(&mut rng, size);
            check(&rov(), w, Priority::Torque, &[], &[]);
            check(
                &rov(),
                w,
                Priority::None,
                &[1.0, 2.0, 1.0, 0.5, 1.0, 1.0, 3.0, 1.0],
                &[1.0; 8],
            );
        }
    }
}

#[test]
fn random_geometries_meet_each_stage_optimum() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut tried = 0;
    while tried < 40 {
        let m = 6 + (rng.next_u64() % 2) as usize;
        let acts = random_geometry(&mut rng, m);
        if Geometry::<f64, 6>::new(&acts).is_err() {
            continue;
        }
        tried += 1;
        let size = [0.5, 3.0, 20.0][tried % 3];
        let w = random_wrench::<6>(&mut rng, size);
        let priority = if tried % 2 == 0 {
            Priority::Torque
        } else {
            Priority::None
        };
        check(&acts, w, priority, &[], &[]);
        // on SO(3): the torque rows alone
        let acts3 = random_geometry(&mut rng, 4 + (tried % 3));
        if Geometry::<f64, 3>::new(&acts3).is_ok() {
            check(
                &acts3,
                random_wrench::<3>(&mut rng, size),
                Priority::Torque,
                &[],
                &[],
            );
        }
    }
}

#[test]
fn under_saturation_torque_priority_keeps_the_torque_and_none_does_not() {
    // a yaw torque and a climb the hexarotor cannot both give: torque first keeps the torque
    let demand = SVector::<f64, 6>::from([0.0, 0.0, 1.2, 0.0, 0.0, 45.0]);
    let g = Geometry::<f64, 6>::new(&hexarotor()).unwrap();
    let torque = Allocator::new(g, &[], &[], Priority::Torque)
        .unwrap()
        .allocate(&demand);
    let none = Allocator::new(g, &[], &[], Priority::None)
        .unwrap()
        .allocate(&demand);
    assert_eq!(torque.status, Status::ForceGivenUp);
    assert!(
        (torque.achieved.fixed_rows::<3>(0) - demand.fixed_rows::<3>(0)).amax() < 1e-9,
        "{torque:?}"
    );
    assert!(
        torque.achieved[5] < demand[5] - 1.0,
        "the force is given up: {}",
        torque.achieved[5]
    );
    assert_eq!(none.status, Status::TorqueInfeasible);
    let torque_miss = (none.achieved.fixed_rows::<3>(0) - demand.fixed_rows::<3>(0)).norm();
    assert!(
        torque_miss > 1e-3,
        "with no priority the torque is not kept: miss {torque_miss}"
    );
    assert!(
        none.achieved[5] > torque.achieved[5],
        "and more of the force is: {} vs {}",
        none.achieved[5],
        torque.achieved[5]
    );
    // with bounds that never bind, the answer meets the demand, and u_pref decides the rest
    let small = SVector::<f64, 6>::from([0.01, -0.02, 0.01, 0.1, -0.1, 20.0]);
    let a = Allocator::new(g, &[], &[], Priority::Torque)
        .unwrap()
        .allocate(&small);
    assert_eq!(a.status, Status::Met);
    assert!((a.achieved - small).amax() < 1e-9);
}

#[test]
fn a_failed_actuator_is_held_and_the_rest_take_over() {
    let g = Geometry::<f64, 6>::new(&rov()).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let demand = SVector::<f64, 6>::from([1.0, -2.0, 3.0, 20.0, -10.0, 5.0]);
    let mut bounds = alloc.bounds();
    bounds.fail(2, 0.0);
    let a = alloc.allocate_within(&demand, &bounds);
    assert_eq!(
        a.u[2], 0.0,
        "the failed thruster is held at its stuck value"
    );
    assert_eq!(
        a.status,
        Status::Met,
        "seven thrusters still reach this wrench: {a:?}"
    );
    assert!((a.achieved - demand).amax() < 1e-9);
    // a thruster stuck at full thrust is held there too
    let mut stuck = alloc.bounds();
    stuck.fail(5, 40.0);
    let a = alloc.allocate_within(&demand, &stuck);
    assert_eq!(a.u[5], 40.0);
}

#[test]
fn never_nan() {
    let g = Geometry::<f64, 6>::new(&hexarotor()).unwrap();
    let alloc = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    for bad in [f64::NAN, f64::INFINITY, -f64::INFINITY] {
        let mut d = SVector::<f64, 6>::zeros();
        d[1] = bad;
        let a = alloc.allocate(&d);
        assert_eq!(a.status, Status::InvalidDemand);
        assert!(a.u.iter().all(|x| x.is_finite()));
    }
    let huge = SVector::<f64, 6>::from_element(1e12);
    let a = alloc.allocate(&huge);
    assert!(a.u.iter().all(|x| x.is_finite()) && a.achieved.iter().all(|x| x.is_finite()));
    assert!(a.u.iter().take(6).all(|x| (0.0..=8.0).contains(x)));
    assert_eq!(a.u.len(), MAX_ACTUATORS);
}

#[test]
fn f32_allocates_like_f64() {
    let h32 = presets::hexarotor::<f32>(0.25, 0.5, 0.016, 8.0);
    let g32 = Geometry::<f32, 6>::new(&h32).unwrap();
    let g64 = Geometry::<f64, 6>::new(&hexarotor()).unwrap();
    let d = [0.1, -0.2, 0.05, 1.0, 0.5, 22.0];
    let a32 = Allocator::new(g32, &[], &[], Priority::Torque)
        .unwrap()
        .allocate(&SVector::from(d.map(|x| x as f32)));
    let a64 = Allocator::new(g64, &[], &[], Priority::Torque)
        .unwrap()
        .allocate(&SVector::from(d));
    for j in 0..6 {
        assert!(
            (a32.u[j] as f64 - a64.u[j]).abs() < 1e-3,
            "{j}: {} vs {}",
            a32.u[j],
            a64.u[j]
        );
    }
}

#[test]
fn failed_actuators_held_at_a_value_meet_each_stage_optimum() {
    // a failed actuator is a bound with min = max: one and two of them, on each preset and on
    // random geometries, demands within reach and far past it
    let mut rng = ChaCha8Rng::seed_from_u64(44);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let fail = |acts: &mut [Actuator<f64>], j: usize, at: f64| {
        let a = &mut acts[j % acts.len()];
        let v = a.min + (a.max - a.min) * (at + 1.0) / 2.0;
        (a.min, a.max) = (v, v);
    };
    for i in 0..12 {
        let size = [0.5, 5.0, 40.0][i % 3];
        let mut hex = hexarotor();
        fail(&mut hex, i, x());
        if i % 2 == 1 {
            fail(&mut hex, i + 3, x());
        }
        if Geometry::<f64, 6>::new(&hex).is_ok() {
            let mut w = SVector::<f64, 6>::from_fn(|_, _| size * x());
            w[5] += 20.0;
            check(&hex, w, Priority::Torque, &[], &[]);
        }
        let mut r = rov();
        fail(&mut r, i, x());
        if i % 2 == 0 {
            fail(&mut r, i + 5, x());
        }
        let w = SVector::<f64, 6>::from_fn(|_, _| 4.0 * size * x());
        check(&r, w, Priority::Torque, &[], &[]);
        check(
            &r,
            w,
            Priority::None,
            &[1.0, 2.0, 1.0, 0.5, 1.0, 1.0, 3.0, 1.0],
            &[],
        );
    }
}

#[test]
fn the_hexarotor_with_any_two_rotors_held_meets_each_stage_optimum() {
    // the six-rotor hexarotor's stages 1 and 2 by the dual method
    // (docs/maths.md, "Control allocation": stage 1 of a square geometry): every rotor and every pair held at a value
    // within its range, a pair of opposite rotors leaving the torques the rest reach flat (a
    // plane), on demands within reach and far past it
    let mut rng = ChaCha8Rng::seed_from_u64(45);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let hex = hexarotor();
    for i in 0..6 {
        for j in i..6 {
            for size in [0.5, 3.0, 20.0] {
                let (a, b) = (4.0 * (x() + 1.0), 4.0 * (x() + 1.0));
                let mut w = SVector::<f64, 6>::from_fn(|_, _| size * x());
                w[5] += 30.0;
                check_within(&hex, w, Priority::Torque, &[], &[], &|bounds| {
                    bounds.fail(i, a);
                    if j != i {
                        bounds.fail(j, b);
                    }
                });
            }
        }
    }
}

#[test]
fn the_rov_with_any_two_thrusters_held_meets_each_stage_optimum() {
    // the ROV's blocks by their reach (docs/maths.md, "Control allocation": geometries in
    // blocks): every thruster and every pair held at a value within its range, a pair in one
    // block leaving two movable thrusters there (a flat reach, every stage in closed form, a
    // diagonal pair's two columns alike in the roll and pitch rows), with weights and
    // preferred commands, on demands within reach and far past it
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let rov = rov();
    for i in 0..8 {
        for j in i..8 {
            for size in [2.0, 20.0, 200.0] {
                let (a, b) = (40.0 * x(), 40.0 * x());
                let w = SVector::<f64, 6>::from_fn(|_, _| size * x());
                let weights: Vec<f64> = (0..8).map(|_| 1.5 + x()).collect();
                let preferred: Vec<f64> = (0..8).map(|_| 20.0 * x()).collect();
                for (priority, weights, preferred) in [
                    (Priority::Torque, &[][..], &[][..]),
                    (Priority::Torque, &weights[..], &preferred[..]),
                    (Priority::None, &weights[..], &[][..]),
                ] {
                    check_within(&rov, w, priority, weights, preferred, &|bounds| {
                        bounds.fail(i, a);
                        if j != i {
                            bounds.fail(j, b);
                        }
                    });
                }
            }
        }
    }
}

#[test]
fn a_rov_with_a_block_of_three_thrusters_meets_each_stage_optimum() {
    // a block of three rows and three actuators by its reach
    // (docs/maths.md, "Control allocation": a block of three rows by its reach): the ROV without one horizontal or one
    // vertical thruster, its stages' wrench giving the one command of that block; with each
    // thruster held in turn (two left to move in the block of three: every stage in closed
    // form), with weights and preferred commands, under both priorities
    let mut rng = ChaCha8Rng::seed_from_u64(48);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    for dropped in [3, 7] {
        let seven: Vec<Actuator<f64>> = rov()
            .into_iter()
            .enumerate()
            .filter(|(j, _)| *j != dropped)
            .map(|(_, a)| a)
            .collect();
        for held in 0..8 {
            for size in [2.0, 20.0, 200.0] {
                let at = 40.0 * x();
                let w = SVector::<f64, 6>::from_fn(|_, _| size * x());
                let weights: Vec<f64> = (0..7).map(|_| 1.5 + x()).collect();
                let preferred: Vec<f64> = (0..7).map(|_| 20.0 * x()).collect();
                for (priority, weights, preferred) in [
                    (Priority::Torque, &[][..], &[][..]),
                    (Priority::Torque, &weights[..], &preferred[..]),
                    (Priority::None, &weights[..], &[][..]),
                ] {
                    check_within(&seven, w, priority, weights, preferred, &|bounds| {
                        if held < 7 {
                            bounds.fail(held, at);
                        }
                    });
                }
            }
        }
    }
}

/// A random decoupled actuator on SO(3): a couple about body axis `row` (`p = L e_{r+1}`,
/// `a = ±e_{r+2}`, so `p × a = ±L e_r`), one-way or reversible; with `row` 3, one whose
/// column is zero (it pushes through the centre of mass).
fn couple(x: &mut impl FnMut() -> f64, row: usize) -> Actuator<f64> {
    let e = |i: usize| core::array::from_fn::<f64, 3, _>(|k| if k == i % 3 { 1.0 } else { 0.0 });
    let max = 0.5 + 2.0 * (x() + 1.0);
    let min = if x() > 0.0 {
        0.0
    } else {
        -max * (x() + 1.5) / 2.5
    };
    let sign = if x() > 0.0 { 1.0 } else { -1.0 };
    let arm = 0.2 + (x() + 1.0);
    let (position, axis) = if row == 3 {
        (e(0).map(|v| v * arm), e(0))
    } else {
        (e(row + 1).map(|v| v * arm), e(row + 2).map(|v| v * sign))
    };
    Actuator {
        position,
        axis,
        torque_per_thrust: 0.0,
        min,
        max,
    }
}

#[test]
fn decoupled_geometries_meet_each_stage_optimum_in_closed_form() {
    // the twelve-thruster spacecraft and random decoupled geometries (each column moves one
    // row, a few move none): demands within reach and far past it, weights and preferred
    // commands, actuators held; every stage's optimum, with no active-set iteration
    let mut rng = ChaCha8Rng::seed_from_u64(61);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let (mut checked, mut saturated) = (0, 0);
    for i in 0..60 {
        let acts: Vec<Actuator<f64>> = if i % 3 == 0 {
            presets::spacecraft_twelve(0.9, 1.5).to_vec()
        } else {
            let m = 4 + i % 9;
            (0..m)
                .map(|j| {
                    let row = if j < 3 {
                        j
                    } else {
                        (x().abs() * 3.999) as usize
                    };
                    couple(&mut x, if i % 5 == 0 && j == m - 1 { 3 } else { row })
                })
                .collect()
        };
        let Ok(geometry) = Geometry::<f64, 3>::new(&acts) else {
            continue;
        };
        let m = acts.len();
        let size = [0.3, 2.0, 12.0][i % 3];
        let demand = SVector::<f64, 3>::from_fn(|_, _| size * x());
        let weights: Vec<f64> = if i % 2 == 0 {
            vec![]
        } else {
            (0..m).map(|_| 1.25 + x()).collect()
        };
        let preferred: Vec<f64> = if i % 4 < 2 {
            vec![]
        } else {
            (0..m).map(|_| 2.0 * x()).collect()
        };
        let (held, at) = ((i * 7) % m, x());
        let narrow = |b: &mut Bounds<f64>| {
            if i % 3 != 2 {
                let v = b.lo[held] + (b.hi[held] - b.lo[held]) * (at + 1.0) / 2.0;
                b.fail(held, v);
                if i % 2 == 0 {
                    b.fail((held + 5) % m, b.lo[(held + 5) % m]);
                }
            }
        };
        let got = check_on(
            geometry,
            demand,
            Priority::Torque,
            &weights,
            &preferred,
            &narrow,
        );
        // past the reach the active set would iterate: none here
        assert_eq!(
            got.iterations, 0,
            "case {i}: the closed form did not answer: {got:?}"
        );
        checked += 1;
        saturated += usize::from(got.status != Status::Met);
    }
    assert!(
        checked >= 50 && saturated >= 15,
        "{checked} geometries checked, {saturated} saturated"
    );
}

#[test]
fn a_decoupled_geometry_with_wheels_meets_each_stage_optimum_on_se3() {
    // three thrusters through the centre of mass along the body axes (pure forces, both ways)
    // and three wheels on the body axes (pure torques): each column moves one row of six
    let thrusters: Vec<Actuator<f64>> = (0..3)
        .map(|k| Actuator {
            position: [0.0; 3],
            axis: core::array::from_fn(|i| if i == k { 1.0 } else { 0.0 }),
            torque_per_thrust: 0.0,
            min: -2.0 - k as f64,
            max: 4.0,
        })
        .collect();
    let wheels: Vec<eqtrack_allocation::Wheel<f64>> = (0..3)
        .map(|k| eqtrack_allocation::Wheel {
            axis: core::array::from_fn(|i| if i == k { 1.0 } else { 0.0 }),
            inertia: 0.01,
            max_torque: 0.1 + 0.05 * k as f64,
            max_speed: 600.0,
        })
        .collect();
    let geometry = Geometry::<f64, 6>::with_wheels(&thrusters, &wheels).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(62);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let mut saturated = 0;
    for i in 0..24 {
        let size = [0.05, 0.5, 8.0][i % 3];
        let demand =
            SVector::<f64, 6>::from_fn(|r, _| if r < 3 { size } else { 10.0 * size } * x());
        let priority = [Priority::Torque, Priority::None][i % 2];
        let weights: Vec<f64> = (0..6).map(|_| 1.25 + x()).collect();
        let got = check_on(geometry, demand, priority, &weights, &[], &|_| ());
        assert_eq!(got.iterations, 0, "case {i}: {got:?}");
        saturated += usize::from(got.status != Status::Met);
    }
    assert!(saturated >= 8, "{saturated} of 24 saturated");
}

/// A random thruster of one of two families that keep an SE(3) wrench in two blocks: one in
/// the plane z = 0 pushing within it (it moves `τz, fx, fy`), or one pushing along z (`τx, τy,
/// fz`), as the BlueROV2 Heavy's horizontal and vertical thrusters; one-way or reversible.
fn in_a_block(x: &mut impl FnMut() -> f64, vertical: bool) -> Actuator<f64> {
    let max = 5.0 + 20.0 * (x() + 1.0);
    let min = if x() > -0.3 { -max } else { 0.0 };
    let angle = std::f64::consts::PI * x();
    Actuator {
        position: [0.4 * x(), 0.3 * x(), if vertical { 0.1 * x() } else { 0.0 }],
        axis: if vertical {
            [0.0, 0.0, if x() > 0.0 { 1.0 } else { -1.0 }]
        } else {
            [angle.cos(), angle.sin(), 0.0]
        },
        torque_per_thrust: 0.0,
        min,
        max,
    }
}

#[test]
fn geometries_in_two_blocks_meet_each_stage_optimum() {
    // random ROV-like layouts (three or four thrusters in each block, and now and then a
    // surge thruster on the centreline), demands within reach and far past it, both
    // priorities, weights and preferred commands, thrusters held inside their range or at a
    // bound
    let mut rng = ChaCha8Rng::seed_from_u64(63);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let mut checked = 0;
    for i in 0..48 {
        let (h, v) = (3 + i % 2, 3 + (i / 2) % 2);
        let mut acts: Vec<Actuator<f64>> = (0..h + v).map(|j| in_a_block(&mut x, j >= h)).collect();
        if i % 4 == 3 {
            // in the horizontal block by `fx` alone, with a zero in its torque row `τz`
            // (stage 1 of one row under the torque priority)
            let sign = if x() > 0.0 { 1.0 } else { -1.0 };
            acts.push(Actuator {
                position: [0.2 * x(), 0.0, 0.0],
                axis: [sign, 0.0, 0.0],
                torque_per_thrust: 0.0,
                min: if x() > 0.0 { -30.0 } else { 0.0 },
                max: 30.0,
            });
        }
        let Ok(geometry) = Geometry::<f64, 6>::new(&acts) else {
            continue;
        };
        let m = acts.len();
        let size = [3.0, 20.0, 120.0][i % 3];
        let demand = SVector::<f64, 6>::from_fn(|_, _| size * x());
        let priority = [Priority::Torque, Priority::None][(i / 4) % 2];
        let (weights, preferred): (Vec<f64>, Vec<f64>) = if i % 4 < 2 {
            (vec![], vec![])
        } else {
            (
                (0..m).map(|_| 1.25 + x()).collect(),
                (0..m).map(|_| 5.0 * x()).collect(),
            )
        };
        let (held, at) = ((i * 5) % m, x());
        let narrow = |b: &mut Bounds<f64>| match i % 3 {
            1 => b.fail(
                held,
                b.lo[held] + (b.hi[held] - b.lo[held]) * (at + 1.0) / 2.0,
            ),
            2 => b.fail(held, if at > 0.0 { b.hi[held] } else { b.lo[held] }),
            _ => {}
        };
        check_on(geometry, demand, priority, &weights, &preferred, &narrow);
        checked += 1;
    }
    assert!(checked >= 36, "{checked} geometries checked");
}
