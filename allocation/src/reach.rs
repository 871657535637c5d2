//! Stages 1 and 2 of a block of three rows and three or four actuators by its reach, and stage
//! 3 on the line those stages leave
//! (docs/maths.md, "Control allocation": a block of three rows by its reach). The BlueROV2 Heavy layout's two blocks are such: four thrusters each, moving
//! `τx, τy, fz` and `τz, fx, fy`.
//!
//! The wrenches the box produces in the block's rows form a zonotope `Z = {B u : lo ≤ u ≤ hi}`.
//! When the movable columns span three dimensions, `Z` is the intersection of the slabs
//! `low_f ≤ n_f · x ≤ high_f` of its facets, `n_f = b_i × b_k` over the pairs of columns, with
//! `[low_f, high_f] = Σ_l (n_f·b_l) mid_l ∓ |n_f·b_l| width_l` (`mid`, `width` the box's centre
//! and half-width). With the rows in the stages' order:
//!
//! * stage 1 of all three rows (or of none: then stage 2 has them all) is the point of `Z`
//!   nearest the demand, by the dual method over the slabs, as for a square geometry
//!   (`zonotope.rs`, `dual.rs`);
//! * stage 1 of one row is the demand clamped into the row's interval, and stage 2 the point
//!   of the slabs' slice at that value nearest the other two rows' demand: a polygon, by the
//!   dual method in two dimensions (beyond the row's reach the slice is one point, a vertex);
//! * stage 1 of two rows is the point nearest their demand of `Z`'s shadow on them, the
//!   zonotope of the columns' two entries, a polygon whose edges are normal to `(−b_l,1, b_l,0)`
//!   (dual method in two dimensions); stage 2 clamps the third row's demand into the slabs'
//!   slice at those values, an interval.
//!
//! The commands of the wrench `x` these reach form the line `Bᵀ(BBᵀ)⁻¹x + α n`, `n` spanning
//! `B`'s null space (one point with three actuators), where stage 3 is in closed form
//! ([`blocks::along`]). Everything that depends on `B` alone is formed once, with the
//! allocator.

#![allow(clippy::needless_range_loop)]

use crate::blocks::{self, Compact};
use crate::dual::{self, Dual, dot3};
use crate::qp::MAX_EQ;
use crate::qp::{clamp, tolerance};
use crate::zonotope::cross;
use crate::{Commands, MAX_ACTUATORS};
use nalgebra::{Matrix3, RealField};

/// The most actuators of a block solved by its reach.
const REACH: usize = 4;
/// The pairs of their columns: the reach's facets.
const FACETS: usize = REACH * (REACH - 1) / 2;

/// A block of three rows solved by its reach: its columns, facets and shadow's edges, its
/// pseudo-inverse and null vector, formed once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Reach<T> {
    m: usize,
    /// The columns `b_k` (the block's rows in the stages' order).
    g: [[T; 3]; REACH],
    /// The facets' normals `b_i × b_k` (over the pairs far enough apart), `n_f · b_l` (0 for
    /// the pair's own columns), the pairs, and the columns well out of each facet's plane (a
    /// mask).
    normals: [[T; 3]; FACETS],
    dots: [[T; REACH]; FACETS],
    pairs: [[usize; 2]; FACETS],
    out: [u8; FACETS],
    facets: usize,
    /// The shadow's edges on rows 0 and 1, `(−b_k,1, b_k,0, 0)` over the columns with a
    /// shadow, `e · b_l` (0 for its own column), its column, and the columns well out of its
    /// line (a mask).
    edges: [[T; 3]; REACH],
    edots: [[T; REACH]; REACH],
    edge_of: [usize; REACH],
    eout: [u8; REACH],
    nedges: usize,
    /// `Bᵀ(BBᵀ)⁻¹`, row `j` per actuator.
    pseudo: [[T; 3]; REACH],
    /// `B`'s null vector with four actuators (zero with three).
    null: [T; MAX_ACTUATORS],
}

impl<T: RealField + Copy> Reach<T> {
    /// The reach of the block `p` (its rows and columns; the bounds are not read)
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach), or `None`
    /// when it has not three independent rows and three or four actuators.
    pub(crate) fn of(p: &Compact<T>) -> Option<Self> {
        let m = p.m;
        if p.rows != 3 || !(3..=REACH).contains(&m) {
            return None;
        }
        let g: [[T; 3]; REACH] = core::array::from_fn(|k| {
            if k < m {
                [p.all[0][k], p.all[1][k], p.all[2][k]]
            } else {
                [T::zero(); 3]
            }
        });
        let norms: [T; REACH] = core::array::from_fn(|k| dot3(&g[k], &g[k]));
        let mut reach = Reach {
            m,
            g,
            normals: [[T::zero(); 3]; FACETS],
            dots: [[T::zero(); REACH]; FACETS],
            pairs: [[0; 2]; FACETS],
            out: [0; FACETS],
            facets: 0,
            edges: [[T::zero(); 3]; REACH],
            edots: [[T::zero(); REACH]; REACH],
            edge_of: [0; REACH],
            eout: [0; REACH],
            nedges: 0,
            pseudo: [[T::zero(); 3]; REACH],
            null: [T::zero(); MAX_ACTUATORS],
        };
        reach.facets_and_edges(&norms);
        // Bᵀ(BBᵀ)⁻¹ and, with four columns, the null vector n = (I − Bᵀ(BBᵀ)⁻¹B) e_k for
        // the k that keeps the most of e_k
        let gram = Matrix3::from_fn(|a, b| (0..m).fold(T::zero(), |s, j| s + g[j][a] * g[j][b]));
        let inverse = gram.cholesky()?.inverse();
        for j in 0..m {
            for a in 0..3 {
                reach.pseudo[j][a] = (0..3).fold(T::zero(), |s, b| s + g[j][b] * inverse[(b, a)]);
            }
        }
        let projector =
            |j: usize, k: usize| (0..3).fold(T::zero(), |s, a| s + reach.pseudo[j][a] * g[k][a]);
        if m == REACH {
            let keep = |k: usize| T::one() - projector(k, k);
            let k = (1..m).fold(0, |best, k| if keep(k) > keep(best) { k } else { best });
            for j in 0..m {
                reach.null[j] = if j == k { T::one() } else { T::zero() } - projector(j, k);
            }
        }
        Some(reach)
    }

    /// The facets of the reach and the edges of its shadow on rows 0 and 1 (`norms`: `|b_k|²`)
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach).
    fn facets_and_edges(&mut self, norms: &[T; REACH]) {
        let (m, g) = (self.m, self.g);
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        for i in 0..m {
            for k in i + 1..m {
                let n = cross(&g[i], &g[k]);
                let nn = dot3(&n, &n);
                if nn <= tau * norms[i] * norms[k] {
                    continue;
                }
                let f = self.facets;
                self.normals[f] = n;
                self.pairs[f] = [i, k];
                for l in (0..m).filter(|&l| l != i && l != k) {
                    let d = dot3(&n, &g[l]);
                    self.dots[f][l] = d;
                    if d * d > tau * nn * norms[l] {
                        self.out[f] |= 1 << l;
                    }
                }
                self.facets += 1;
            }
        }
        for k in 0..m {
            let e = [-g[k][1], g[k][0], T::zero()];
            let ee = dot3(&e, &e);
            if ee <= tau * norms[k] {
                continue;
            }
            let r = self.nedges;
            self.edges[r] = e;
            self.edge_of[r] = k;
            for l in (0..m).filter(|&l| l != k) {
                let d = dot3(&e, &g[l]);
                self.edots[r][l] = d;
                let shadow = g[l][0] * g[l][0] + g[l][1] * g[l][1];
                if d * d > tau * ee * shadow {
                    self.eout[r] |= 1 << l;
                }
            }
            self.nedges += 1;
        }
    }

    /// Stages 1 and 2 of the block `p` (its bounds, demand and stage-1 rows) within `budget`
    /// working-set changes: the block's wrench in its rows' order (`x` of `Solved`) and the
    /// changes spent; `Failed` when the movable columns span less than three dimensions
    /// (stage 1 of two rows: when their shadow is flat) or rounding defeats the method.
    pub(crate) fn stages(&self, p: &Compact<T>, budget: u32) -> Dual<T> {
        let b = Span::of(p, self.m);
        let solid = (0..self.facets).any(|f| {
            let [i, k] = self.pairs[f];
            b.moves(i) && b.moves(k) && self.out[f] & b.movable != 0
        });
        if !solid {
            return Dual::Failed { changes: 0 };
        }
        let mut slabs = [[T::zero(); 2]; FACETS];
        for f in 0..self.facets {
            slabs[f] = b.range(&self.dots[f]);
        }
        let answer = match p.first {
            0 | 3 => self.nearest(&p.wanted, &slabs, budget),
            1 => self.sliced(p, &b, &slabs, budget),
            _ => self.shadow(p, &b, &slabs, budget),
        };
        match answer {
            Dual::Solved { x, changes } if !x.iter().all(|v| v.is_finite()) => {
                Dual::Failed { changes }
            }
            other => other,
        }
    }

    /// One stage of all three rows: the point of `Z` (its facets' `slabs`) nearest `w`
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach).
    fn nearest(&self, w: &[T; MAX_EQ], slabs: &[[T; 2]; FACETS], budget: u32) -> Dual<T> {
        let normals = &self.normals;
        let centre: [T; FACETS] = core::array::from_fn(|f| dot3(&normals[f], &[w[0], w[1], w[2]]));
        let low: [T; FACETS] = core::array::from_fn(|f| slabs[f][0]);
        let high: [T; FACETS] = core::array::from_fn(|f| slabs[f][1]);
        match dual::solve(normals, &centre, &low, &high, self.facets, budget) {
            Dual::Solved { x, changes } => Dual::Solved {
                x: [w[0] + x[0], w[1] + x[1], w[2] + x[2]],
                changes,
            },
            other => other,
        }
    }

    /// Stage 1 of row 0, an interval; stage 2 of rows 1 and 2
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach), the point nearest their demand
    /// of the slabs' slice at row 0's value, a polygon (beyond the row's reach, one vertex).
    fn sliced(
        &self,
        p: &Compact<T>,
        b: &Span<T>,
        slabs: &[[T; 2]; FACETS],
        budget: u32,
    ) -> Dual<T> {
        let (m, w, g, lo, hi) = (self.m, &p.wanted, &self.g, &p.lo, &p.hi);
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let (floor, ceiling) = blocks::row_reach(|l| g[l][0], lo.as_slice(), hi.as_slice(), m);
        let t = clamp(w[0], floor, ceiling);
        if t != w[0] && (0..m).all(|l| g[l][0] != T::zero() || !b.moves(l)) {
            // beyond the row's reach every actuator that moves the row is at the bound that
            // takes it there, and the others are held: Z's face there is one point
            let top = t == ceiling;
            let at = |l: usize| match (g[l][0] > T::zero(), g[l][0] < T::zero()) {
                (true, _) if top => hi[l],
                (true, _) => lo[l],
                (_, true) if top => lo[l],
                (_, true) => hi[l],
                _ => b.mid[l],
            };
            let (y, z) = (0..m).fold((T::zero(), T::zero()), |(y, z), l| {
                (y + g[l][1] * at(l), z + g[l][2] * at(l))
            });
            return Dual::Solved {
                x: [t, y, z],
                changes: 0,
            };
        }
        let mut rows = [[T::zero(); 3]; FACETS];
        let mut centre = [T::zero(); FACETS];
        let (mut from, mut to) = ([T::zero(); FACETS], [T::zero(); FACETS]);
        let mut kept = 0;
        for f in 0..self.facets {
            let n = &self.normals[f];
            if n[1] * n[1] + n[2] * n[2] > tau * dot3(n, n) {
                rows[kept] = [n[1], n[2], T::zero()];
                centre[kept] = n[1] * w[1] + n[2] * w[2];
                (from[kept], to[kept]) = (slabs[f][0] - n[0] * t, slabs[f][1] - n[0] * t);
                kept += 1;
            }
        }
        match dual::solve(&rows, &centre, &from, &to, kept, budget) {
            Dual::Solved { x, changes } => Dual::Solved {
                x: [t, w[1] + x[0], w[2] + x[1]],
                changes,
            },
            other => other,
        }
    }

    /// Stage 1 of rows 0 and 1 (docs/maths.md, "Control allocation": a block of three rows by its reach),
    /// the point nearest their demand of `Z`'s shadow on them; stage 2
    /// of row 2, its demand clamped into the slabs' slice at those values, an interval.
    fn shadow(
        &self,
        p: &Compact<T>,
        b: &Span<T>,
        slabs: &[[T; 2]; FACETS],
        budget: u32,
    ) -> Dual<T> {
        let w = &p.wanted;
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let plane =
            (0..self.nedges).any(|r| b.moves(self.edge_of[r]) && self.eout[r] & b.movable != 0);
        if !plane {
            return Dual::Failed { changes: 0 };
        }
        let mut centre = [T::zero(); REACH];
        let (mut from, mut to) = ([T::zero(); REACH], [T::zero(); REACH]);
        for r in 0..self.nedges {
            [from[r], to[r]] = b.range(&self.edots[r]);
            centre[r] = self.edges[r][0] * w[0] + self.edges[r][1] * w[1];
        }
        let (x, changes) = match dual::solve(&self.edges, &centre, &from, &to, self.nedges, budget)
        {
            Dual::Solved { x, changes } => (x, changes),
            other => return other,
        };
        let (a, c) = (w[0] + x[0], w[1] + x[1]);
        let Some(top) = T::max_value() else {
            return Dual::Failed { changes };
        };
        let (mut floor, mut ceiling) = (-top, top);
        for f in 0..self.facets {
            let n = &self.normals[f];
            if n[2] * n[2] > tau * dot3(n, n) {
                let rest = n[0] * a + n[1] * c;
                let (x, y) = ((slabs[f][0] - rest) / n[2], (slabs[f][1] - rest) / n[2]);
                let (x, y) = if x <= y { (x, y) } else { (y, x) };
                if x > floor {
                    floor = x;
                }
                if y < ceiling {
                    ceiling = y;
                }
            }
        }
        let z = if floor <= ceiling {
            clamp(w[2], floor, ceiling)
        } else {
            // rounding has emptied the slice of a point on Z's boundary: its middle
            (floor + ceiling) / T::from_subset(&2.0)
        };
        Dual::Solved {
            x: [a, c, z],
            changes,
        }
    }

    /// Every stage of the block `p` when two of its actuators move and the rest are held (a
    /// flat reach; docs/maths.md, "Control allocation": a block of three rows by its reach): the wrench is
    /// `c + G v` over the two movable commands `v`, `G` their two columns, so each stage is a
    /// least-squares problem in two unknowns over what the stages before left, a rectangle, a
    /// segment or a point ([`Two`]). `None` when not two actuators move, or their columns are
    /// not independent.
    pub(crate) fn two(
        &self,
        p: &Compact<T>,
        w: &Commands<T>,
        up: &Commands<T>,
    ) -> Option<Commands<T>> {
        let m = self.m;
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let half = T::from_subset(&0.5);
        let (lo, hi, g) = (&p.lo, &p.hi, &self.g);
        let tol = tolerance(lo.as_slice(), hi.as_slice(), m);
        let mut pair = [0; 2];
        let mut count = 0;
        for k in (0..m).filter(|&k| hi[k] - lo[k] > tol) {
            if count == 2 {
                return None;
            }
            pair[count] = k;
            count += 1;
        }
        let [a, b] = pair;
        let n = cross(&g[a], &g[b]);
        if count != 2 || dot3(&n, &n) <= tau * dot3(&g[a], &g[a]) * dot3(&g[b], &g[b]) {
            return None;
        }
        // the held actuators' wrench, and each row's demand less it
        let mut u = Commands::zeros();
        for k in 0..m {
            u[k] = (lo[k] + hi[k]) * half;
        }
        let rest: [T; 3] = core::array::from_fn(|r| {
            p.wanted[r]
                - (0..m)
                    .filter(|&k| k != a && k != b)
                    .fold(T::zero(), |s, k| s + g[k][r] * u[k])
        });
        let rows: [[T; 2]; 3] = core::array::from_fn(|r| [g[a][r], g[b][r]]);
        let mut set = Two::Rectangle;
        let first = if p.first == 0 { 3 } else { p.first };
        let stages = [(0, first), (first, 3)];
        let (blo, bhi) = ([lo[a], lo[b]], [hi[a], hi[b]]);
        for (from, to) in stages.into_iter().filter(|(f, t)| f < t) {
            set = set.least_squares(&rows[from..to], &rest[from..to], &blo, &bhi, tau)?;
        }
        let v = set.nearest(&[w[a], w[b]], &[up[a], up[b]], &blo, &bhi)?;
        (u[a], u[b]) = (v[0], v[1]);
        u.iter().all(|x| x.is_finite()).then_some(u)
    }

    /// Stage 3 (docs/maths.md, "Control allocation": a block of three rows by its reach): the command of the
    /// block's wrench `x` nearest `up` in the `w`-norm within the box, on the line
    /// `Bᵀ(BBᵀ)⁻¹x + α n` ([`blocks::along`]), or the one command `B⁻¹x` with three
    /// actuators. `None` when the box misses the line.
    pub(crate) fn last(
        &self,
        p: &Compact<T>,
        w: &Commands<T>,
        up: &Commands<T>,
        x: &[T; 3],
    ) -> Option<Commands<T>> {
        let mut u = Commands::zeros();
        for j in 0..self.m {
            u[j] = dot3(&self.pseudo[j], x);
        }
        if self.m < REACH {
            // the one command: within the box, or the stages' wrench is not in Z (rounding
            // defeated them) and the primal stages answer
            let tol = tolerance(p.lo.as_slice(), p.hi.as_slice(), self.m);
            let inside = (0..self.m).all(|j| u[j] >= p.lo[j] - tol && u[j] <= p.hi[j] + tol);
            return inside.then_some(u);
        }
        blocks::along(p, w, up, &u, &self.null)
    }
}

/// A block's box: each actuator's centre and half-width, and which move (a mask).
struct Span<T> {
    m: usize,
    mid: [T; REACH],
    width: [T; REACH],
    movable: u8,
}

impl<T: RealField + Copy> Span<T> {
    fn of(p: &Compact<T>, m: usize) -> Self {
        let half = T::from_subset(&0.5);
        let (lo, hi) = (&p.lo, &p.hi);
        let tol = tolerance(lo.as_slice(), hi.as_slice(), m);
        let mut span = Span {
            m,
            mid: [T::zero(); REACH],
            width: [T::zero(); REACH],
            movable: 0,
        };
        for k in 0..m {
            span.mid[k] = (lo[k] + hi[k]) * half;
            span.width[k] = (hi[k] - lo[k]) * half;
            if hi[k] - lo[k] > tol {
                span.movable |= 1 << k;
            }
        }
        span
    }

    fn moves(&self, k: usize) -> bool {
        self.movable & (1 << k) != 0
    }

    /// The range of `d · u` over the box, `Σ_l d_l mid_l ∓ |d_l| width_l`
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach).
    fn range(&self, d: &[T; REACH]) -> [T; 2] {
        let (mut c, mut r) = (T::zero(), T::zero());
        for l in 0..self.m {
            c += d[l] * self.mid[l];
            r += d[l].abs() * self.width[l];
        }
        [c - r, c + r]
    }
}

/// What the stages before have left of two movable commands `v` within their box.
#[derive(Debug, Clone, Copy)]
enum Two<T> {
    /// The whole box.
    Rectangle,
    /// `v0 + t d`, `t` in `[t0, t1]`.
    Segment { v0: [T; 2], d: [T; 2], t: [T; 2] },
    /// One command.
    Point([T; 2]),
}

impl<T: RealField + Copy> Two<T> {
    /// The part of `self` where `‖A v − r‖²` is least (`A` the rows `a`): a point where `A`
    /// fixes `v` (rank 2 on the box, or any rank on a segment), the segment `q · v = s*` where
    /// `A`'s rows are multiples of one `q` (rank 1 on the box), `self` where `A` is 0.
    fn least_squares(
        self,
        a: &[[T; 2]],
        r: &[T],
        lo: &[T; 2],
        hi: &[T; 2],
        tau: T,
    ) -> Option<Self> {
        let dot = |x: &[T; 2], y: &[T; 2]| x[0] * y[0] + x[1] * y[1];
        let miss = |v: &[T; 2]| {
            a.iter().zip(r).fold(T::zero(), |s, (row, r)| {
                let e = dot(row, v) - *r;
                s + e * e
            })
        };
        match self {
            Two::Point(_) => Some(self),
            Two::Segment { v0, d, t } => {
                // ‖A (v0 + t d) − r‖² in t
                let (mut num, mut den) = (T::zero(), T::zero());
                for (row, r) in a.iter().zip(r) {
                    let ad = dot(row, &d);
                    num += ad * (*r - dot(row, &v0));
                    den += ad * ad;
                }
                if den <= T::zero() {
                    return Some(self);
                }
                let s = clamp(num / den, t[0], t[1]);
                Some(Two::Point([v0[0] + s * d[0], v0[1] + s * d[1]]))
            }
            Two::Rectangle => {
                // AᵀA and Aᵀr
                let (mut h, mut y) = ([[T::zero(); 2]; 2], [T::zero(); 2]);
                for (row, r) in a.iter().zip(r) {
                    for i in 0..2 {
                        y[i] += row[i] * *r;
                        for j in 0..2 {
                            h[i][j] += row[i] * row[j];
                        }
                    }
                }
                let trace = h[0][0] + h[1][1];
                let det = h[0][0] * h[1][1] - h[0][1] * h[1][0];
                if trace <= T::zero() {
                    return Some(self);
                }
                // rank 2 beyond rounding's reach; rank 1 within a few ulps of the trace's
                // square (as `AᵀA` of rows that are multiples of one row comes out); between,
                // neither is sure, and the primal stages answer
                if det > tau * trace * trace {
                    return Some(Self::box_least_squares(&h, &y, det, lo, hi, miss));
                }
                if det > T::from_subset(&64.0) * T::default_epsilon() * trace * trace {
                    return None;
                }
                Self::on_a_row(&h, a, r, lo, hi)
            }
        }
    }

    /// Rank 2 on the box (docs/maths.md, "Control allocation": a block of three rows by its reach):
    /// the unconstrained optimum `(AᵀA)⁻¹Aᵀr` (`h = AᵀA`, `y = Aᵀr`, `det`
    /// its determinant) when within the box, else the best of the four edges' optima, each a
    /// clamped one-dimensional least squares (the miss is convex: its least over the box is
    /// on the boundary then).
    fn box_least_squares(
        h: &[[T; 2]; 2],
        y: &[T; 2],
        det: T,
        lo: &[T; 2],
        hi: &[T; 2],
        miss: impl Fn(&[T; 2]) -> T,
    ) -> Self {
        let v = [
            (h[1][1] * y[0] - h[0][1] * y[1]) / det,
            (h[0][0] * y[1] - h[1][0] * y[0]) / det,
        ];
        if (0..2).all(|i| v[i] >= lo[i] && v[i] <= hi[i]) {
            return Two::Point(v);
        }
        let mut best: Option<([T; 2], T)> = None;
        for fixed in 0..2 {
            let other = 1 - fixed;
            for bound in [lo[fixed], hi[fixed]] {
                let free = if h[other][other] > T::zero() {
                    clamp(
                        (y[other] - h[other][fixed] * bound) / h[other][other],
                        lo[other],
                        hi[other],
                    )
                } else {
                    lo[other]
                };
                let mut v = [T::zero(); 2];
                (v[fixed], v[other]) = (bound, free);
                let e = miss(&v);
                if best.is_none_or(|(_, b)| e < b) {
                    best = Some((v, e));
                }
            }
        }
        best.map_or(Two::Point(v), |(v, _)| Two::Point(v))
    }

    /// Rank 1 on the box (docs/maths.md, "Control allocation": a block of three rows by its reach):
    /// the rows of `A` are multiples of `q` (of `h = AᵀA`, the row of the
    /// larger norm); the miss is least where `q · v = s*`, `s*` the least-squares value clamped
    /// into `q · v`'s range over the box: a segment (one point at a corner).
    fn on_a_row(h: &[[T; 2]; 2], a: &[[T; 2]], r: &[T], lo: &[T; 2], hi: &[T; 2]) -> Option<Self> {
        let dot = |x: &[T; 2], y: &[T; 2]| x[0] * y[0] + x[1] * y[1];
        let q = if h[0][0] >= h[1][1] {
            [h[0][0], h[0][1]]
        } else {
            [h[1][0], h[1][1]]
        };
        let qq = dot(&q, &q);
        // A v = α (q · v) row by row: Σ α_i r_i / Σ α_i² with α_i = (row_i · q)/|q|²
        let (mut num, mut den) = (T::zero(), T::zero());
        for (row, r) in a.iter().zip(r) {
            let alpha = dot(row, &q) / qq;
            num += alpha * *r;
            den += alpha * alpha;
        }
        let (floor, ceiling) = blocks::row_reach(|i| q[i], lo, hi, 2);
        let s = clamp(num / den, floor, ceiling);
        let v0 = [q[0] * s / qq, q[1] * s / qq];
        let d = [-q[1], q[0]];
        let (mut t0, mut t1) = (-T::max_value()?, T::max_value()?);
        for i in 0..2 {
            // a side the segment crosses (a tiny `d_i` gives a wide, correct interval)
            if d[i] != T::zero() {
                let (x, y) = ((lo[i] - v0[i]) / d[i], (hi[i] - v0[i]) / d[i]);
                let (x, y) = if x <= y { (x, y) } else { (y, x) };
                t0 = if x > t0 { x } else { t0 };
                t1 = if y < t1 { y } else { t1 };
            }
        }
        if t0 > t1 {
            // rounding at a corner of the box: that corner
            let t = (t0 + t1) / T::from_subset(&2.0);
            return Some(Two::Point([v0[0] + t * d[0], v0[1] + t * d[1]]));
        }
        Some(Two::Segment { v0, d, t: [t0, t1] })
    }

    /// The command of `self` nearest `up` in the `w`-norm, within the box.
    fn nearest(self, w: &[T; 2], up: &[T; 2], lo: &[T; 2], hi: &[T; 2]) -> Option<[T; 2]> {
        let v = match self {
            Two::Point(v) => v,
            Two::Rectangle => [clamp(up[0], lo[0], hi[0]), clamp(up[1], lo[1], hi[1])],
            Two::Segment { v0, d, t } => {
                let num = w[0] * d[0] * (up[0] - v0[0]) + w[1] * d[1] * (up[1] - v0[1]);
                let den = w[0] * d[0] * d[0] + w[1] * d[1] * d[1];
                let s = if den > T::zero() {
                    clamp(num / den, t[0], t[1])
                } else {
                    t[0]
                };
                [v0[0] + s * d[0], v0[1] + s * d[1]]
            }
        };
        Some([clamp(v[0], lo[0], hi[0]), clamp(v[1], lo[1], hi[1])])
    }
}
