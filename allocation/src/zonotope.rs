//! Stage 1 of a square, well-separated geometry (the six-rotor hexarotor) by its reach
//! (docs/maths.md, "Control allocation": stage 1 of a square geometry). The torques the box can
//! produce form a zonotope `Z = {B_τ u : lo ≤ u ≤ hi}`, and stage 1's torque `τ*` is the
//! point of `Z` nearest `τ_d`. A full-dimensional zonotope in three dimensions is the
//! intersection of the half-spaces of its facets, whose normals are among the cross products
//! `n = b_i × b_j` of its generators, each with its support value
//! `h_Z(n) = Σ_k max(lo_k n·b_k, hi_k n·b_k)`. So stage 1 is
//!
//! ```text
//! min ½‖x‖²  subject to  −h_Z(−n_f) − n_f·τ_d ≤ n_f · x ≤ h_Z(n_f) − n_f·τ_d,   x = τ − τ_d,
//! ```
//!
//! for the fifteen pairs `f = (i, j)`: three unknowns, strictly convex, solved by the same dual
//! method as stage 2 (`dual.rs`).

#![allow(clippy::needless_range_loop)]

use crate::dual::{self, Dual, dot3};
use nalgebra::RealField;

/// The actuators of a square geometry's stage 1 (three torque rows, six columns).
const M: usize = 6;
/// The pairs of its columns.
pub(crate) const PAIRS: usize = M * (M - 1) / 2;

/// The facets' unit normals `n_f = (b_i × b_j)/|b_i × b_j|` (zero for a pair that spans no
/// plane) and `n_f · b_k` for every column, formed once with the allocator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Facets<T> {
    normals: [[T; 3]; PAIRS],
    dots: [[T; M]; PAIRS],
    /// The columns `(i, j)` of each pair.
    pairs: [[usize; 2]; PAIRS],
    /// `|b_k|²`.
    norms: [T; M],
    /// The columns `b_k`.
    columns: [[T; 3]; M],
    /// `|b_i × b_j|² / (|b_i|² |b_j|²)` of each pair: how far apart its columns are.
    apart: [T; PAIRS],
}

impl<T: RealField + Copy> Facets<T> {
    /// The facets of the zonotope of `columns` (`b_k`, stage 1's rows of column `k`).
    pub(crate) fn new(columns: &[[T; 3]; M]) -> Self {
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let mut normals = [[T::zero(); 3]; PAIRS];
        let mut dots = [[T::zero(); M]; PAIRS];
        let mut pairs = [[0; 2]; PAIRS];
        let mut apart = [T::zero(); PAIRS];
        let norms: [T; M] = core::array::from_fn(|k| dot3(&columns[k], &columns[k]));
        let mut f = 0;
        for i in 0..M {
            for j in i + 1..M {
                pairs[f] = [i, j];
                let (a, b) = (&columns[i], &columns[j]);
                let n = cross(a, b);
                let nn = dot3(&n, &n);
                if nn > tau * norms[i] * norms[j] {
                    apart[f] = nn / (norms[i] * norms[j]);
                    let scale = T::one() / nn.sqrt();
                    normals[f] = [n[0] * scale, n[1] * scale, n[2] * scale];
                    for k in 0..M {
                        // the pair's own columns lie in the facet's plane
                        if k != i && k != j {
                            dots[f][k] = dot3(&normals[f], &columns[k]);
                        }
                    }
                }
                f += 1;
            }
        }
        Facets {
            normals,
            dots,
            pairs,
            norms,
            columns: *columns,
            apart,
        }
    }

    /// The torque of `Z` nearest `wanted` (the `Solved` `x` is `τ* − τ_d`), with at most
    /// `budget` working-set changes. When the movable columns (`hi − lo` above `tol`) span only
    /// a plane, `Z` is flat and described by that plane and its edges ([`Facets::flat`]);
    /// `Failed` when they span less.
    pub(crate) fn nearest(
        &self,
        wanted: &[T; 3],
        lo: &[T],
        hi: &[T],
        tol: T,
        budget: u32,
    ) -> Dual<T> {
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let half = T::from_subset(&0.5);
        // h_Z(±n) = ±n·b mid + |n·b| width / 2 over the columns
        let mid: [T; M] = core::array::from_fn(|k| (lo[k] + hi[k]) * half);
        let width: [T; M] = core::array::from_fn(|k| (hi[k] - lo[k]) * half);
        let movable: [bool; M] = core::array::from_fn(|k| hi[k] - lo[k] > tol);
        let mut low = [T::zero(); PAIRS];
        let mut high = [T::zero(); PAIRS];
        let mut centre = [T::zero(); PAIRS];
        let mut solid = false;
        let mut plane = None;
        for f in 0..PAIRS {
            let d = &self.dots[f];
            let (mut c, mut r) = (T::zero(), T::zero());
            for k in 0..M {
                c += d[k] * mid[k];
                r += d[k].abs() * width[k];
            }
            low[f] = c - r;
            high[f] = c + r;
            centre[f] = dot3(&self.normals[f], wanted);
            let [i, j] = self.pairs[f];
            if !solid && movable[i] && movable[j] && self.apart[f] > T::zero() {
                // the plane of the movable pair farthest apart
                if plane.is_none_or(|p: usize| self.apart[f] > self.apart[p]) {
                    plane = Some(f);
                }
                solid = (0..M).any(|k| movable[k] && d[k] * d[k] > tau * self.norms[k]);
            }
        }
        match (solid, plane) {
            (true, _) => dual::solve(&self.normals, &centre, &low, &high, PAIRS, budget),
            (false, Some(f)) => self.flat(wanted, &mid, &width, &movable, f, budget),
            (false, None) => Dual::Failed { changes: 0 },
        }
    }

    /// The torque of a flat `Z` nearest `wanted`: the movable columns lie in the plane of
    /// facet `f`'s normal `p`, so `Z` is the slab `p · τ` within `[−h_Z(−p), h_Z(p)]` (of
    /// rounding's width) cut by the half-spaces of its edges, whose normals in the plane are
    /// `p × b_k` over the movable columns (docs/maths.md, "Control allocation": stage 1 of a
    /// square geometry).
    fn flat(
        &self,
        wanted: &[T; 3],
        mid: &[T; M],
        width: &[T; M],
        movable: &[bool; M],
        f: usize,
        budget: u32,
    ) -> Dual<T> {
        let tau = T::from_subset(&1e3) * T::default_epsilon();
        let p = self.normals[f];
        let mut rows = [[T::zero(); 3]; M + 1];
        rows[0] = p;
        let mut count = 1;
        for k in 0..M {
            let b = &self.columns[k];
            let e = cross(&p, b);
            let ee = dot3(&e, &e);
            if movable[k] && ee > tau * self.norms[k] {
                let scale = T::one() / eqtrack_hw_sqrt::sqrt(ee);
                rows[count] = [e[0] * scale, e[1] * scale, e[2] * scale];
                count += 1;
            }
        }
        let mut low = [T::zero(); M + 1];
        let mut high = [T::zero(); M + 1];
        let mut centre = [T::zero(); M + 1];
        for r in 0..count {
            let (mut c, mut h) = (T::zero(), T::zero());
            for k in 0..M {
                let d = dot3(&rows[r], &self.columns[k]);
                c += d * mid[k];
                h += d.abs() * width[k];
            }
            low[r] = c - h;
            high[r] = c + h;
            centre[r] = dot3(&rows[r], wanted);
        }
        dual::solve(&rows, &centre, &low, &high, count, budget)
    }
}

/// `a × b`.
pub(crate) fn cross<T: RealField + Copy>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
