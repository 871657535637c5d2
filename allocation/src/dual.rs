//! Stage 2 of a square, well-separated geometry (the six-rotor hexarotor) in the force
//! (docs/maths.md, "Control allocation": stage 2 of a square geometry). With `B` invertible, every command that
//! keeps stage 1's torque `τ*` is `u = P τ* + S f` (`[P S] = B⁻¹`, split by the stages' rows),
//! so stage 2, `min ½‖B_f u − f_d‖²` over the box with `B_τ u = τ*`, is
//!
//! ```text
//! min ½‖x‖²  subject to  lo − c ≤ S x ≤ hi − c,   c = P τ* + S f_d,  x = f − f_d,
//! ```
//!
//! strictly convex in three unknowns. (Stage 1 of the same geometries has this form too, in the
//! torque against the facets of its reach: `zonotope.rs`.) It is solved by the dual active-set
//! method of Goldfarb
//! and Idnani (1983) with the identity as Hessian, from the unconstrained optimum `x = 0`:
//! each violated row is added, rows whose multipliers would turn negative dropped on the way,
//! and every working set holds at most three independent rows.

#![allow(clippy::needless_range_loop)]

use crate::qp::{MAX_EQ, ldl_solve, tolerance};
use nalgebra::RealField;

/// What the dual stage returns: `x` (the force's change from `f_d`) and the working-set
/// changes it spent, or that it stopped (the budget) or could not finish (rounding made the
/// rows look infeasible): the caller keeps its start then.
pub(crate) enum Dual<T> {
    Solved { x: [T; 3], changes: u32 },
    Stopped { changes: u32 },
    Failed { changes: u32 },
}

/// A constraint `n · x ≥ b`: row `k / 2` of `S` (lower bound, `k` even) or its negative (upper).
fn normal<T: RealField + Copy, const R: usize>(s: &[[T; 3]; R], k: usize) -> [T; 3] {
    let r = s[k / 2];
    if k.is_multiple_of(2) {
        r
    } else {
        [-r[0], -r[1], -r[2]]
    }
}

/// `a · b` in three dimensions.
pub(crate) fn dot3<T: RealField + Copy>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The rows: `S`'s (at most `R`), their squared norms, each constraint's `b` (`b[k / 2][k % 2]`),
/// and the working set (its rows and multipliers).
struct Rows<'a, T, const R: usize> {
    s: &'a [[T; 3]; R],
    norms: [T; R],
    b: [[T; 2]; R],
    m: usize,
    active: [usize; 3],
    lambda: [T; 3],
    na: usize,
    /// The working set as a mask over the constraints (`1 << k`).
    held: u64,
}

impl<T: RealField + Copy, const R: usize> Rows<'_, T, R> {
    /// Constraint `k`'s right-hand side.
    fn rhs(&self, k: usize) -> T {
        self.b[k / 2][k % 2]
    }

    /// The most violated constraint at `x` by more than `tol`, its violation measured in `x`'s
    /// units (`(b − n · x) / |n|`, compared squared). Each row's two constraints share `s_j · x`.
    fn most_violated(&self, x: &[T; 3], tol: T) -> Option<usize> {
        let mut best: Option<(usize, T)> = None;
        for j in 0..self.m {
            if self.norms[j] <= T::zero() {
                continue;
            }
            let v = dot3(&self.s[j], x);
            for (k, violation) in [(2 * j, self.b[j][0] - v), (2 * j + 1, self.b[j][1] + v)] {
                if violation <= tol || self.held & (1 << k) != 0 {
                    continue;
                }
                let measure = violation * violation / self.norms[j];
                if best.is_none_or(|(_, b)| measure > b) {
                    best = Some((k, measure));
                }
            }
        }
        best.map(|(k, _)| k)
    }

    /// `r = (NᵀN)⁻¹ Nᵀ n` over the working set's normals `N`, and `z = n − N r`.
    fn split(&self, n: &[T; 3]) -> ([T; MAX_EQ], [T; 3]) {
        let mut g = [[T::zero(); MAX_EQ]; MAX_EQ];
        let mut r = [T::zero(); MAX_EQ];
        let ns: [[T; 3]; 3] = core::array::from_fn(|a| {
            if a < self.na {
                normal(self.s, self.active[a])
            } else {
                [T::zero(); 3]
            }
        });
        for a in 0..self.na {
            for b in 0..=a {
                let v = dot3(&ns[a], &ns[b]);
                g[a][b] = v;
                g[b][a] = v;
            }
            r[a] = dot3(&ns[a], n);
        }
        ldl_solve(&mut g, self.na, &mut r);
        let mut z = *n;
        for a in 0..self.na {
            for i in 0..3 {
                z[i] -= r[a] * ns[a][i];
            }
        }
        (r, z)
    }

    /// The working set's row `a` leaves it.
    fn drop(&mut self, a: usize) {
        self.held &= !(1 << self.active[a]);
        for b in a..self.na - 1 {
            self.active[b] = self.active[b + 1];
            self.lambda[b] = self.lambda[b + 1];
        }
        self.na -= 1;
    }
}

/// Goldfarb–Idnani on `min ½‖x‖²`, `lo_j − c_j ≤ s_j · x ≤ hi_j − c_j` for the `m` rows `s_j`,
/// with at most `budget` working-set changes (docs/maths.md, "Control allocation").
// kept out of the allocator's common path (within reach it is not called)
#[inline(never)]
pub(crate) fn solve<T: RealField + Copy, const R: usize>(
    s: &[[T; 3]; R],
    c: &[T; R],
    lo: &[T],
    hi: &[T],
    m: usize,
    budget: u32,
) -> Dual<T> {
    // the working set's mask has a bit for each of the 2m constraints
    debug_assert!(m <= R && 2 * m <= 64);
    let tol = tolerance(lo, hi, m);
    let tau = T::from_subset(&1e3) * T::default_epsilon();
    // each row written once (no clearing first), those past `m` zero
    let mut w = Rows {
        s,
        norms: core::array::from_fn(|j| if j < m { dot3(&s[j], &s[j]) } else { T::zero() }),
        b: core::array::from_fn(|j| {
            if j < m {
                [lo[j] - c[j], c[j] - hi[j]]
            } else {
                [T::zero(); 2]
            }
        }),
        m,
        active: [0; 3],
        lambda: [T::zero(); 3],
        na: 0,
        held: 0,
    };
    let mut x = [T::zero(); 3];
    let mut changes = 0u32;
    while let Some(p) = w.most_violated(&x, tol) {
        let np = normal(s, p);
        let mut lp = T::zero();
        loop {
            if changes == budget {
                return Dual::Stopped { changes };
            }
            // a planted slow path (scripts/cortex-m.sh's self-test): one more factorisation
            // per change must break the worst-case limits
            #[cfg(feature = "planted-slow-path")]
            core::hint::black_box(w.split(core::hint::black_box(&np)));
            let (r, z) = w.split(&np);
            let zz = dot3(&z, &z);
            // the full step, when n_p has a part off the working set's span
            let full = (zz > tau * w.norms[p / 2]).then(|| (w.rhs(p) - dot3(&np, &x)) / zz);
            // the partial step: the first multiplier to reach zero
            let mut partial: Option<(usize, T)> = None;
            for a in 0..w.na {
                if r[a] > T::zero() {
                    let t = w.lambda[a] / r[a];
                    if partial.is_none_or(|(_, b)| t < b) {
                        partial = Some((a, t));
                    }
                }
            }
            let (t, leaves) = match (full, partial) {
                (Some(t1), Some((a, t2))) if t2 < t1 => (t2, Some(a)),
                (Some(t1), _) => (t1, None),
                (None, Some((a, t2))) => (t2, Some(a)),
                (None, None) => return Dual::Failed { changes },
            };
            if full.is_some() {
                for i in 0..3 {
                    x[i] += t * z[i];
                }
            }
            for a in 0..w.na {
                w.lambda[a] -= t * r[a];
            }
            lp += t;
            changes += 1;
            match leaves {
                Some(a) => w.drop(a),
                None if w.na == 3 => return Dual::Failed { changes },
                None => {
                    w.active[w.na] = p;
                    w.held |= 1 << p;
                    w.lambda[w.na] = lp;
                    w.na += 1;
                    break;
                }
            }
        }
    }
    Dual::Solved { x, changes }
}
