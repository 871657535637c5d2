//! One stage of the allocation: the convex quadratic programme
//! `min ½ uᵀHu + gᵀu` subject to `C u = d` and `lo ≤ u ≤ hi`, by a primal active-set method
//! with the null-space step (docs/maths.md, "Control allocation": the active-set method).

use crate::{Commands, MAX_ACTUATORS};
use nalgebra::{Cholesky, QR, RealField, SMatrix, SVector, SymmetricEigen};

const N: usize = MAX_ACTUATORS;

/// The most equality rows a stage has (the whole wrench on SE(3)).
pub(crate) const MAX_EQ: usize = 6;

/// A stage's programme. `H` is positive semidefinite (definite on the last stage); the first `k` rows of `c` are the
/// equality constraints (linearly independent), the rest zero.
pub(crate) struct Qp<T> {
    /// `H` is positive definite (the last stage): the reduced step by Cholesky.
    pub(crate) definite: bool,
    pub(crate) h: SMatrix<T, N, N>,
    pub(crate) g: Commands<T>,
    pub(crate) c: SMatrix<T, MAX_EQ, N>,
    pub(crate) k: usize,
}

/// A stage's answer.
pub(crate) struct Solved<T> {
    pub(crate) u: Commands<T>,
    pub(crate) iterations: u32,
    /// The iteration cap was reached (or a factorisation failed) before the optimum:
    /// `u` is the last iterate, feasible and finite.
    pub(crate) stopped: bool,
}

/// Whether an actuator is in the working set, and at which bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bound {
    Free,
    Lower,
    Upper,
}

/// The working set's constraint normals as the columns of a matrix (`C`'s rows, then `+e_i`
/// for a lower bound, `−e_i` for an upper one), factored `Aᵀ = Q R`.
struct Factored<T: RealField + Copy> {
    q: SMatrix<T, N, N>,
    r: SMatrix<T, N, N>,
    /// The number of constraints in the working set (its columns come first).
    w: usize,
    /// Which actuator each column past `k` fixes.
    fixes: [usize; N],
}

/// The working set's normals, factored; `None` when they are not linearly independent.
fn factor<T: RealField + Copy>(qp: &Qp<T>, work: &[Bound; N]) -> Option<Factored<T>> {
    let mut at = SMatrix::<T, N, N>::zeros();
    let mut fixes = [0; N];
    let mut w = 0;
    for i in 0..qp.k {
        at.set_column(w, &qp.c.row(i).transpose());
        w += 1;
    }
    for (i, b) in work.iter().enumerate() {
        let sign = match b {
            Bound::Free => continue,
            Bound::Lower => T::one(),
            Bound::Upper => -T::one(),
        };
        if w == N {
            return None;
        }
        at[(i, w)] = sign;
        fixes[w] = i;
        w += 1;
    }
    let qr = QR::new(at);
    let r = qr.r();
    let scale = at.amax().max(T::one());
    let tol = T::default_epsilon().sqrt() * scale;
    if (0..w).any(|j| r[(j, j)].abs() <= tol) {
        return None;
    }
    Some(Factored {
        q: qr.q(),
        r,
        w,
        fixes,
    })
}

/// The step `p` that minimises the programme over the working set's null space: `p = Z y`
/// with `y` the minimum-norm solution of `ZᵀHZ y = −Zᵀ∇`, `Z` the columns of `Q` past the
/// working set. `H` may be only semidefinite (a least-squares stage): the system is
/// consistent (the gradient of `½‖Au − b‖²` lies in the range of `AᵀA`), and the
/// minimum-norm solution leaves the directions the objective does not see alone.
fn step<T: RealField + Copy>(qp: &Qp<T>, f: &Factored<T>, grad: &Commands<T>) -> Commands<T> {
    let mut reduced = f.q.transpose() * qp.h * f.q;
    let mut rhs = -(f.q.transpose() * grad);
    for i in 0..f.w {
        for j in 0..N {
            reduced[(i, j)] = T::zero();
            reduced[(j, i)] = T::zero();
        }
        rhs[i] = T::zero();
    }
    if qp.definite {
        // the padded rows and columns get 1 on the diagonal (their right-hand side is 0)
        let mut padded = reduced;
        for i in 0..f.w {
            padded[(i, i)] = T::one();
        }
        if let Some(ch) = Cholesky::new(padded) {
            return f.q * ch.solve(&rhs);
        }
    }
    let eig = SymmetricEigen::new(reduced);
    let top = eig.eigenvalues.amax();
    let floor = T::from_subset(&1e3) * T::default_epsilon() * top;
    let mut y = Commands::<T>::zeros();
    for (i, l) in eig.eigenvalues.iter().enumerate() {
        if *l > floor {
            let v = eig.eigenvectors.column(i);
            y += v * (v.dot(&rhs) / *l);
        }
    }
    f.q * y
}

/// The working set's multipliers at the subproblem's optimum: `Aᵀλ = ∇`, from `R λ = Qᵀ∇`.
fn multipliers<T: RealField + Copy>(f: &Factored<T>, grad: &Commands<T>) -> Commands<T> {
    let qg = f.q.transpose() * grad;
    let mut lambda = Commands::<T>::zeros();
    for i in (0..f.w).rev() {
        let mut s = qg[i];
        for j in i + 1..f.w {
            s -= f.r[(i, j)] * lambda[j];
        }
        lambda[i] = s / f.r[(i, i)];
    }
    lambda
}

/// Solves the stage from `start`, which must be feasible (within the bounds, on `C u = d`).
pub(crate) fn solve<T: RealField + Copy>(
    qp: &Qp<T>,
    lo: &Commands<T>,
    hi: &Commands<T>,
    start: Commands<T>,
    cap: u32,
) -> Solved<T> {
    let scale = T::one() + lo.amax().max(hi.amax());
    let tol = T::from_subset(&1e3) * T::default_epsilon() * scale;
    let mut u = start;
    let mut work = initial_working_set(qp, lo, hi, &u, tol);
    let mut iterations = 0;
    while iterations < cap {
        iterations += 1;
        let Some(f) = factor(qp, &work) else {
            break;
        };
        let grad = qp.h * u + qp.g;
        let p = step(qp, &f, &grad);
        if p.amax() <= tol {
            let lambda = multipliers(&f, &grad);
            let mtol = T::from_subset(&1e3) * T::default_epsilon() * (T::one() + grad.amax());
            // the most negative multiplier of a bound an actuator can leave
            let release = (qp.k..f.w)
                .filter(|&c| hi[f.fixes[c]] - lo[f.fixes[c]] > tol && lambda[c] < -mtol)
                .min_by(|&a, &b| {
                    lambda[a]
                        .partial_cmp(&lambda[b])
                        .unwrap_or(core::cmp::Ordering::Equal)
                });
            match release {
                Some(c) => work[f.fixes[c]] = Bound::Free,
                None => {
                    return Solved {
                        u,
                        iterations,
                        stopped: false,
                    };
                }
            }
            continue;
        }
        let (alpha, block) = step_length(&work, lo, hi, &u, &p, tol);
        u += p * alpha;
        if let Some((i, b)) = block {
            u[i] = if b == Bound::Lower { lo[i] } else { hi[i] };
            work[i] = b;
        }
    }
    Solved {
        u,
        iterations,
        stopped: true,
    }
}

/// The longest step along `p` (at most 1) that keeps the free actuators within their bounds,
/// and the bound that stops it (components of `p` within `tol` of 0 block nothing).
fn step_length<T: RealField + Copy>(
    work: &[Bound; N],
    lo: &Commands<T>,
    hi: &Commands<T>,
    u: &Commands<T>,
    p: &Commands<T>,
    tol: T,
) -> (T, Option<(usize, Bound)>) {
    let mut alpha = T::one();
    let mut block = None;
    for i in 0..N {
        if work[i] != Bound::Free {
            continue;
        }
        // a component at rounding level moves nothing: it does not block
        let (room, bound) = if p[i] < -tol {
            ((lo[i] - u[i]) / p[i], Bound::Lower)
        } else if p[i] > tol {
            ((hi[i] - u[i]) / p[i], Bound::Upper)
        } else {
            continue;
        };
        let room = room.max(T::zero());
        if room < alpha {
            alpha = room;
            block = Some((i, bound));
        }
    }
    (alpha, block)
}

/// The first working set: the equality rows, then each actuator at a bound (a fixed one
/// first), as long as the normals stay linearly independent. All of them at once when they
/// are (the usual case: one factorisation), else one by one.
fn initial_working_set<T: RealField + Copy>(
    qp: &Qp<T>,
    lo: &Commands<T>,
    hi: &Commands<T>,
    u: &Commands<T>,
    tol: T,
) -> [Bound; N] {
    let at_bound = |i: usize| {
        if u[i] <= lo[i] + tol {
            Some(Bound::Lower)
        } else if u[i] >= hi[i] - tol {
            Some(Bound::Upper)
        } else {
            None
        }
    };
    let mut work = [Bound::Free; N];
    for (i, w) in work.iter_mut().enumerate() {
        *w = at_bound(i).unwrap_or(Bound::Free);
    }
    if factor(qp, &work).is_some() {
        return work;
    }
    let mut work = [Bound::Free; N];
    let order = (0..N)
        .filter(|&i| hi[i] - lo[i] <= tol)
        .chain((0..N).filter(|&i| hi[i] - lo[i] > tol));
    for i in order {
        let Some(b) = at_bound(i) else {
            continue;
        };
        work[i] = b;
        if factor(qp, &work).is_none() {
            work[i] = Bound::Free;
        }
    }
    work
}

/// A least-squares stage's matrices: `½‖Au − b‖²` is `½uᵀHu + gᵀu` (plus a constant) with
/// `H = AᵀA`, `g = −Aᵀb`.
pub(crate) fn least_squares<T: RealField + Copy>(
    a: &SMatrix<T, MAX_EQ, N>,
    b: &SVector<T, MAX_EQ>,
) -> (SMatrix<T, N, N>, Commands<T>) {
    (a.transpose() * a, -(a.transpose() * b))
}
