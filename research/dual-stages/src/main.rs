use eqtrack_allocation::{Allocator, Geometry, Priority, presets};
use firmware_cases::demands::{self, KINDS, PER_KIND, Seeded};
use nalgebra::{DMatrix, DVector, Matrix6, SMatrix, Vector3, Vector6};

/// Goldfarb–Idnani with H = I on min ½‖x‖² s.t. l ≤ S x + c ≤ h (6 rows, 3 unknowns).
/// Returns x and the count of working-set changes (adds + drops).
fn dual(
    s: &SMatrix<f64, 6, 3>,
    c: &Vector6<f64>,
    lo: &[f64; 6],
    hi: &[f64; 6],
) -> Option<(Vector3<f64>, usize)> {
    let normal = |k: usize| -> (Vector3<f64>, f64) {
        let i = k / 2;
        let row: Vector3<f64> = s.row(i).transpose();
        if k % 2 == 0 {
            (row, lo[i] - c[i])
        } else {
            (-row, -(hi[i] - c[i]))
        }
    };
    let mut x = Vector3::zeros();
    let mut active: Vec<usize> = vec![];
    let mut lambda: Vec<f64> = vec![];
    let mut changes = 0;
    for _outer in 0..50 {
        // the most violated constraint, scaled
        let mut best: Option<(usize, f64)> = None;
        for k in 0..12 {
            if active.contains(&k) {
                continue;
            }
            let (n, b) = normal(k);
            let v = (b - n.dot(&x)) / n.norm();
            if v > 1e-12 * (1.0 + b.abs()) && best.is_none_or(|(_, w)| v > w) {
                best = Some((k, v));
            }
        }
        let Some((p, _)) = best else {
            return Some((x, changes));
        };
        let (np, bp) = normal(p);
        let mut lp = 0.0;
        loop {
            let na = active.len();
            let nmat = DMatrix::from_fn(3, na, |r, a| normal(active[a]).0[r]);
            let r: DVector<f64> = if na == 0 {
                DVector::zeros(0)
            } else {
                let g = nmat.transpose() * &nmat;
                g.try_inverse()? * (nmat.transpose() * DVector::from_column_slice(np.as_slice()))
            };
            let nr = &nmat * &r;
            let z = np - Vector3::new(nr[0], nr[1], nr[2]);
            let t1 = if z.norm() > 1e-12 * np.norm() {
                (bp - np.dot(&x)) / z.dot(&np)
            } else {
                f64::INFINITY
            };
            let mut t2 = f64::INFINITY;
            let mut l = None;
            for a in 0..na {
                if r[a] > 1e-14 {
                    let t = lambda[a] / r[a];
                    if t < t2 {
                        t2 = t;
                        l = Some(a);
                    }
                }
            }
            let t = t1.min(t2);
            if !t.is_finite() {
                return None;
            }
            if t1.is_finite() {
                x += z * t;
            }
            for a in 0..na {
                lambda[a] -= t * r[a];
            }
            lp += t;
            changes += 1;
            if t1 <= t2 {
                active.push(p);
                lambda.push(lp);
                break;
            }
            let l = l.unwrap();
            active.remove(l);
            lambda.remove(l);
        }
    }
    None
}

fn study(name: &str, a32: &Allocator<f32, 6>, a64: &Allocator<f64, 6>) {
    let mut rng = Seeded::new(demands::seed(name));
    let n = KINDS.len() * PER_KIND;
    let m = a64.geometry().count();
    assert_eq!(m, 6);
    let b = a64.geometry().effectiveness();
    let b6 = Matrix6::from_fn(|r, j| b[(r, j)]);
    let inv = b6.try_inverse().unwrap();
    let p: SMatrix<f64, 6, 3> = inv.fixed_view::<6, 3>(0, 0).into_owned();
    let s: SMatrix<f64, 6, 3> = inv.fixed_view::<6, 3>(0, 3).into_owned();
    let mut hist_old = [0usize; 40];
    let mut hist_new = [0usize; 40];
    let mut worst_err: f64 = 0.0;
    let mut failed = 0;
    for i in 0..n {
        let (d32, b32) = demands::demand(a32, i, &mut rng);
        let d = d32.map(f64::from);
        let mut bounds = a64.bounds();
        for j in 0..m {
            bounds.lo[j] = f64::from(b32.lo[j]);
            bounds.hi[j] = f64::from(b32.hi[j]);
        }
        let all = a64.allocate_within(&d, &bounds);
        let first = a64.allocate_first_stage(&d, &bounds, None);
        if all.iterations == 0 {
            continue;
        }
        let old2 = (all.iterations - first.iterations) as usize;
        hist_old[old2.min(39)] += 1;
        let u1 = first.u;
        let w1 = b * u1;
        let tau = Vector3::new(w1[0], w1[1], w1[2]);
        let fd = Vector3::new(d[3], d[4], d[5]);
        let c = p * tau + s * fd;
        let lo: [f64; 6] = core::array::from_fn(|j| bounds.lo[j]);
        let hi: [f64; 6] = core::array::from_fn(|j| bounds.hi[j]);
        match dual(&s, &c, &lo, &hi) {
            Some((x, k)) => {
                hist_new[k.min(39)] += 1;
                let u = c + s * x;
                let scale = (0..6).fold(0.0f64, |a, j| a.max(lo[j].abs()).max(hi[j].abs()));
                let err = (0..6).fold(0.0f64, |a, j| a.max((u[j] - all.u[j]).abs())) / scale;
                if err > 1e-9 {
                    println!(
                        "  demand {i} ({}): differs by {err:e}: dual {:?} ref {:?}",
                        KINDS[i / PER_KIND],
                        u.as_slice(),
                        &all.u.as_slice()[..6]
                    );
                }
                worst_err = worst_err.max(err);
            }
            None => {
                failed += 1;
                println!("  demand {i}: dual failed");
            }
        }
    }
    let show = |h: &[usize; 40]| {
        h.iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(k, c)| format!("{k}:{c}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "{name}: stage 2 iterations, the allocator: {}",
        show(&hist_old)
    );
    println!(
        "{name}: stage 2 changes, dual in f:        {}",
        show(&hist_new)
    );
    println!("{name}: worst |u - u_ref| / bound {worst_err:e}, dual failures {failed}");
}

fn main() {
    let a32 = demands::hexarotor().unwrap();
    let g = Geometry::new(&presets::hexarotor(0.25f64, 0.5, 0.016, 8.0)).unwrap();
    let a64 = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    study("hexarotor", &a32, &a64);
    let r32 = demands::rov().unwrap();
    let r64 = Allocator::new(
        Geometry::new(&presets::rov_heavy(0.4f64, 0.3, 0.12, 0.22, 40.0)).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap();
    last_stage("rov", &r32, &r64);
    let s32 = demands::spacecraft().unwrap();
    let s64 = Allocator::new(
        Geometry::new(&presets::spacecraft_twelve(0.5f64, 3.0)).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap();
    last_stage("spacecraft", &s32, &s64);
    split("hexarotor", &a32);
    split("rov", &r32);
    split("spacecraft", &s32);
}

/// Goldfarb–Idnani with H = I: min ½‖u − up‖² s.t. E u = e (always active), lo ≤ u ≤ hi
/// (m unknowns). Returns u and the count of working-set changes.
fn dual_u(
    e_rows: &DMatrix<f64>,
    e: &DVector<f64>,
    up: &DVector<f64>,
    lo: &[f64],
    hi: &[f64],
) -> Option<(DVector<f64>, usize)> {
    let m = up.len();
    let ke = e_rows.nrows();
    // the equality-constrained minimiser
    let g = e_rows * e_rows.transpose();
    let gi = g.try_inverse()?;
    let mut u = up + e_rows.transpose() * (&gi * (e - e_rows * up));
    let normal = |k: usize| -> (DVector<f64>, f64) {
        let j = k / 2;
        let mut n = DVector::zeros(m);
        if k % 2 == 0 {
            n[j] = 1.0;
            (n, lo[j])
        } else {
            n[j] = -1.0;
            (n, -hi[j])
        }
    };
    let mut active: Vec<usize> = vec![];
    let mut lambda: Vec<f64> = vec![];
    let mut changes = 0;
    for _ in 0..100 {
        let mut best: Option<(usize, f64)> = None;
        for k in 0..2 * m {
            if active.contains(&k) {
                continue;
            }
            let (n, b) = normal(k);
            let v = b - n.dot(&u);
            if v > 1e-12 * (1.0 + b.abs()) && best.is_none_or(|(_, w)| v > w) {
                best = Some((k, v));
            }
        }
        let Some((p, _)) = best else {
            return Some((u, changes));
        };
        let (np, bp) = normal(p);
        let mut lp = 0.0;
        loop {
            let na = active.len();
            let mut nmat = DMatrix::zeros(m, ke + na);
            for r in 0..ke {
                for j in 0..m {
                    nmat[(j, r)] = e_rows[(r, j)];
                }
            }
            for a in 0..na {
                let (n, _) = normal(active[a]);
                nmat.set_column(ke + a, &n);
            }
            let gg = nmat.transpose() * &nmat;
            let r = gg.try_inverse()? * (nmat.transpose() * &np);
            let z = &np - &nmat * &r;
            let t1 = if z.norm() > 1e-12 {
                (bp - np.dot(&u)) / z.dot(&np)
            } else {
                f64::INFINITY
            };
            let mut t2 = f64::INFINITY;
            let mut l = None;
            for a in 0..na {
                if r[ke + a] > 1e-14 {
                    let t = lambda[a] / r[ke + a];
                    if t < t2 {
                        t2 = t;
                        l = Some(a);
                    }
                }
            }
            let t = t1.min(t2);
            if !t.is_finite() {
                return None;
            }
            if t1.is_finite() {
                u += &z * t;
            }
            for a in 0..na {
                lambda[a] -= t * r[ke + a];
            }
            lp += t;
            changes += 1;
            if t1 <= t2 {
                active.push(p);
                lambda.push(lp);
                break;
            }
            let l = l.unwrap();
            active.remove(l);
            lambda.remove(l);
        }
    }
    None
}

pub fn last_stage<const K: usize>(name: &str, a32: &Allocator<f32, K>, a64: &Allocator<f64, K>) {
    let mut rng = Seeded::new(demands::seed(name));
    let n = KINDS.len() * PER_KIND;
    let m = a64.geometry().count();
    let b = a64.geometry().effectiveness();
    let bm = DMatrix::from_fn(K, m, |r, j| b[(r, j)]);
    let mut hist = [0usize; 60];
    let mut worst_err: f64 = 0.0;
    let mut failed = 0;
    for i in 0..n {
        let (d32, b32) = demands::demand(a32, i, &mut rng);
        let d = d32.map(f64::from);
        let mut bounds = a64.bounds();
        for j in 0..m {
            bounds.lo[j] = f64::from(b32.lo[j]);
            bounds.hi[j] = f64::from(b32.hi[j]);
        }
        let all = a64.allocate_within(&d, &bounds);
        if all.iterations == 0 {
            continue;
        }
        let lo: Vec<f64> = (0..m).map(|j| bounds.lo[j]).collect();
        let hi: Vec<f64> = (0..m).map(|j| bounds.hi[j]).collect();
        let uref = DVector::from_fn(m, |j, _| all.u[j]);
        let e = &bm * &uref;
        let up = DVector::from_fn(m, |j, _| 0.0f64.max(lo[j]).min(hi[j]));
        match dual_u(&bm, &e, &up, &lo, &hi) {
            Some((u, k)) => {
                hist[k.min(59)] += 1;
                let scale = (0..m).fold(0.0f64, |a, j| a.max(lo[j].abs()).max(hi[j].abs()));
                let err = (&u - &uref).amax() / scale;
                if err > 1e-9 {
                    println!("  demand {i} ({}): differs by {err:e}", KINDS[i / PER_KIND]);
                }
                worst_err = worst_err.max(err);
            }
            None => {
                failed += 1;
                println!("  demand {i}: dual failed");
            }
        }
    }
    let show = |h: &[usize; 60]| {
        h.iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(k, c)| format!("{k}:{c}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!(
        "{name}: last stage by the dual in u (from the answer's wrench): {}",
        show(&hist)
    );
    println!("{name}: worst |u - u_ref| / bound {worst_err:e}, dual failures {failed}");
}

pub fn split<const K: usize>(name: &str, a: &Allocator<f32, K>) {
    let mut rng = Seeded::new(demands::seed(name));
    let n = KINDS.len() * PER_KIND;
    let mut h = [[0usize; 20]; 3];
    let mut worst = (0, 0, 0, 0);
    for i in 0..n {
        let (d, b) = demands::demand(a, i, &mut rng);
        let t = a.allocate_within(&d, &b).iterations as usize;
        let s1 = a.allocate_first_stage(&d, &b, None).iterations as usize;
        let s12 = a.allocate_two_stages(&d, &b).iterations as usize;
        let (x, y, z) = (s1, s12 - s1, t - s12);
        h[0][x.min(19)] += 1;
        h[1][y.min(19)] += 1;
        h[2][z.min(19)] += 1;
        if t > worst.0 {
            worst = (t, x, y, z);
        }
    }
    for (k, row) in h.iter().enumerate() {
        println!(
            "{name} (f32) stage {}: {}",
            k + 1,
            row.iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(k, c)| format!("{k}:{c}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    println!(
        "{name} (f32) worst total {} = {} + {} + {}",
        worst.0, worst.1, worst.2, worst.3
    );
}
