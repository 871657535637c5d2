//! The allocation of a geometry whose actuators fall into blocks
//! (docs/maths.md, "Control allocation": geometries in blocks). A block is a set of wrench rows and the actuators
//! whose columns have their entries that are not exactly zero in those rows only: the
//! BlueROV2 Heavy layout's horizontal thrusters move `τz, fx, fy` and its vertical ones
//! `τx, τy, fz`; the twelve-thruster spacecraft's couples on SO(3) move one body axis each.
//! Every stage's objective and equalities are sums over rows, so each block is an allocation
//! of its own, with its rows in the stages' order:
//!
//! * a block of one row in closed form: the row's reach is the interval
//!   `[Σ min(b_j lo_j, b_j hi_j), Σ max(b_j lo_j, b_j hi_j)]`, so stages 1 and 2 clamp the
//!   demand into it; stage 3, `min Σ w_j (u_j − up_j)²` with `Σ b_j u_j = t` and the box, has
//!   `u_j(λ) = clamp(up_j + λ b_j / w_j, lo_j, hi_j)` for one multiplier `λ`, and
//!   `g(λ) = Σ b_j u_j(λ)` is continuous, nondecreasing and piecewise linear: `λ` is found on
//!   the segment of the sorted breakpoints where `g` crosses `t`;
//! * a larger block by the primal active set over its own actuators and rows only, but for
//!   two closed forms: a stage 1 of one row (the command nearest the start with that row's
//!   value clamped into its reach, by the same search with unit weights), and a stage 3 whose
//!   feasible commands lie on a line (the block's rows of rank one less than its actuators:
//!   one coordinate along the null space, clamped where the box holds) or at one point (rank
//!   equal to its actuators).
//!
//! An actuator in no row (a zero column) is at `up_j` within its bounds.

use crate::qp::{Factored, MAX_EQ, Objective, Rows, Stage, clamp, solve, tolerance};
use crate::{Commands, MAX_ACTUATORS};
use nalgebra::{RealField, SMatrix};

const N: usize = MAX_ACTUATORS;

/// An actuator in no block (its column is zero).
const NONE: u8 = u8::MAX;

/// A prioritised problem in compact coordinates: `rows` rows in the stages' order (the first
/// `first` are stage 1's, the rest stage 2's), over `m` actuators with their bounds.
pub(crate) struct Compact<T> {
    pub(crate) all: Rows<T>,
    pub(crate) wanted: [T; MAX_EQ],
    pub(crate) rows: usize,
    pub(crate) first: usize,
    pub(crate) m: usize,
    pub(crate) lo: Commands<T>,
    pub(crate) hi: Commands<T>,
}

/// Stage 2 solved another way (the dual method of a square geometry): given stage 1's answer
/// and the budget left, the command (`None`: not solved), the changes spent and whether the
/// budget ran out; `None` when there is no other way.
pub(crate) type Stage2<T> = Option<(Option<Commands<T>>, u32, bool)>;

/// The primal active-set stages of `p` from `start` (docs/maths.md, "Control allocation"),
/// from stage `from` through stage `through`, within `budget` of which `spent` is spent:
/// stage 1 on the first `first` rows, stage 2 on the rest keeping them (by `force` when it
/// answers), stage 3 nearest `up` in the `w`-norm keeping them all (unless `last` is false:
/// the wrench fixes the command). Returns the command, the iterations spent in all and
/// whether the budget ran out.
#[allow(clippy::too_many_arguments)]
pub(crate) fn primal<T: RealField + Copy>(
    p: &Compact<T>,
    w: &Commands<T>,
    up: &Commands<T>,
    start: Commands<T>,
    budget: u32,
    mut spent: u32,
    (from, through): (usize, usize),
    last: bool,
    mut force: impl FnMut(&Commands<T>, u32) -> Stage2<T>,
) -> (Commands<T>, u32, bool) {
    let mut stopped = false;
    let mut workspace = Factored::new();
    let mut run = |objective: Objective<'_, T>,
                   k: usize,
                   from: Commands<T>,
                   spent: &mut u32,
                   stopped: &mut bool| {
        if *stopped {
            return from;
        }
        let stage = Stage {
            objective,
            c: &p.all,
            k,
            m: p.m,
            lo: &p.lo,
            hi: &p.hi,
        };
        let s = solve(&stage, from, budget - *spent, &mut workspace);
        *spent += s.iterations;
        *stopped |= s.stopped;
        s.u
    };
    // stage 1: the torque (or the whole wrench)
    let mut u = start;
    if p.first > 0 && from <= 1 {
        let objective = Objective::LeastSquares {
            a: &p.all,
            b: &p.wanted,
            q: p.first,
        };
        u = run(objective, 0, u, &mut spent, &mut stopped);
    }
    // stage 2: the force, keeping the torque
    if p.rows > p.first && from <= 2 && through >= 2 {
        let mut done = false;
        if !stopped && let Some((answer, changes, spent_all)) = force(&u, budget - spent) {
            spent += changes;
            stopped = spent_all;
            if let Some(answer) = answer {
                u = answer;
            }
            done = answer.is_some() || spent_all;
        }
        if !done {
            let mut rows: Rows<T> = [[T::zero(); N]; MAX_EQ];
            let mut b = [T::zero(); MAX_EQ];
            let q = p.rows - p.first;
            rows[..q].copy_from_slice(&p.all[p.first..p.rows]);
            b[..q].copy_from_slice(&p.wanted[p.first..p.rows]);
            let objective = Objective::LeastSquares { a: &rows, b: &b, q };
            u = run(objective, p.first, u, &mut spent, &mut stopped);
        }
    }
    // stage 3: nearest u_pref, keeping the wrench achieved
    if through >= 3 && last {
        let objective = Objective::Nearest { w, up };
        u = run(objective, p.rows, u, &mut spent, &mut stopped);
    }
    (u, spent, stopped)
}

/// The blocks of a geometry: each row's block and each actuator's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Blocks {
    row: [u8; MAX_EQ],
    actuator: [u8; N],
    count: u8,
}

impl Blocks {
    /// The blocks of the first `m` columns of `b`, or `None` when there is one block (then
    /// nothing falls apart).
    pub(crate) fn of<T: RealField + Copy, const K: usize>(
        b: &SMatrix<T, K, N>,
        m: usize,
    ) -> Option<Blocks> {
        // union of each column's rows: `parent` is a row's smallest row in its block so far
        let mut parent: [usize; MAX_EQ] = core::array::from_fn(|r| r);
        let root = |parent: &[usize; MAX_EQ], mut r: usize| {
            while parent[r] != r {
                r = parent[r];
            }
            r
        };
        for j in 0..m {
            let mut first: Option<usize> = None;
            for r in 0..K {
                if b[(r, j)] == T::zero() {
                    continue;
                }
                match first {
                    None => first = Some(r),
                    Some(f) => {
                        let (x, y) = (root(&parent, f), root(&parent, r));
                        parent[x.max(y)] = x.min(y);
                    }
                }
            }
        }
        let mut blocks = Blocks {
            row: [NONE; MAX_EQ],
            actuator: [NONE; N],
            count: 0,
        };
        for r in 0..K {
            let top = root(&parent, r);
            blocks.row[r] = if top == r {
                blocks.count += 1;
                blocks.count - 1
            } else {
                blocks.row[top]
            };
        }
        for j in 0..m {
            if let Some(r) = (0..K).find(|&r| b[(r, j)] != T::zero()) {
                blocks.actuator[j] = blocks.row[r];
            }
        }
        (blocks.count > 1).then_some(blocks)
    }

    /// How many blocks.
    pub(crate) fn count(&self) -> usize {
        usize::from(self.count)
    }

    /// Whether row `r` is in block `c`.
    pub(crate) fn has_row(&self, c: usize, r: usize) -> bool {
        usize::from(self.row[r]) == c
    }

    /// Whether actuator `j` is in block `c`.
    pub(crate) fn has_actuator(&self, c: usize, j: usize) -> bool {
        usize::from(self.actuator[j]) == c
    }
}

/// The interval a row with entries `b(j)` produces over the box of the first `n` actuators,
/// `[Σ min(b_j lo_j, b_j hi_j), Σ max(b_j lo_j, b_j hi_j)]`
/// (docs/maths.md, "Control allocation": geometries in blocks).
pub(crate) fn row_reach<T: RealField + Copy>(
    b: impl Fn(usize) -> T,
    lo: &[T],
    hi: &[T],
    n: usize,
) -> (T, T) {
    let (mut floor, mut ceiling) = (T::zero(), T::zero());
    for j in 0..n {
        let (x, y) = (b(j) * lo[j], b(j) * hi[j]);
        let (low, high) = if x <= y { (x, y) } else { (y, x) };
        floor += low;
        ceiling += high;
    }
    (floor, ceiling)
}

/// A block of one row (row 0 of `p`) in closed form: the demand clamped into the row's reach,
/// then the command nearest `up` in the `w`-norm producing it, `u_j = clamp(up_j + λ s_j,
/// lo_j, hi_j)` with `s_j = b_j / w_j` (docs/maths.md, "Control allocation": geometries in
/// blocks). `up` lies within the bounds and `w` is positive.
pub(crate) fn one_row<T: RealField + Copy>(
    p: &Compact<T>,
    w: &Commands<T>,
    up: &Commands<T>,
) -> Commands<T> {
    let (m, b, lo, hi) = (p.m, &p.all[0], &p.lo, &p.hi);
    let (floor, ceiling) = row_reach(|j| b[j], lo.as_slice(), hi.as_slice(), m);
    let target = clamp(p.wanted[0], floor, ceiling);
    let slope = |j: usize| b[j] / w[j];
    let at = |j: usize, lambda: T| clamp(up[j] + lambda * slope(j), lo[j], hi[j]);
    // the breakpoints: where each actuator that moves the row meets its bounds (an actuator of
    // a larger block may have a zero in this row: it stays at `up`, and has none)
    let mut points = [T::zero(); 2 * N];
    let mut np = 0;
    for j in 0..m {
        if hi[j] > lo[j] && b[j] != T::zero() {
            let s = slope(j);
            points[np] = (lo[j] - up[j]) / s;
            points[np + 1] = (hi[j] - up[j]) / s;
            np += 2;
        }
    }
    let mut u = *up;
    if np == 0 {
        // every actuator that moves the row is held (at `up`, within its bounds): the row's
        // value is fixed
        return u;
    }
    // insertion sort (at most 2 · 12 numbers)
    for i in 1..np {
        let x = points[i];
        let mut k = i;
        while k > 0 && points[k - 1] > x {
            points[k] = points[k - 1];
            k -= 1;
        }
        points[k] = x;
    }
    let g = |lambda: T| (0..m).fold(T::zero(), |s, j| s + b[j] * at(j, lambda));
    // below the first breakpoint g is the reach's low end, past the last its high end; the
    // first breakpoint where g exceeds the target closes the segment where g crosses it
    let lambda = match (1..np).find(|&k| g(points[k]) > target) {
        None => points[np - 1],
        Some(k) => {
            let (left, right) = (points[k - 1], points[k]);
            let below = g(left);
            if below >= target {
                left
            } else {
                // on (left, right) the free actuators are those strictly inside their bounds
                // at the segment's middle, and g rises with slope Σ_free b_j s_j
                let middle = (left + right) / T::from_subset(&2.0);
                let rise = (0..m)
                    .filter(|&j| {
                        let v = up[j] + middle * slope(j);
                        hi[j] > lo[j] && v > lo[j] && v < hi[j]
                    })
                    .fold(T::zero(), |s, j| s + b[j] * slope(j));
                if rise > T::zero() {
                    clamp(left + (target - below) / rise, left, right)
                } else {
                    left
                }
            }
        }
    };
    for j in 0..m {
        if b[j] != T::zero() {
            u[j] = at(j, lambda);
        }
    }
    u
}

/// Stage 3 of a block whose rows leave a line (docs/maths.md, "Control allocation": geometries
/// in blocks): when the block's rows have rank one less than its actuators, the commands that
/// keep the wrench `u` produces are `u + α n` (`n` spanning the rows' null space), so stage 3 is
/// `α = clamp(−Σ w_j n_j (u_j − up_j) / Σ w_j n_j², α_lo, α_hi)`, `[α_lo, α_hi]` where the box
/// holds. With as many independent rows as actuators, `u` itself (the one feasible command).
/// `None` when the null space is neither a line nor a point (the primal stage then answers).
pub(crate) fn on_a_line<T: RealField + Copy>(
    p: &Compact<T>,
    w: &Commands<T>,
    up: &Commands<T>,
    u: &Commands<T>,
) -> Option<Commands<T>> {
    let m = p.m;
    let tau = T::from_subset(&1e3) * T::default_epsilon();
    // the rows made orthogonal (Gram–Schmidt, as the factorisation does)
    let mut q: Rows<T> = [[T::zero(); N]; MAX_EQ];
    let mut d = [T::zero(); MAX_EQ];
    let mut rank = 0;
    for r in 0..p.rows {
        let mut v = p.all[r];
        let size = (0..m).fold(T::zero(), |s, j| s + v[j] * v[j]);
        for i in 0..rank {
            let c = (0..m).fold(T::zero(), |s, j| s + v[j] * q[i][j]) / d[i];
            for j in 0..m {
                v[j] -= c * q[i][j];
            }
        }
        let vv = (0..m).fold(T::zero(), |s, j| s + v[j] * v[j]);
        if vv > tau * size && vv > T::zero() {
            q[rank] = v;
            d[rank] = vv;
            rank += 1;
        }
    }
    if rank == m {
        // as many independent rows as actuators: `u` is the only command that keeps them
        return Some(*u);
    }
    if rank + 1 != m {
        return None;
    }
    // n = e_k less its part in the rows' span, for the k that keeps the most of it
    let keep = |k: usize| T::one() - (0..rank).fold(T::zero(), |s, i| s + q[i][k] * q[i][k] / d[i]);
    let k = (1..m).fold(0, |best, k| if keep(k) > keep(best) { k } else { best });
    let mut n = [T::zero(); N];
    for j in 0..m {
        let along = (0..rank).fold(T::zero(), |s, i| s + q[i][k] * q[i][j] / d[i]);
        n[j] = if j == k { T::one() } else { T::zero() } - along;
    }
    along(p, w, up, u, &n)
}

/// Stage 3 on the line `u + α n` (docs/maths.md, "Control allocation": geometries in blocks):
/// `α = clamp(−Σ w_j n_j (u_j − up_j) / Σ w_j n_j², α_lo, α_hi)`, `[α_lo, α_hi]` where the box
/// holds; `None` when the box misses the line.
pub(crate) fn along<T: RealField + Copy>(
    p: &Compact<T>,
    w: &Commands<T>,
    up: &Commands<T>,
    u: &Commands<T>,
    n: &[T; N],
) -> Option<Commands<T>> {
    let m = p.m;
    let tau = T::from_subset(&1e3) * T::default_epsilon();
    let top = n
        .iter()
        .take(m)
        .fold(T::zero(), |a, x| if x.abs() > a { x.abs() } else { a });
    // the box along the line, and the slack of each end: the tolerance over the `|n_j|` of
    // the actuator that sets it
    let (mut low, mut high) = (-T::max_value()?, T::max_value()?);
    let (mut low_slack, mut high_slack) = (T::zero(), T::zero());
    let (mut num, mut den) = (T::zero(), T::zero());
    let tol = tolerance(p.lo.as_slice(), p.hi.as_slice(), m);
    for j in 0..m {
        if n[j].abs() <= tau * top {
            // an actuator the line does not move: where it is, within its bounds
            if u[j] < p.lo[j] - tol || u[j] > p.hi[j] + tol {
                return None;
            }
            continue;
        }
        let (a, b) = ((p.lo[j] - u[j]) / n[j], (p.hi[j] - u[j]) / n[j]);
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        if a > low {
            (low, low_slack) = (a, tol / n[j].abs());
        }
        if b < high {
            (high, high_slack) = (b, tol / n[j].abs());
        }
        num -= w[j] * n[j] * (u[j] - up[j]);
        den += w[j] * n[j] * n[j];
    }
    if !den.is_finite() || den <= T::zero() || low > high + low_slack + high_slack {
        return None;
    }
    // the box holds one point of the line when rounding has crossed its ends: their middle
    let alpha = if low <= high {
        clamp(num / den, low, high)
    } else {
        (low + high) / T::from_subset(&2.0)
    };
    let mut v = *u;
    for j in 0..m {
        v[j] = clamp(u[j] + alpha * n[j], p.lo[j], p.hi[j]);
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::{Compact, one_row};
    use crate::Commands;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// One row in closed form (a block's stage 1 of one row, or a block of one row), where
        /// some actuators have a zero in the row (they belong to a larger block by another
        /// row) and start on a bound: they stay where they are, and the others give the row
        /// the demand clamped into its reach, finite and within their bounds.
        #[test]
        fn one_row_meets_its_reach_and_leaves_the_zero_entries(
            entries in proptest::collection::vec(prop_oneof![Just(0.0f64), -2.0f64..2.0], 2..9),
            starts in proptest::collection::vec(prop_oneof![Just(-1.0f64), Just(1.0), -1.0f64..1.0], 9),
            weights in proptest::collection::vec(0.3f64..3.0, 9),
            wanted in -12.0f64..12.0,
        ) {
            let m = entries.len();
            let mut p = Compact {
                all: [[0.0f64; crate::MAX_ACTUATORS]; crate::qp::MAX_EQ],
                wanted: [0.0; crate::qp::MAX_EQ],
                rows: 1,
                first: 1,
                m,
                lo: Commands::zeros(),
                hi: Commands::zeros(),
            };
            let (mut up, mut w) = (Commands::zeros(), Commands::from_element(1.0));
            let (mut floor, mut ceiling) = (0.0, 0.0);
            for j in 0..m {
                p.all[0][j] = entries[j];
                (p.lo[j], p.hi[j], up[j], w[j]) = (-1.0, 1.0, starts[j], weights[j]);
                floor -= entries[j].abs();
                ceiling += entries[j].abs();
            }
            p.wanted[0] = wanted;
            let u = one_row(&p, &w, &up);
            let row: f64 = (0..m).map(|j| entries[j] * u[j]).sum();
            prop_assert!((row - wanted.clamp(floor, ceiling)).abs() < 1e-9, "row {row}, wanted {wanted}: {u}");
            for j in 0..m {
                prop_assert!(u[j].is_finite() && (-1.0..=1.0).contains(&u[j]), "{u}");
                if entries[j] == 0.0 {
                    prop_assert_eq!(u[j], starts[j]);
                }
            }
        }
    }
}
