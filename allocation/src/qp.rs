//! One stage of the allocation: a convex quadratic programme over the `m` real actuators,
//!
//! ```text
//! min ½‖A u − b‖²  (a least-squares stage)   or   min ½ (u − u_pref)ᵀ W (u − u_pref)  (the last)
//! subject to  C u = d  (the earlier stages' rows, met by the start),  lo ≤ u ≤ hi,
//! ```
//!
//! by a primal active-set method with the bounds kept as a free/fixed mask (docs/maths.md,
//! "Control allocation": the active-set method). Each working set is factored by modified
//! Gram–Schmidt without normalisation: no square root, no matrix larger than the free
//! actuators by the stage's rows (at most 6).

// The factorisation's loops index several short arrays at once (rows, coefficients, the free
// actuators' map); written as index loops they read as the formulas of docs/maths.md.
#![allow(clippy::needless_range_loop)]

use crate::{Commands, MAX_ACTUATORS};
use nalgebra::RealField;

const N: usize = MAX_ACTUATORS;

/// The most rows a stage has (the whole wrench on SE(3)), for its objective or its equalities.
pub(crate) const MAX_EQ: usize = 6;

/// Rows over the actuators (row `r`, actuator `j`).
pub(crate) type Rows<T> = [[T; N]; MAX_EQ];

/// A stage's objective.
pub(crate) enum Objective<'a, T> {
    /// `½‖A u − b‖²` over the first `q` rows of `a` and `b`.
    LeastSquares {
        a: &'a Rows<T>,
        b: &'a [T; MAX_EQ],
        q: usize,
    },
    /// `½ (u − u_pref)ᵀ W (u − u_pref)`, `W = diag(w)`, `w > 0`.
    Nearest {
        w: &'a Commands<T>,
        up: &'a Commands<T>,
    },
}

/// A stage's programme: the objective, the first `k` rows of `c` as equalities (the start
/// meets them), the actuator count `m`, the bounds.
pub(crate) struct Stage<'a, T> {
    pub(crate) objective: Objective<'a, T>,
    pub(crate) c: &'a Rows<T>,
    pub(crate) k: usize,
    pub(crate) m: usize,
    pub(crate) lo: &'a Commands<T>,
    pub(crate) hi: &'a Commands<T>,
}

/// A stage's answer.
pub(crate) struct Solved<T> {
    pub(crate) u: Commands<T>,
    /// Factorisations of a working set (each change of the working set costs one).
    pub(crate) iterations: u32,
    /// The budget ran out before the optimum: `u` is the last iterate, within the bounds,
    /// and the objective no higher than at the start.
    pub(crate) stopped: bool,
}

/// Whether an actuator is held at a bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bound {
    Free,
    Lower,
    Upper,
}

/// The free actuators, in order.
struct Free {
    idx: [usize; N],
    n: usize,
}

impl Free {
    fn of(mask: &[Bound; N], m: usize) -> Self {
        let mut f = Free { idx: [0; N], n: 0 };
        for (j, b) in mask.iter().enumerate().take(m) {
            if *b == Bound::Free {
                f.idx[f.n] = j;
                f.n += 1;
            }
        }
        f
    }

    fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.idx[..self.n].iter().copied()
    }
}

/// Rows made orthogonal by modified Gram–Schmidt without normalisation, in the free
/// actuators' compact coordinates (entry `i` is free actuator `free.idx[i]`): input row `j` is
/// `Σ_i l[j][i] q_i`. A row that adds no direction has `pivot[j] = false`.
struct Ortho<T> {
    q: Rows<T>,
    /// `⟨q_i, q_i⟩` in the stage's inner product.
    d: [T; MAX_EQ],
    rank: usize,
    l: [[T; MAX_EQ]; MAX_EQ],
    pivot: [bool; MAX_EQ],
}

impl<T: RealField + Copy> Ortho<T> {
    fn new() -> Self {
        Ortho {
            q: [[T::zero(); N]; MAX_EQ],
            d: [T::zero(); MAX_EQ],
            rank: 0,
            l: [[T::zero(); MAX_EQ]; MAX_EQ],
            pivot: [false; MAX_EQ],
        }
    }

    /// Orthogonalises the first `count` rows of `rows` over their first `n` entries, in
    /// order, in the inner product weighted by `metric` when given
    /// (docs/maths.md, "Control allocation"). A row whose remainder has
    /// `⟨v, v⟩ ≤ tau · scale` adds nothing.
    fn of(
        &mut self,
        rows: &Rows<T>,
        count: usize,
        n: usize,
        metric: Option<&[T; N]>,
        tau: T,
        scale: T,
    ) {
        self.rank = 0;
        for j in 0..count {
            let mut v = rows[j];
            for i in 0..self.rank {
                let c = dot(&v, &self.q[i], n, metric) / self.d[i];
                for (x, y) in v.iter_mut().zip(self.q[i].iter()).take(n) {
                    *x -= c * *y;
                }
                self.l[j][i] = c;
            }
            for x in self.l[j].iter_mut().skip(self.rank) {
                *x = T::zero();
            }
            let vv = dot(&v, &v, n, metric);
            self.pivot[j] = vv > tau * scale && vv > T::zero();
            if self.pivot[j] {
                self.q[self.rank] = v;
                self.d[self.rank] = vv;
                self.l[j][self.rank] = T::one();
                self.rank += 1;
            }
        }
    }
}

/// `x` clamped into `[l, h]` (`l ≤ h`) by comparisons: `x.max(l).min(h)` for every `x`, a NaN
/// giving `l` as `max` does, but without `max`/`min`, whose NaN handling costs a
/// comparison sequence each on the Cortex-M4F (BENCHMARKS section 24). A tie returns `x`.
#[inline]
pub(crate) fn clamp<T: RealField + Copy>(x: T, l: T, h: T) -> T {
    let y = if x >= l { x } else { l };
    if y <= h { y } else { h }
}

/// The larger of `a` (not a NaN) and `b` by one comparison: `a.max(b)`, a NaN `b` leaving
/// `a` as `max` does.
#[inline]
fn larger<T: RealField + Copy>(a: T, b: T) -> T {
    if b > a { b } else { a }
}

/// The tolerance of a bound or a step, `10³ ε (1 + the largest |bound|)` over the first `m`
/// actuators: the primal and the dual stages share it.
pub(crate) fn tolerance<T: RealField + Copy>(lo: &[T], hi: &[T], m: usize) -> T {
    let bound = (0..m).fold(T::zero(), |a, j| {
        larger(larger(a, lo[j].abs()), hi[j].abs())
    });
    T::from_subset(&1e3) * T::default_epsilon() * (T::one() + bound)
}

/// The inner product of the first `n` entries, weighted by `metric` when given.
fn dot<T: RealField + Copy>(a: &[T; N], b: &[T; N], n: usize, metric: Option<&[T; N]>) -> T {
    let mut s = T::zero();
    match metric {
        Some(w) => {
            for i in 0..n {
                s += a[i] * b[i] * w[i];
            }
        }
        None => {
            for i in 0..n {
                s += a[i] * b[i];
            }
        }
    }
    s
}

/// A working set, factored in the free actuators' compact coordinates: the equalities' rows
/// orthogonalised (in the metric `W⁻¹` on the last stage), and on a least-squares stage the
/// objective's rows projected off them and orthogonalised in turn. Filled in place, once per
/// working set.
pub(crate) struct Factored<T> {
    free: Free,
    /// The inverse weights of the free actuators (the last stage's metric).
    metric: [T; N],
    /// Whether the metric is not the identity: with every weight 1 (the default) the inner
    /// products skip it, which changes no bit (`x · 1 = x`).
    weighted: bool,
    /// The rows, compact: the equalities' `C_F`, then (least squares) the objective's `A_F`.
    c: Rows<T>,
    a: Rows<T>,
    eq: Ortho<T>,
    ls: Ortho<T>,
}

impl<T: RealField + Copy> Factored<T> {
    /// A workspace for a working set's factorisation (each factorisation writes what it
    /// reads).
    pub(crate) fn new() -> Self {
        Factored {
            free: Free { idx: [0; N], n: 0 },
            metric: [T::one(); N],
            weighted: false,
            c: [[T::zero(); N]; MAX_EQ],
            a: [[T::zero(); N]; MAX_EQ],
            eq: Ortho::new(),
            ls: Ortho::new(),
        }
    }
}

/// The largest `⟨r, r⟩` among the first `count` rows over their first `n` entries.
fn scale<T: RealField + Copy>(
    rows: &Rows<T>,
    count: usize,
    n: usize,
    metric: Option<&[T; N]>,
) -> T {
    rows.iter()
        .take(count)
        .map(|r| dot(r, r, n, metric))
        .fold(T::zero(), larger)
}

impl<'a, T: RealField + Copy> Stage<'a, T> {
    /// Factors the working set of `mask` into `f` (docs/maths.md, "Control allocation").
    fn factor(&self, mask: &[Bound; N], inv_w: &[T; N], tau: T, f: &mut Factored<T>) {
        f.free = Free::of(mask, self.m);
        let n = f.free.n;
        let nearest = matches!(self.objective, Objective::Nearest { .. });
        for (i, j) in f.free.iter().enumerate() {
            f.metric[i] = inv_w[j];
            for r in 0..self.k {
                f.c[r][i] = self.c[r][j];
            }
        }
        f.weighted = nearest && f.metric[..n].iter().any(|w| *w != T::one());
        let metric = f.weighted.then_some(&f.metric);
        let s = scale(&f.c, self.k, n, metric);
        f.eq.of(&f.c, self.k, n, metric, tau, s);
        if let Objective::LeastSquares { a, q, .. } = self.objective {
            // the objective's rows with the equalities' directions taken out: their span is
            // where a step may go
            for (r, row) in a.iter().enumerate().take(q) {
                for (i, j) in f.free.iter().enumerate() {
                    f.a[r][i] = row[j];
                }
            }
            let s = scale(&f.a, q, n, None);
            for r in 0..q {
                for i in 0..f.eq.rank {
                    let c = dot(&f.a[r], &f.eq.q[i], n, None) / f.eq.d[i];
                    for x in 0..n {
                        f.a[r][x] -= c * f.eq.q[i][x];
                    }
                }
            }
            f.ls.of(&f.a, q, n, None, tau, s);
        }
    }

    /// The objective's residual `r = Au − b` at `u` (least squares; 0 on the last stage).
    fn residuals(&self, u: &Commands<T>) -> [T; MAX_EQ] {
        let mut r = [T::zero(); MAX_EQ];
        if let Objective::LeastSquares { a, b, q } = self.objective {
            for (i, x) in r.iter_mut().enumerate().take(q) {
                *x = residual(&a[i], b[i], u, self.m);
            }
        }
        r
    }

    /// The objective's gradient at `u`, its residual `r` given (`Aᵀr`, or `W(u − u_pref)`).
    fn gradient(&self, u: &Commands<T>, r: &[T; MAX_EQ]) -> [T; N] {
        let mut g = [T::zero(); N];
        match self.objective {
            Objective::LeastSquares { a, q, .. } => {
                for i in 0..q {
                    let res = r[i];
                    for j in 0..self.m {
                        g[j] += a[i][j] * res;
                    }
                }
            }
            Objective::Nearest { w, up } => {
                for j in 0..self.m {
                    g[j] = w[j] * (u[j] - up[j]);
                }
            }
        }
        g
    }

    /// The step `p` that minimises the objective from `u` over the working set's null space
    /// (docs/maths.md, "Control allocation": the step). A least-squares stage takes the
    /// minimum-norm one: `p = Mᵀ(MMᵀ)⁺(−r)` with `M` the objective's rows projected off the
    /// equalities, `r = Au − b`; through `M = L S` (`S` orthogonal rows), `p = Sᵀ D⁻¹ t` with
    /// `t` the least-squares solution of `L t = −r`. The last stage projects in the metric `W⁻¹`:
    /// `p = −v + W⁻¹ Σ_i (q_i·v / ⟨q_i, q_i⟩) q_i` with `v = u − u_pref`.
    fn step(&self, f: &Factored<T>, u: &Commands<T>, r: &[T; MAX_EQ]) -> [T; N] {
        let n = f.free.n;
        let mut compact = [T::zero(); N];
        match self.objective {
            Objective::LeastSquares { q, .. } => {
                let s = &f.ls;
                let t = least_squares(&s.l, q, s.rank, r);
                for i in 0..s.rank {
                    let c = t[i] / s.d[i];
                    for x in 0..n {
                        compact[x] += c * s.q[i][x];
                    }
                }
            }
            Objective::Nearest { up, .. } => {
                let mut v = [T::zero(); N];
                for (i, j) in f.free.iter().enumerate() {
                    v[i] = u[j] - up[j];
                    compact[i] = -v[i];
                }
                for i in 0..f.eq.rank {
                    let beta = dot(&f.eq.q[i], &v, n, None) / f.eq.d[i];
                    for x in 0..n {
                        compact[x] += beta * f.eq.q[i][x] * f.metric[x];
                    }
                }
            }
        }
        let mut p = [T::zero(); N];
        for (i, j) in f.free.iter().enumerate() {
            p[j] = compact[i];
        }
        p
    }

    /// At the working set's optimum, the fixed (and not locked) bound with the most negative
    /// multiplier, if any: `∇ = Cᵀμ + Σ λ_j (±e_j)`. On the free actuators `C_Fᵀμ = Σ_i β_i q_i`
    /// with `β_i` the free part of `∇` projected on `q_i` (in the stage's metric); with
    /// `C_F = L Q`, `μ` solves `Lᵀμ = β` (0 for a row that added no direction), and then
    /// `λ_j = ∇_j − (Cᵀμ)_j` on each held actuator.
    fn release(
        &self,
        f: &Factored<T>,
        mask: &[Bound; N],
        u: &Commands<T>,
        r: &[T; MAX_EQ],
        tol: T,
    ) -> Option<usize> {
        let g = self.gradient(u, r);
        let n = f.free.n;
        let metric = f.weighted.then_some(&f.metric);
        let mut gf = [T::zero(); N];
        for (i, j) in f.free.iter().enumerate() {
            gf[i] = g[j];
        }
        let mut beta = [T::zero(); MAX_EQ];
        for (i, b) in beta.iter_mut().enumerate().take(f.eq.rank) {
            *b = dot(&f.eq.q[i], &gf, n, metric) / f.eq.d[i];
        }
        // Lᵀμ = β, back substitution over the rows that added a direction
        let mut mu = [T::zero(); MAX_EQ];
        let mut col = f.eq.rank;
        for j in (0..self.k).rev() {
            if !f.eq.pivot[j] {
                continue;
            }
            col -= 1;
            let mut s = beta[col];
            for (r, m) in mu.iter().enumerate().take(self.k).skip(j + 1) {
                s -= f.eq.l[r][col] * *m;
            }
            mu[j] = s;
        }
        let top = g
            .iter()
            .take(self.m)
            .fold(T::zero(), |a, x| larger(a, x.abs()));
        let mtol = T::from_subset(&1e3) * T::default_epsilon() * (T::one() + top);
        let mut best: Option<(usize, T)> = None;
        for j in 0..self.m {
            let sign = match mask[j] {
                Bound::Free => continue,
                Bound::Lower => T::one(),
                Bound::Upper => -T::one(),
            };
            if self.hi[j] - self.lo[j] <= tol {
                continue;
            }
            let mut lambda = g[j];
            for (r, m) in mu.iter().enumerate().take(self.k) {
                lambda -= *m * self.c[r][j];
            }
            let signed = sign * lambda;
            if signed < -mtol && best.is_none_or(|(_, b)| signed < b) {
                best = Some((j, signed));
            }
        }
        best.map(|(j, _)| j)
    }

    /// The first working set at `u`: every actuator at a bound held there, then (on a stage
    /// with equalities) as few of them freed, in order, as make the free actuators' columns of
    /// `C` span what all the movable ones span, so that the multipliers are unique. A locked
    /// actuator (`lo = hi`) is always held.
    /// Returns the mask and the rank of the free actuators' columns of `C`.
    fn initial(&self, u: &Commands<T>, tol: T, tau: T) -> ([Bound; N], usize) {
        let mut mask = [Bound::Free; N];
        for (j, b) in mask.iter_mut().enumerate().take(self.m) {
            if u[j] <= self.lo[j] + tol {
                *b = Bound::Lower;
            } else if u[j] >= self.hi[j] - tol {
                *b = Bound::Upper;
            }
        }
        if self.k == 0 {
            return (mask, 0);
        }
        // the columns' span, by Gram–Schmidt over the k equality rows
        let column = |j: usize| {
            let mut c = [T::zero(); MAX_EQ];
            for (r, x) in c.iter_mut().enumerate().take(self.k) {
                *x = self.c[r][j];
            }
            c
        };
        let mut basis = [[T::zero(); MAX_EQ]; MAX_EQ];
        let mut norms = [T::zero(); MAX_EQ];
        let mut rank = 0;
        let mut add = |c: [T; MAX_EQ], basis: &mut [[T; MAX_EQ]; MAX_EQ], rank: &mut usize| {
            if *rank == self.k {
                return false;
            }
            let cc: T = c.iter().fold(T::zero(), |s, x| s + *x * *x);
            let mut v = c;
            for i in 0..*rank {
                let d: T = (0..self.k).fold(T::zero(), |s, r| s + v[r] * basis[i][r]);
                let d = d / norms[i];
                for r in 0..self.k {
                    v[r] -= d * basis[i][r];
                }
            }
            let vv = v.iter().fold(T::zero(), |s, x| s + *x * *x);
            if vv > tau * cc && vv > T::zero() {
                basis[*rank] = v;
                norms[*rank] = vv;
                *rank += 1;
                true
            } else {
                false
            }
        };
        for j in 0..self.m {
            if mask[j] == Bound::Free {
                add(column(j), &mut basis, &mut rank);
            }
        }
        for j in 0..self.m {
            if mask[j] != Bound::Free
                && self.hi[j] - self.lo[j] > tol
                && add(column(j), &mut basis, &mut rank)
            {
                mask[j] = Bound::Free;
            }
        }
        (mask, rank)
    }
}

/// `aᵀu − b` over the first `m` actuators.
fn residual<T: RealField + Copy>(a: &[T; N], b: T, u: &Commands<T>, m: usize) -> T {
    let mut s = -b;
    for j in 0..m {
        s += a[j] * u[j];
    }
    s
}

/// The least-squares solution `t` of `L t = −r`, `L` the `q × rank` coefficients of the
/// orthogonalised rows: by forward substitution when every row added a direction (`L` is
/// then unit lower triangular), else from the normal equations `LᵀL t = −Lᵀr` by `LDLᵀ`.
fn least_squares<T: RealField + Copy>(
    l: &[[T; MAX_EQ]; MAX_EQ],
    q: usize,
    rank: usize,
    r: &[T; MAX_EQ],
) -> [T; MAX_EQ] {
    let mut t = [T::zero(); MAX_EQ];
    if rank == q {
        for j in 0..q {
            let mut s = -r[j];
            for i in 0..j {
                s -= l[j][i] * t[i];
            }
            t[j] = s;
        }
        return t;
    }
    let mut g = [[T::zero(); MAX_EQ]; MAX_EQ];
    for a in 0..rank {
        for b in 0..=a {
            let s = (0..q).fold(T::zero(), |s, j| s + l[j][a] * l[j][b]);
            g[a][b] = s;
            g[b][a] = s;
        }
        t[a] = (0..q).fold(T::zero(), |s, j| s - l[j][a] * r[j]);
    }
    ldl_solve(&mut g, rank, &mut t);
    t
}

/// Solves `G x = h` in place (`G` symmetric positive definite, `n × n`) by `G = L D Lᵀ`:
/// no square root.
pub(crate) fn ldl_solve<T: RealField + Copy>(
    g: &mut [[T; MAX_EQ]; MAX_EQ],
    n: usize,
    x: &mut [T; MAX_EQ],
) {
    for j in 0..n {
        for k in 0..j {
            let ljk = g[j][k];
            g[j][j] -= ljk * ljk * g[k][k];
        }
        for i in j + 1..n {
            let mut s = g[i][j];
            for k in 0..j {
                s -= g[i][k] * g[j][k] * g[k][k];
            }
            g[i][j] = s / g[j][j];
        }
    }
    for i in 0..n {
        for k in 0..i {
            x[i] -= g[i][k] * x[k];
        }
    }
    for i in 0..n {
        x[i] /= g[i][i];
    }
    for i in (0..n).rev() {
        for k in i + 1..n {
            x[i] -= g[k][i] * x[k];
        }
    }
}

/// Solves the stage from `start`, which must be feasible (within the bounds, on `C u = d`),
/// with at most `budget` factorisations, in the workspace `f` (one for an allocation's
/// stages: each factorisation writes what it reads).
pub(crate) fn solve<T: RealField + Copy>(
    stage: &Stage<'_, T>,
    start: Commands<T>,
    budget: u32,
    f: &mut Factored<T>,
) -> Solved<T> {
    let (lo, hi, m) = (stage.lo, stage.hi, stage.m);
    let tol = tolerance(lo.as_slice(), hi.as_slice(), m);
    let tau = T::from_subset(&1e3) * T::default_epsilon();
    let mut inv_w = [T::one(); N];
    if let Objective::Nearest { w, .. } = stage.objective {
        for j in 0..m {
            inv_w[j] = T::one() / w[j];
        }
    }
    let mut u = start;
    let (mut mask, rank) = stage.initial(&u, tol, tau);
    // nothing can move and no bound can leave: the start is the answer (a stage with no free
    // dimension is skipped)
    if Free::of(&mask, m).n == rank && !movable_fixed(stage, &mask, tol) {
        return Solved {
            u,
            iterations: 0,
            stopped: false,
        };
    }
    let mut iterations = 0;
    // whether `f` holds the present working set's factorisation
    let mut factored = false;
    // the full steps taken on one factorisation (the second and third refine the first)
    let mut refinements = 0;
    loop {
        if !factored {
            if iterations == budget {
                return Solved {
                    u,
                    iterations,
                    stopped: true,
                };
            }
            iterations += 1;
            refinements = 0;
            // a planted slow path (scripts/cortex-m.sh's self-test): one more factorisation
            // per iteration must break the worst-case limits
            #[cfg(feature = "planted-slow-path")]
            stage.factor(&mask, &inv_w, tau, core::hint::black_box(&mut *f));
            stage.factor(&mask, &inv_w, tau, f);
            factored = true;
        }
        let r = stage.residuals(&u);
        let p = stage.step(f, &u, &r);
        let size = p.iter().take(m).fold(T::zero(), |a, x| larger(a, x.abs()));
        if size <= tol || refinements == 3 {
            match stage.release(f, &mask, &u, &r, tol) {
                Some(j) => {
                    mask[j] = Bound::Free;
                    factored = false;
                }
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
        let (alpha, block) = step_length(&f.free, lo, hi, &u, &p, tol);
        f.free.iter().for_each(|j| u[j] += p[j] * alpha);
        match block {
            Some((j, b)) => {
                u[j] = if b == Bound::Lower { lo[j] } else { hi[j] };
                mask[j] = b;
                factored = false;
            }
            None => refinements += 1,
        }
    }
}

/// Whether some actuator held at a bound could leave it (its bounds differ).
fn movable_fixed<T: RealField + Copy>(stage: &Stage<'_, T>, mask: &[Bound; N], tol: T) -> bool {
    (0..stage.m).any(|j| mask[j] != Bound::Free && stage.hi[j] - stage.lo[j] > tol)
}

/// The longest step along `p` (at most 1) that keeps the free actuators within their bounds,
/// and the bound that stops it (components of `p` within `tol` of 0 block nothing).
fn step_length<T: RealField + Copy>(
    free: &Free,
    lo: &Commands<T>,
    hi: &Commands<T>,
    u: &Commands<T>,
    p: &[T; N],
    tol: T,
) -> (T, Option<(usize, Bound)>) {
    let mut alpha = T::one();
    let mut block = None;
    for i in free.iter() {
        // a component at rounding level moves nothing: it does not block
        let (room, bound) = if p[i] < -tol {
            ((lo[i] - u[i]) / p[i], Bound::Lower)
        } else if p[i] > tol {
            ((hi[i] - u[i]) / p[i], Bound::Upper)
        } else {
            continue;
        };
        let room = larger(T::zero(), room);
        if room < alpha {
            alpha = room;
            block = Some((i, bound));
        }
    }
    (alpha, block)
}

#[cfg(test)]
mod step_tests {
    use super::Objective as Stage_;
    use super::{Bound, Commands, Factored, MAX_EQ, N, Rows, Stage};
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;

    /// A stage's objective over the free actuators, for [`reference`].
    enum Objective<'a> {
        /// `‖A_F p + r‖²`: `A_F` and the residual `r = Au − b`.
        LeastSquares(&'a DMatrix<f64>, &'a DVector<f64>),
        /// `(v + p)ᵀW(v + p)`: `W`'s diagonal and `v = u − u_pref`.
        Nearest(&'a DVector<f64>, &'a DVector<f64>),
    }

    /// The step by its definition (docs/maths.md, "Control allocation": the step), by
    /// singular value decompositions: over an orthonormal basis `Z` of the null space of
    /// `C_F`, the minimum-norm minimiser of the objective.
    fn reference(c: &DMatrix<f64>, objective: Objective<'_>) -> DVector<f64> {
        let n = c.ncols();
        // the right singular vectors of C_F (padded square) with a singular value at
        // rounding level
        let padded = DMatrix::from_fn(n.max(c.nrows()), n, |r, i| {
            if r < c.nrows() { c[(r, i)] } else { 0.0 }
        });
        let svd = padded.svd(false, true);
        let vt = svd.v_t.unwrap();
        let top = svd.singular_values.max();
        let basis: Vec<DVector<f64>> = (0..n)
            .filter(|i| svd.singular_values[*i] <= 1e-9 * (1.0 + top))
            .map(|i| vt.row(i).transpose())
            .collect();
        if basis.is_empty() {
            return DVector::zeros(n);
        }
        let z = DMatrix::from_columns(&basis);
        let x = match objective {
            Objective::LeastSquares(a, r) => (a * &z).pseudo_inverse(1e-10).unwrap() * (-r),
            Objective::Nearest(w, v) => {
                let wm = DMatrix::from_diagonal(w);
                let h = z.transpose() * &wm * &z;
                h.pseudo_inverse(1e-10).unwrap() * -(z.transpose() * &wm * v)
            }
        };
        &z * x
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The factorisation's step equals the step by definition, on random rows, working
        /// sets and stages (the torque, the force under the torque, the last).
        #[test]
        fn the_step_is_the_definitions(
            entries in proptest::collection::vec(-1.0f64..1.0, 6 * N),
            m in 3usize..=N,
            kind in 0usize..3,
            held in proptest::collection::vec(any::<bool>(), N),
            us in proptest::collection::vec(-1.0f64..1.0, N),
            ws in proptest::collection::vec(0.1f64..1.0, N),
            bs in proptest::collection::vec(-1.0f64..1.0, 6),
        ) {
            let mut rows: Rows<f64> = [[0.0; N]; MAX_EQ];
            for r in 0..6 {
                for j in 0..m {
                    rows[r][j] = entries[r * N + j];
                }
            }
            let mut force: Rows<f64> = [[0.0; N]; MAX_EQ];
            force[..3].copy_from_slice(&rows[3..6]);
            let mut b = [0.0; MAX_EQ];
            b.copy_from_slice(&bs);
            let mut fb = [0.0; MAX_EQ];
            fb[..3].copy_from_slice(&bs[3..6]);
            let mut u = Commands::<f64>::zeros();
            let mut w = Commands::<f64>::from_element(1.0);
            for j in 0..m {
                u[j] = us[j];
                w[j] = ws[j];
            }
            let up = Commands::<f64>::zeros();
            let (lo, hi) = (Commands::from_element(-2.0), Commands::from_element(2.0));
            let (objective, k) = match kind {
                0 => (Stage_::LeastSquares { a: &rows, b: &b, q: 3 }, 0),
                1 => (Stage_::LeastSquares { a: &force, b: &fb, q: 3 }, 3),
                _ => (Stage_::Nearest { w: &w, up: &up }, 6),
            };
            let stage = Stage { objective, c: &rows, k, m, lo: &lo, hi: &hi };
            let mut mask = [Bound::Free; N];
            for j in 0..m {
                if held[j] {
                    mask[j] = Bound::Lower;
                }
            }
            let mut inv_w = [1.0; N];
            if kind == 2 {
                for j in 0..m {
                    inv_w[j] = 1.0 / w[j];
                }
            }
            let mut f = Factored::new();
            stage.factor(&mask, &inv_w, 1e3 * f64::EPSILON, &mut f);
            let p = stage.step(&f, &u, &stage.residuals(&u));
            let free: Vec<usize> = (0..m).filter(|j| !held[*j]).collect();
            let n = free.len();
            prop_assume!(n > 0);
            let c = DMatrix::from_fn(k, n, |r, i| rows[r][free[i]]);
            let got = DVector::from_fn(n, |i, _| p[free[i]]);
            let (want, how) = if kind == 2 {
                let wf = DVector::from_fn(n, |i, _| w[free[i]]);
                let v = DVector::from_fn(n, |i, _| u[free[i]]);
                (reference(&c, Objective::Nearest(&wf, &v)), String::new())
            } else {
                let (a, target) = if kind == 0 { (&rows, &b) } else { (&force, &fb) };
                let am = DMatrix::from_fn(3, n, |r, i| a[r][free[i]]);
                let res = DVector::from_fn(3, |r, _| {
                    (0..m).map(|j| a[r][j] * u[j]).sum::<f64>() - target[r]
                });
                let want = reference(&c, Objective::LeastSquares(&am, &res));
                let misses = ((&am * &got + &res).norm(), (&am * &want + &res).norm());
                (want, format!("; ‖A p + r‖ {:e}, by definition {:e}", misses.0, misses.1))
            };
            // a backward-stable step is exact to a tolerance relative to its size: a
            // near-singular A_F gives a long step (3e4 in a saved case) that agrees to 3e-11
            prop_assert!(
                (&got - &want).amax() < 1e-7 * (1.0 + want.amax()),
                "stage {kind}, {n} free: p {:?}, by definition {:?}; ‖C p‖ {:e}{how}",
                got.as_slice(),
                want.as_slice(),
                (&c * &got).norm()
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{clamp, larger};
    use proptest::prelude::*;

    proptest! {
        /// The comparisons give what `max` and `min` give (the same value; a tie of zeros of
        /// either sign is the same value), a NaN `x` clamped to `l` as `max` does.
        #[test]
        fn clamp_and_larger_are_max_and_min(
            x in prop_oneof![any::<f32>(), Just(f32::NAN), Just(-0.0f32), Just(0.0f32)],
            a in -1e6f32..1e6,
            w in 0.0f32..1e6,
        ) {
            let (l, h) = (a, a + w);
            let want = x.max(l).min(h);
            let got = clamp(x, l, h);
            prop_assert!(got == want, "clamp({x}, {l}, {h}) = {got}, max/min {want}");
            prop_assert!(got >= l && got <= h);
            let (p, q) = (a.abs(), x.abs());
            let want = p.max(q);
            let got = larger(p, q);
            prop_assert!(got == want || (q.is_nan() && got == p), "larger({p}, {q}) = {got}");
        }
    }
}
