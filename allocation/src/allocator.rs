//! The prioritised bounded allocation (docs/maths.md, "Control allocation").

use crate::blocks::{self, Blocks, Compact};
use crate::dual;
use crate::geometry::Geometry;
use crate::qp::{MAX_EQ, clamp, tolerance};
use crate::reach::Reach;
use crate::zonotope::Facets;
use crate::{Commands, MAX_ACTUATORS};
use core::fmt;
use nalgebra::{RealField, SMatrix, SVector};

/// Which part of the wrench is met first when not all of it can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Priority {
    /// The torque first, then the force (SE(3)); on SO(3) there is only torque.
    Torque,
    /// The whole wrench as one least-squares problem.
    None,
    /// The tilt first (SE(3)): the roll and pitch torques and the force along the body's
    /// z axis, then the yaw torque and the other forces. On SO(3), as [`Priority::Torque`].
    Tilt,
}

/// The wrench's rows in the order the stages take them: the first three are stage 1's.
const fn row_order(priority: Priority) -> [usize; 6] {
    match priority {
        Priority::Tilt => [0, 1, 5, 2, 3, 4],
        Priority::Torque | Priority::None => [0, 1, 2, 3, 4, 5],
    }
}

/// Stage 1's rows: the torque's three on SE(3) with a priority, else the whole wrench (a
/// wrench split into a torque stage and a force stage when fewer than `K`).
const fn first_rows<const K: usize>(priority: Priority) -> usize {
    if K == 6 && !matches!(priority, Priority::None) {
        3
    } else {
        K
    }
}

/// Block `c` of `geometry` as a problem of its own (docs/maths.md, "Control allocation":
/// geometries in blocks): its rows in the stages' order (`first` of them stage 1's), its
/// actuators in their order with `bounds`, and `demand`'s rows; with each compact actuator's
/// index in the geometry.
fn block_problem<T: RealField + Copy, const K: usize>(
    geometry: &Geometry<T, K>,
    blocks: &Blocks,
    c: usize,
    priority: Priority,
    demand: &SVector<T, K>,
    bounds: &Bounds<T>,
) -> (Compact<T>, [usize; MAX_ACTUATORS]) {
    let b = geometry.effectiveness();
    let order = row_order(if K == 6 { priority } else { Priority::Torque });
    let first = first_rows::<K>(priority);
    let mut p = Compact {
        all: [[T::zero(); MAX_ACTUATORS]; MAX_EQ],
        wanted: [T::zero(); MAX_EQ],
        rows: 0,
        first: 0,
        m: 0,
        lo: Commands::zeros(),
        hi: Commands::zeros(),
    };
    let mut rows = [0; MAX_EQ];
    for (i, &r) in order.iter().take(K).enumerate() {
        if blocks.has_row(c, r) {
            rows[p.rows] = r;
            p.wanted[p.rows] = demand[r];
            p.first += usize::from(i < first);
            p.rows += 1;
        }
    }
    let mut at = [0; MAX_ACTUATORS];
    for j in (0..geometry.count()).filter(|&j| blocks.has_actuator(c, j)) {
        let i = p.m;
        at[i] = j;
        for (x, &r) in rows.iter().take(p.rows).enumerate() {
            p.all[x][i] = b[(r, j)];
        }
        (p.lo[i], p.hi[i]) = (bounds.lo[j], bounds.hi[j]);
        p.m += 1;
    }
    (p, at)
}

/// How an allocation went: an integer code in `trajectory.csv` (`alloc_status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// 0: the demand is met (to the solver's accuracy).
    Met = 0,
    /// 1: the torque cannot be met within the bounds (with [`Priority::None`]: the wrench);
    /// the nearest achievable one is produced.
    TorqueInfeasible = 1,
    /// 2: the torque is met; the force cannot be, and the nearest achievable one (with that
    /// torque) is produced.
    ForceGivenUp = 2,
    /// 3: the budget of iterations ran out before the optimum; the answer is the last
    /// iterate (within the bounds, finite, no stage's objective above its start; a primal
    /// stage that finished keeps its optimum). The dual stages of a square geometry give no
    /// command until both finish: a budget spent in them answers the primal stages' start,
    /// the closed form clamped, or the previous command clamped when one is given. In a
    /// geometry in blocks, each block that finished keeps its optimum, and the one the budget
    /// ran out in its last iterate.
    Stopped = 3,
    /// 4: the demand was not finite; the answer is the preferred command within the bounds.
    InvalidDemand = 4,
}

impl Status {
    /// The integer code.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The status of an integer code (`None`: not a code).
    pub fn from_code(code: u32) -> Option<Status> {
        [
            Status::Met,
            Status::TorqueInfeasible,
            Status::ForceGivenUp,
            Status::Stopped,
            Status::InvalidDemand,
        ]
        .into_iter()
        .find(|s| u32::from(s.code()) == code)
    }
}

/// One allocation's answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Allocation<T, const K: usize> {
    /// The actuator commands `u_cmd` (0 past the geometry's count).
    pub u: Commands<T>,
    /// The wrench they produce, `B u_cmd`.
    pub achieved: SVector<T, K>,
    /// How it went.
    pub status: Status,
    /// Active-set iterations (factorisations of a working set) over all stages.
    pub iterations: u32,
}

/// Why allocator settings are refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AllocatorError {
    /// `weights` or `preferred` does not have one entry per actuator.
    Length {
        /// `weights` or `preferred`.
        what: &'static str,
        /// Its length.
        found: usize,
        /// The actuator count.
        expected: usize,
    },
    /// A weight is not positive and finite, or a preferred command is not finite.
    Value {
        /// `weights` or `preferred`.
        what: &'static str,
        /// The entry (0-based).
        index: usize,
    },
}

impl fmt::Display for AllocatorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AllocatorError::Length {
                what,
                found,
                expected,
            } => write!(
                f,
                "`{what}` has {found} entries; it needs one per actuator ({expected})"
            ),
            AllocatorError::Value { what, index } => write!(
                f,
                "`{what}` entry {index} must be {}",
                if *what == "weights" {
                    "positive and finite"
                } else {
                    "finite"
                }
            ),
        }
    }
}

/// The bounds an allocation respects: the geometry's, narrowed for a rate limit or a failed
/// actuator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds<T> {
    /// The least command of each actuator.
    pub lo: Commands<T>,
    /// The largest command of each actuator.
    pub hi: Commands<T>,
}

impl<T: RealField + Copy> Bounds<T> {
    /// Holds actuator `j` at `value` (a failed actuator, stuck): its bounds become
    /// `[value, value]`.
    pub fn fail(&mut self, j: usize, value: T) {
        if j < MAX_ACTUATORS {
            self.lo[j] = value;
            self.hi[j] = value;
        }
    }

    /// Narrows actuator `j`'s bounds to `[from − step, from + step]` (a rate limit over one
    /// period), keeping them within the present ones.
    pub fn limit_rate(&mut self, j: usize, from: T, step: T) {
        if j < MAX_ACTUATORS {
            let lo = (from - step).max(self.lo[j]).min(self.hi[j]);
            let hi = (from + step).min(self.hi[j]).max(lo);
            self.lo[j] = lo;
            self.hi[j] = hi;
        }
    }
}

/// The allocator: a geometry, the weights `W` and preferred command `u_pref` of the last
/// stage, and the priority.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Allocator<T, const K: usize> {
    geometry: Geometry<T, K>,
    weights: Commands<T>,
    preferred: Commands<T>,
    priority: Priority,
    budget: u32,
    /// `B W⁻¹`, and the Cholesky factor of `B W⁻¹ Bᵀ` (as nalgebra leaves it; `None`: not
    /// positive definite), formed once: the closed form's, the same numbers every call.
    bw: SMatrix<T, K, MAX_ACTUATORS>,
    gram: Option<SMatrix<T, K, K>>,
    /// Whether the wrench fixes the command, so that the last stage has one feasible point
    /// and is not started: as many actuators as wrench rows, and each column far enough from
    /// the others' span that the last stage's first working set would free them all.
    fixed: bool,
    /// `B⁻¹` when `fixed`: stage 2 is then solved in the force (`dual.rs`).
    inverse: Option<SMatrix<T, K, K>>,
    /// Stage 1's reach by its facets when `fixed` with a priority: stage 1 is then solved in
    /// the torque (`zonotope.rs`).
    facets: Option<Facets<T>>,
    /// The blocks of rows and actuators when the geometry falls into more than one (the ROV's
    /// horizontal and vertical thrusters, the spacecraft's couples): each block is then
    /// allocated alone, a block of one row in closed form (`blocks.rs`).
    blocks: Option<Blocks>,
    /// The blocks of three rows and three or four actuators (the ROV's two), each with its
    /// reach, formed once: their stages 1 and 2 by it (`reach.rs`).
    reach: [Option<(usize, Reach<T>)>; 2],
    /// `√ε`, the tolerance of [`Status::Met`].
    sqrt_eps: T,
}

/// The default budget of active-set iterations per allocation: over the seeded demands of
/// every preset and the twelve-thruster spacecraft (docs/vehicles.md, "Bounded time"), none
/// needs more than 10, well within it.
pub const DEFAULT_BUDGET: u32 = 3 * MAX_ACTUATORS as u32;

impl<T: RealField + Copy, const K: usize> Allocator<T, K> {
    /// An allocator over `geometry` with weights `W` (positive; empty: all 1) and preferred
    /// command `u_pref` (empty: 0), one entry per actuator each.
    pub fn new(
        geometry: Geometry<T, K>,
        weights: &[T],
        preferred: &[T],
        priority: Priority,
    ) -> Result<Self, AllocatorError> {
        let m = geometry.count();
        let mut w = Commands::from_element(T::one());
        let mut up = Commands::zeros();
        for (what, given, into) in [
            ("weights", weights, &mut w),
            ("preferred", preferred, &mut up),
        ] {
            if given.is_empty() {
                continue;
            }
            if given.len() != m {
                return Err(AllocatorError::Length {
                    what,
                    found: given.len(),
                    expected: m,
                });
            }
            for (i, x) in given.iter().enumerate() {
                let ok = x.is_finite() && (what != "weights" || *x > T::zero());
                if !ok {
                    return Err(AllocatorError::Value { what, index: i });
                }
                into[i] = *x;
            }
        }
        let top = w.max();
        Ok(Self::formed(
            geometry,
            w / top,
            up,
            priority,
            DEFAULT_BUDGET,
            T::default_epsilon().sqrt(),
        ))
    }

    /// The allocator with its closed form's matrices formed once (weights already scaled to
    /// a largest of 1), and `sqrt_eps`, `√ε` (the first allocator's, copied into those formed
    /// from it).
    fn formed(
        geometry: Geometry<T, K>,
        weights: Commands<T>,
        preferred: Commands<T>,
        priority: Priority,
        budget: u32,
        sqrt_eps: T,
    ) -> Self {
        let b = geometry.effectiveness();
        // B W⁻¹: each column divided by its weight
        let mut bw = *b;
        for (j, mut c) in bw.column_iter_mut().enumerate() {
            c /= weights[j];
        }
        let gram = nalgebra::Cholesky::new(bw * b.transpose()).map(|c| c.unpack_dirty());
        let fixed = gram.is_some() && geometry.count() == K && Self::separated(b);
        let inverse = if fixed {
            b.fixed_columns::<K>(0).into_owned().try_inverse()
        } else {
            None
        };
        let facets = (inverse.is_some() && K == 6 && priority != Priority::None).then(|| {
            let order = row_order(priority);
            Facets::new(&core::array::from_fn(|k| {
                core::array::from_fn(|r| b[(order[r], k)])
            }))
        });
        let blocks = Blocks::of(b, geometry.count());
        let mut reach = [None; 2];
        if let Some(blocks) = &blocks {
            let bounds = Bounds {
                lo: Commands::zeros(),
                hi: Commands::zeros(),
            };
            let found = (0..blocks.count()).filter_map(|c| {
                let (p, _) =
                    block_problem(&geometry, blocks, c, priority, &SVector::zeros(), &bounds);
                Reach::of(&p).map(|r| (c, r))
            });
            for (slot, r) in reach.iter_mut().zip(found) {
                *slot = Some(r);
            }
        }
        Allocator {
            geometry,
            weights,
            preferred,
            priority,
            budget,
            bw,
            gram,
            fixed,
            inverse,
            facets,
            blocks,
            reach,
            sqrt_eps,
        }
    }

    /// Whether each of the first `K` columns of `b` (square) lies farther from the others'
    /// span than the last stage's first working set asks
    /// (docs/maths.md, "Control allocation"): its squared distance `1/|r_j|²` (`r_j` row `j` of `B⁻¹`) above
    /// `4 τ |b_j|²`, `τ = 10³ ε`, a margin of four over the test that working set makes in any
    /// order. Then that working set frees every movable actuator and the last stage has one
    /// feasible point, its start.
    fn separated(b: &SMatrix<T, K, MAX_ACTUATORS>) -> bool {
        let square: SMatrix<T, K, K> = b.fixed_columns::<K>(0).into_owned();
        let Some(inverse) = square.try_inverse() else {
            return false;
        };
        let bound = T::one() / (T::from_subset(&4e3) * T::default_epsilon());
        (0..K).all(|j| {
            let product = inverse.row(j).norm_squared() * square.column(j).norm_squared();
            product.is_finite() && product < bound
        })
    }

    /// The same allocator over the geometry with actuator `j`'s column scaled by `factor`
    /// ([`Geometry::scaled`]): what it allocates when actuator `j` produces only `factor`
    /// of its command. Weights, preferred command, priority and budget stay; the closed
    /// form's matrices are formed again. With every factor 1 it is the allocator itself, bit
    /// for bit.
    pub fn scaled(&self, j: usize, factor: T) -> Self {
        Self::formed(
            self.geometry.scaled(j, factor),
            self.weights,
            self.preferred,
            self.priority,
            self.budget,
            self.sqrt_eps,
        )
    }

    /// Poses this allocator, of the same geometry as `healthy` and otherwise equal to it but
    /// for the fields the weights enter, as `healthy`'s [`Allocator::scaled`] by `factors` in
    /// the actuators' thrust (docs/maths.md, "Control allocation", a weak
    /// actuator's thrust as its variable): over its own geometry, each actuator `j` with
    /// `factors[j] = k ≠ 1` weighted `w_j / k²` and preferring `k u_pref,j`. Allocated within
    /// the bounds scaled by `k`, its command `y` divided by `k` is [`Allocator::scaled`]'s (the
    /// same problem, its variable `y_j = k u_j`). Only `B W⁻¹`'s column `j` and the Cholesky
    /// factor of `B W⁻¹ Bᵀ` change: the factor by a rank-one update per actuator,
    /// `(k² − 1)/w_j · b_j b_jᵀ`, and formed again only if an update leaves a diagonal entry
    /// that is not finite and positive. With every factor 1 it is `healthy` again, bit for
    /// bit. Factors must be finite and positive, and `w_j / k²` finite.
    pub(crate) fn pose_in_thrust(&mut self, healthy: &Self, factors: &Commands<T>) {
        // what the weights enter, from the healthy allocator (the rest is its already)
        self.weights = healthy.weights;
        self.preferred = healthy.preferred;
        self.bw = healthy.bw;
        let b = self.geometry.effectiveness();
        if (0..self.geometry.count()).all(|j| factors[j] == T::one()) {
            self.gram = healthy.gram;
            return;
        }
        let mut chol = healthy.gram;
        for j in 0..self.geometry.count() {
            let k = factors[j];
            if k == T::one() {
                continue;
            }
            let w = weigh(
                healthy.weights[j],
                j,
                k,
                &mut self.weights,
                &mut self.preferred,
            );
            self.bw.set_column(j, &(b.column(j) / w));
            if let Some(l) = chol.as_mut() {
                rank_one_update(
                    l,
                    &b.column(j).into_owned(),
                    (k * k - T::one()) / healthy.weights[j],
                );
            }
        }
        self.put_gram(&chol);
    }

    /// The factor of `B W⁻¹ Bᵀ` its updates gave, in force, or that matrix's factor formed
    /// again where an update left a diagonal entry that is not finite and positive (or none
    /// was formed).
    #[inline(always)]
    fn put_gram(&mut self, l: &Option<SMatrix<T, K, K>>) {
        // (read in place: a copy of the factor to test it costs a Cortex-M4F more than the test)
        let mut sound = l.is_some();
        if let Some(l) = l {
            for i in 0..K {
                let d = l[(i, i)];
                if !(d.is_finite() && d > T::zero()) {
                    sound = false;
                    break;
                }
            }
        }
        if sound {
            self.gram = *l;
        } else {
            let b = self.geometry.effectiveness();
            self.gram = nalgebra::Cholesky::new(self.bw * b.transpose()).map(|c| c.unpack_dirty());
        }
    }

    /// [`Allocator::pose_in_thrust`] of this healthy allocator for `factors` begun, to be
    /// made over a few cycles (docs/maths.md, "Failure detection", *A weak actuator told over
    /// cycles*): the fields the weights enter copied, their updates to come
    /// ([`Allocator::advance`]); `actuator` the one whose tell asked for it.
    pub(crate) fn reweighting(&self, factors: &Commands<T>, actuator: usize) -> Reweighting<T, K> {
        let mut r = Reweighting {
            factors: *factors,
            actuator,
            weak: (0..self.geometry.count()).any(|j| factors[j] != T::one()),
            weights: self.weights,
            preferred: self.preferred,
            column: self.bw.column(actuator).into_owned(),
            gram: self.gram,
            weighed: false,
            next: 0,
            update: 0,
            x: SVector::zeros(),
            beta: T::one(),
            sigma: T::zero(),
        };
        self.seek(&mut r, 0);
        r
    }

    /// `r`'s next rank-one update: that of the first weak actuator from `from` on (`next`
    /// the count where there is none, or no factor to update).
    fn seek(&self, r: &mut Reweighting<T, K>, from: usize) {
        let count = self.geometry.count();
        let mut next = count;
        if r.gram.is_some() {
            for j in from..count {
                if r.factors[j] != T::one() {
                    next = j;
                    break;
                }
            }
        }
        r.next = next;
        if next < count {
            let k = r.factors[next];
            r.update = 0;
            r.x = self.geometry.effectiveness().column(next).into_owned();
            r.beta = T::one();
            r.sigma = (k * k - T::one()) / self.weights[next];
        }
    }

    /// One step of `r` (of this healthy allocator): up to `columns` more columns of its
    /// rank-one updates ([`rank_one_column`]), one weak actuator after another in the
    /// actuators' order, as [`Allocator::pose_in_thrust`] makes them; once they are all
    /// made, the weights, preferred command and `B W⁻¹` of its weak actuators, in a step of
    /// their own. True when nothing is left.
    pub(crate) fn advance(&self, r: &mut Reweighting<T, K>, columns: usize) -> bool {
        let count = self.geometry.count();
        if r.done(count) {
            return true;
        }
        if r.next < count {
            let mut left = columns;
            while r.next < count && left > 0 {
                let Some(l) = r.gram.as_mut() else {
                    break;
                };
                rank_one_column(l, &mut r.x, &mut r.beta, r.sigma, r.update);
                r.update += 1;
                left -= 1;
                if r.update == K {
                    self.seek(r, r.next + 1);
                }
            }
            return false;
        }
        if !r.weighed {
            r.weighed = true;
            for j in 0..count {
                let k = r.factors[j];
                if k != T::one() {
                    let w = weigh(self.weights[j], j, k, &mut r.weights, &mut r.preferred);
                    // (the actuator's column of `B W⁻¹` only: the others are in force already;
                    // at factor 1 it stays the healthy one, copied when it began)
                    if j == r.actuator {
                        r.column = self.geometry.effectiveness().column(j) / w;
                    }
                }
            }
        }
        false
    }

    /// This allocator, of `healthy`'s geometry, posed as `r` says, its steps made (those left
    /// are made first): what [`Allocator::pose_in_thrust`] of `r`'s factors gives, bit for
    /// bit, where this allocator is posed for `r`'s factors but its actuator's (its other
    /// columns of `B W⁻¹` are then those already).
    pub(crate) fn put(&mut self, healthy: &Self, r: &mut Reweighting<T, K>) {
        while !r.done(healthy.geometry.count()) {
            healthy.advance(r, usize::MAX);
        }
        self.weights = r.weights;
        self.preferred = r.preferred;
        self.bw.set_column(r.actuator, &r.column);
        if r.weak {
            self.put_gram(&r.gram);
        } else {
            self.gram = r.gram;
        }
    }

    /// The same allocator with at most `budget` active-set iterations per allocation, over
    /// all stages, spent on the torque stage first (default [`DEFAULT_BUDGET`]). An
    /// allocation that spends it answers [`Status::Stopped`] with its last iterate.
    pub fn with_budget(mut self, budget: u32) -> Self {
        self.budget = budget.max(1);
        self
    }

    /// The budget of active-set iterations per allocation.
    pub fn budget(&self) -> u32 {
        self.budget
    }

    /// The last stage's preferred command `u_pref` (0 past the count).
    pub fn preferred(&self) -> &Commands<T> {
        &self.preferred
    }

    /// Sets the last stage's preferred command `u_pref` for the allocations that follow (a
    /// momentum manager's, every cycle: docs/maths.md, "Momentum management"); an entry that
    /// is not finite, or past the count, is 0.
    pub fn set_preferred(&mut self, preferred: &Commands<T>) {
        for j in 0..MAX_ACTUATORS {
            let x = preferred[j];
            self.preferred[j] = if j < self.geometry.count() && x.is_finite() {
                x
            } else {
                T::zero()
            };
        }
    }

    /// The geometry.
    pub fn geometry(&self) -> &Geometry<T, K> {
        &self.geometry
    }

    /// The geometry's bounds, to narrow for a failure or a rate limit.
    pub fn bounds(&self) -> Bounds<T> {
        let (lo, hi) = self.geometry.bounds();
        Bounds { lo, hi }
    }

    /// Allocates `demand` (torque, then force on SE(3)) within the geometry's bounds.
    pub fn allocate(&self, demand: &SVector<T, K>) -> Allocation<T, K> {
        self.allocate_within(demand, &self.bounds())
    }

    /// Allocates `demand` within `bounds`, solved cold (docs/maths.md, "Control allocation"):
    /// see [`Allocator::allocate_from`].
    pub fn allocate_within(&self, demand: &SVector<T, K>, bounds: &Bounds<T>) -> Allocation<T, K> {
        self.allocate_from(demand, bounds, None)
    }

    /// Allocates `demand` within `bounds` (docs/maths.md, "Control allocation"): stage 1 the
    /// torque (or with [`Priority::None`], or on SO(3), the whole wrench), stage 2 the force
    /// keeping the torque achieved, stage 3 the command nearest `u_pref` in the `W`-norm
    /// keeping the wrench achieved. With `previous` (the last cycle's command, which the
    /// caller keeps), stage 1 starts from it, clamped into `bounds`, and its working set from
    /// the actuators it held at a bound (a warm start: the same optimum, usually in fewer
    /// iterations, where the primal stages run; a square geometry's dual stages and a block
    /// solved by its reach take no start). Allocation-free; never NaN.
    pub fn allocate_from(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        previous: Option<&Commands<T>>,
    ) -> Allocation<T, K> {
        self.stages(demand, bounds, previous, 3)
    }

    /// Stage 1 alone (the torque, or the whole wrench), from `previous` as
    /// [`Allocator::allocate_from`] starts: what a peer solver is timed against on the same
    /// problem (`allocation/examples/peer.rs`). Its command is one of stage 1's optima, not
    /// the allocation's answer.
    #[doc(hidden)]
    pub fn allocate_first_stage(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        previous: Option<&Commands<T>>,
    ) -> Allocation<T, K> {
        self.stages(demand, bounds, previous, 1)
    }

    /// Stages 1 and 2 alone (research: the iterations of each stage).
    #[doc(hidden)]
    pub fn allocate_two_stages(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
    ) -> Allocation<T, K> {
        self.stages(demand, bounds, None, 2)
    }

    /// The stages up to `through` (1 to 3).
    fn stages(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        previous: Option<&Commands<T>>,
        through: usize,
    ) -> Allocation<T, K> {
        let up = self.clamped(&self.preferred, bounds);
        if !demand.iter().all(|x| x.is_finite()) {
            return self.answer(up, Status::InvalidDemand, 0);
        }
        let split = first_rows::<K>(self.priority) < K;
        let (start, inside) = self.start(demand, &up, bounds);
        if inside {
            // the command nearest u_pref producing the whole demand lies within the bounds:
            // it is every stage's optimum (docs/maths.md, "Control allocation")
            return self.answer(start, Status::Met, 0);
        }
        let start = match previous {
            Some(p) if p.iter().all(|x| x.is_finite()) => self.clamped(p, bounds),
            _ => start,
        };
        // stages 1 and 2 of a square geometry in the torque and the force, by the dual method;
        // where rounding defeats it or the budget runs out, the primal stages with what is
        // left of the budget
        let (square, changes) = if split && through >= 2 && (self.blocks.is_none() || through < 3) {
            self.square_stages(demand, bounds)
        } else {
            (None, 0)
        };
        let (u, spent, stopped) = match (square, &self.blocks) {
            (Some(u), _) => (u, changes, false),
            // a geometry in blocks: each alone (stages 1 and 2 asked alone keep the whole
            // geometry's active set, whose stage-1 command is one of many optima)
            (None, Some(blocks)) if through == 3 => {
                self.by_blocks(blocks, demand, bounds, &up, &start)
            }
            (None, _) => self.active_set(demand, bounds, &up, start, changes, through),
        };
        let u = self.clamped(&u, bounds);
        if !u.iter().all(|x| x.is_finite()) {
            return self.answer(up, Status::Stopped, spent);
        }
        let status = if stopped {
            Status::Stopped
        } else {
            self.met(&u, demand, split)
        };
        self.answer(u, status, spent)
    }

    /// The active-set stages from `start` (docs/maths.md, "Control allocation"), through
    /// stage `through`, within one budget: the command, the iterations spent, and whether
    /// the budget ran out.
    fn active_set(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        up: &Commands<T>,
        start: Commands<T>,
        spent: u32,
        through: usize,
    ) -> (Commands<T>, u32, bool) {
        let m = self.geometry.count();
        let b = self.geometry.effectiveness();
        let order = self.order();
        let mut p = Compact {
            all: [[T::zero(); MAX_ACTUATORS]; MAX_EQ],
            wanted: [T::zero(); MAX_EQ],
            rows: K,
            first: first_rows::<K>(self.priority),
            m,
            lo: bounds.lo,
            hi: bounds.hi,
        };
        for r in 0..K {
            for j in 0..m {
                p.all[r][j] = b[(order[r], j)];
            }
            p.wanted[r] = demand[order[r]];
        }
        let mut f = [T::zero(); MAX_EQ];
        f[..3].copy_from_slice(&p.wanted[3..6]);
        // stage 2: with `B` square and well separated, in the force by the dual method
        // (dual.rs), the primal method if rounding defeats it
        let force = |u: &Commands<T>, budget: u32| {
            let inv = self.inverse.as_ref()?;
            let torque: [T; 3] =
                core::array::from_fn(|a| (0..m).fold(T::zero(), |s, j| s + p.all[a][j] * u[j]));
            Some(Self::force_by_dual(
                inv, &torque, &f, &order, bounds, m, budget,
            ))
        };
        // stage 3: when the wrench fixes the command (`fixed`: as many actuators as wrench
        // rows, the columns well apart, as the six-rotor hexarotor's), it has one feasible
        // point, its start, and is skipped without forming its first working set
        blocks::primal(
            &p,
            &self.weights,
            up,
            start,
            self.budget,
            spent,
            (1, through),
            !self.fixed,
            force,
        )
    }

    /// Every stage of a geometry in blocks, block by block
    /// (docs/maths.md, "Control allocation": geometries in blocks): a block of one row in closed
    /// form, a larger one by [`Allocator::block`], from `start`, within one budget.
    fn by_blocks(
        &self,
        blocks: &Blocks,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
        up: &Commands<T>,
        start: &Commands<T>,
    ) -> (Commands<T>, u32, bool) {
        // an actuator in no block: at u_pref
        let mut u = *up;
        let (mut spent, mut stopped) = (0, false);
        for c in 0..blocks.count() {
            let (p, at) = block_problem(&self.geometry, blocks, c, self.priority, demand, bounds);
            let (mut w, mut pref, mut from) =
                (Commands::zeros(), Commands::zeros(), Commands::zeros());
            for (i, &j) in at.iter().take(p.m).enumerate() {
                (w[i], pref[i], from[i]) = (self.weights[j], up[j], start[j]);
            }
            let v = if p.rows == 1 {
                blocks::one_row(&p, &w, &pref)
            } else {
                let reach = self
                    .reach
                    .iter()
                    .flatten()
                    .find(|(b, _)| *b == c)
                    .map(|(_, r)| r);
                let (v, s, st) = self.block(&p, reach, &w, &pref, from, spent);
                (spent, stopped) = (s, stopped | st);
                v
            };
            for (i, &j) in at.iter().take(p.m).enumerate() {
                u[j] = v[i];
            }
        }
        (u, spent, stopped)
    }

    /// A block of several rows (docs/maths.md, "Control allocation": geometries in blocks): of
    /// three rows and three or four actuators, by its `reach` (reach.rs) when it answers
    /// (docs/maths.md, "Control allocation": a block of three rows by its reach); otherwise
    /// stage 1 of one row in closed form, the command nearest the start with the row's value
    /// clamped into its reach (one of stage 1's optima; stage 2 starts from it), else by the
    /// primal stage; stage 2 by the primal stage; stage 3 on a line (a one-dimensional null
    /// space) in closed form, else by the primal stage. From `from` with `spent` of the budget
    /// spent: the command, the iterations spent in all and whether the budget ran out.
    #[allow(clippy::too_many_arguments)]
    fn block(
        &self,
        p: &Compact<T>,
        reach: Option<&Reach<T>>,
        w: &Commands<T>,
        pref: &Commands<T>,
        mut from: Commands<T>,
        mut spent: u32,
    ) -> (Commands<T>, u32, bool) {
        // three rows and three or four actuators: stages 1 and 2 by the block's reach, stage
        // 3 on the line through the wrench they reach (reach.rs)
        if let Some(reach) = reach {
            match reach.stages(p, self.budget - spent) {
                dual::Dual::Solved { x, changes } => {
                    spent += changes;
                    if let Some(v) = reach.last(p, w, pref, &x) {
                        return (v, spent, false);
                    }
                }
                dual::Dual::Failed { changes } => {
                    spent += changes;
                    // two of its actuators move: every stage in closed form
                    if let Some(v) = reach.two(p, w, pref) {
                        return (v, spent, false);
                    }
                }
                dual::Dual::Stopped { changes } => spent += changes,
            }
        }
        let first = if p.first == 1 {
            from = blocks::one_row(p, &Commands::from_element(T::one()), &from);
            2
        } else {
            1
        };
        let none = |_: &Commands<T>, _| None;
        let (v, spent, stopped) = blocks::primal(
            p,
            w,
            pref,
            from,
            self.budget,
            spent,
            (first, 2),
            false,
            none,
        );
        match blocks::on_a_line(p, w, pref, &v) {
            Some(v) if !stopped => (v, spent, false),
            _ => {
                let (v, spent, last) =
                    blocks::primal(p, w, pref, v, self.budget, spent, (3, 3), true, none);
                (v, spent, stopped | last)
            }
        }
    }

    /// The wrench's rows in the stages' order (the torque's first with three rotations).
    fn order(&self) -> [usize; 6] {
        row_order(if K == 6 {
            self.priority
        } else {
            Priority::Torque
        })
    }

    /// Stages 1 and 2 of a square, well-separated geometry by the dual method
    /// (docs/maths.md, "Control allocation": stages 1 and 2 of a square geometry): the torque
    /// of the reach nearest the demand's (zonotope.rs), then the force (dual.rs). Returns the
    /// command (`None`: not such a geometry, rounding defeated the method or the budget ran
    /// out) and the working-set changes spent.
    fn square_stages(
        &self,
        demand: &SVector<T, K>,
        bounds: &Bounds<T>,
    ) -> (Option<Commands<T>>, u32) {
        let (Some(facets), Some(inv)) = (&self.facets, &self.inverse) else {
            return (None, 0);
        };
        let order = &row_order(self.priority);
        let wanted: [T; MAX_EQ] = core::array::from_fn(|r| demand[order[r]]);
        let m = self.geometry.count();
        let tol = tolerance(bounds.lo.as_slice(), bounds.hi.as_slice(), m);
        let (lo, hi) = (bounds.lo.as_slice(), bounds.hi.as_slice());
        let mut torque = [wanted[0], wanted[1], wanted[2]];
        match facets.nearest(&torque, lo, hi, tol, self.budget) {
            dual::Dual::Solved { x, changes } => {
                for a in 0..3 {
                    torque[a] += x[a];
                }
                // a demand near the scalar's largest can overflow the offsets: the primal
                // stages then answer (the clamps would turn a NaN into a bound unseen)
                if !torque.iter().all(|t| t.is_finite()) {
                    return (None, changes);
                }
                let mut f = [T::zero(); MAX_EQ];
                f[..3].copy_from_slice(&wanted[3..6]);
                let (answer, more, _) =
                    Self::force_by_dual(inv, &torque, &f, order, bounds, m, self.budget - changes);
                let answer = answer.filter(|u| u.iter().all(|x| x.is_finite()));
                (answer, changes + more)
            }
            dual::Dual::Stopped { changes } | dual::Dual::Failed { changes } => (None, changes),
        }
    }

    /// Stage 2 in the force by the dual method (dual.rs; docs/maths.md, "Control allocation":
    /// stage 2 of a square geometry): `u = P τ* + S (f_d + x)`, `P` and `S` the columns of
    /// `B⁻¹` of the stages' rows, `τ*` stage 1's torque. Returns the command (`None`: rounding
    /// defeated the method, or the budget ran out), the changes spent, and whether the budget
    /// ran out.
    fn force_by_dual(
        inv: &SMatrix<T, K, K>,
        torque: &[T; 3],
        f: &[T; MAX_EQ],
        order: &[usize; 6],
        bounds: &Bounds<T>,
        m: usize,
        budget: u32,
    ) -> (Option<Commands<T>>, u32, bool) {
        let mut s_rows = [[T::zero(); 3]; MAX_ACTUATORS];
        let mut c = [T::zero(); MAX_ACTUATORS];
        for j in 0..m {
            let mut cj = T::zero();
            for a in 0..3 {
                s_rows[j][a] = inv[(j, order[3 + a])];
                cj += inv[(j, order[a])] * torque[a] + s_rows[j][a] * f[a];
            }
            c[j] = cj;
        }
        match dual::solve(
            &s_rows,
            &c,
            bounds.lo.as_slice(),
            bounds.hi.as_slice(),
            m,
            budget,
        ) {
            dual::Dual::Solved { x, changes } => {
                let mut answer = Commands::zeros();
                for j in 0..m {
                    answer[j] =
                        c[j] + s_rows[j][0] * x[0] + s_rows[j][1] * x[1] + s_rows[j][2] * x[2];
                }
                (Some(answer), changes, false)
            }
            dual::Dual::Stopped { changes } => (None, changes, true),
            dual::Dual::Failed { changes } => (None, changes, false),
        }
    }

    /// Where stage 1 starts: the command nearest `u_pref` in the `W`-norm that produces the
    /// whole demand, `u_pref + W⁻¹Bᵀ(BW⁻¹Bᵀ)⁻¹(w − B u_pref)`, clamped into the bounds, and
    /// whether it was inside them already. Inside, it meets stages 1 and 2 exactly and is
    /// stage 3's unconstrained optimum, so it is every stage's answer. (Any point of the box
    /// is a valid start.)
    fn start(
        &self,
        demand: &SVector<T, K>,
        up: &Commands<T>,
        bounds: &Bounds<T>,
    ) -> (Commands<T>, bool) {
        let b = self.geometry.effectiveness();
        let Some(l) = &self.gram else {
            return (*up, false);
        };
        // the Cholesky solve, as nalgebra's `Cholesky::solve` does it
        let mut x = demand - b * up;
        l.solve_lower_triangular_unchecked_mut(&mut x);
        l.ad_solve_lower_triangular_unchecked_mut(&mut x);
        let u = up + self.bw.transpose() * x;
        let inside = u
            .iter()
            .zip(bounds.lo.iter().zip(bounds.hi.iter()))
            .all(|(x, (l, h))| x.is_finite() && *x >= *l && *x <= *h);
        (self.clamped(&u, bounds), inside)
    }

    /// `x` clamped into `bounds` on the geometry's actuators, 0 past them (where the
    /// geometry's bounds are 0).
    fn clamped(&self, x: &Commands<T>, bounds: &Bounds<T>) -> Commands<T> {
        let mut u = Commands::zeros();
        for j in 0..self.geometry.count() {
            u[j] = clamp(x[j], bounds.lo[j], bounds.hi[j]);
        }
        u
    }

    /// Whether `u` meets the demand: the torque (or wrench), then the force.
    fn met(&self, u: &Commands<T>, demand: &SVector<T, K>, split: bool) -> Status {
        let miss = self.geometry.wrench(u) - demand;
        let tol = self.sqrt_eps * (T::one() + demand.amax());
        let order = self.order();
        let part = |r: core::ops::Range<usize>| r.into_iter().any(|i| miss[order[i]].abs() > tol);
        if part(0..if split { 3 } else { K }) {
            Status::TorqueInfeasible
        } else if split && part(3..6) {
            Status::ForceGivenUp
        } else {
            Status::Met
        }
    }

    fn answer(&self, u: Commands<T>, status: Status, iterations: u32) -> Allocation<T, K> {
        Allocation {
            u,
            achieved: self.geometry.wrench(&u),
            status,
            iterations,
        }
    }
}

/// The Cholesky factor `l` (lower triangle; the upper is not read) of `A` updated in place to
/// that of `A + σ x xᵀ` (docs/maths.md, "Control allocation", *A weak actuator's thrust as its
/// variable*): the recurrence of nalgebra's `Cholesky::rank_one_update` (Eigen's
/// `llt_rank_update_lower`), column by column with the running `β`, each operation in its
/// order, so the same bits, but with [`eqtrack_hw_sqrt::sqrt`]: the FPU's square root on a
/// Cortex-M4F, five instructions where libm's takes fifty (the test
/// `the_rank_one_update_is_nalgebras` holds it to nalgebra's, bit for bit).
fn rank_one_update<T: RealField + Copy + 'static, const K: usize>(
    l: &mut SMatrix<T, K, K>,
    x: &SVector<T, K>,
    sigma: T,
) {
    let (mut x, mut beta) = (*x, T::one());
    for j in 0..K {
        rank_one_column(l, &mut x, &mut beta, sigma, j);
    }
}

/// Actuator `j`'s weight and preferred command when it gives `k` of its command, its thrust
/// the variable (docs/maths.md, "Control allocation", *A weak actuator's thrust as its
/// variable*): `w_j / k²` and `k u_pref,j`, from its healthy weight `w` and the healthy
/// preferred command already in `preferred`; the weight, whose column of `B W⁻¹` is
/// `b_j / (w_j / k²)`.
#[inline(always)]
fn weigh<T: RealField + Copy>(
    w: T,
    j: usize,
    k: T,
    weights: &mut Commands<T>,
    preferred: &mut Commands<T>,
) -> T {
    let w = w / (k * k);
    weights[j] = w;
    preferred[j] *= k;
    w
}

/// Column `j` of [`rank_one_update`], its running `x` and `β` (1 at the start) carried from
/// column to column: a weak actuator's update made a few columns a cycle
/// ([`Allocator::advance`]), the same operations in the same order.
#[inline(always)]
fn rank_one_column<T: RealField + Copy + 'static, const K: usize>(
    l: &mut SMatrix<T, K, K>,
    x: &mut SVector<T, K>,
    beta: &mut T,
    sigma: T,
    j: usize,
) {
    let diag = l[(j, j)];
    let diag2 = diag * diag;
    let xj = x[j];
    let sigma_xj2 = sigma * (xj * xj);
    let gamma = diag2 * *beta + sigma_xj2;
    let new_diag = eqtrack_hw_sqrt::sqrt(diag2 + sigma_xj2 / *beta);
    l[(j, j)] = new_diag;
    *beta += sigma_xj2 / diag2;
    // x below j less (x_j / l_jj) times the column; then the column, as nalgebra's axpy
    // forms it (`a x + b y`, or `a x` alone when `b` is zero)
    let a = -xj / diag;
    for i in j + 1..K {
        x[i] = a * l[(i, j)] + x[i];
    }
    if gamma != T::zero() {
        let a = new_diag * sigma / gamma * xj;
        let b = new_diag / diag;
        for i in j + 1..K {
            l[(i, j)] = if b != T::zero() {
                a * x[i] + b * l[(i, j)]
            } else {
                a * x[i]
            };
        }
    }
}

/// A reweighting of an allocator for a loss of effectiveness, made a few steps at a time
/// (docs/maths.md, "Failure detection", *A weak actuator told over cycles*): what
/// [`crate::VehicleControl::weaken`] does at once, for a cycle that must stay short (a failure
/// detector's). Begun by [`crate::VehicleControl::reweighting`], stepped by
/// [`crate::VehicleControl::advance`] and put in force by [`crate::VehicleControl::reweight`],
/// which leaves the vehicle as `weaken` would, bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reweighting<T, const K: usize> {
    /// The factors it poses the allocator for, whether any is not 1, and the actuator whose
    /// tell began it.
    factors: Commands<T>,
    weak: bool,
    actuator: usize,
    /// The fields the weights enter, the healthy allocator's until `weighed`: the weights, the
    /// preferred command and the actuator's column of `B W⁻¹` (the others do not change);
    /// and the factor of `B W⁻¹ Bᵀ` as far as its updates are made.
    weights: Commands<T>,
    preferred: Commands<T>,
    column: SVector<T, K>,
    gram: Option<SMatrix<T, K, K>>,
    weighed: bool,
    /// The weak actuator whose update runs (the count once all are made), the update's next
    /// column, and its running vector, `β` and `σ` ([`rank_one_column`]).
    next: usize,
    update: usize,
    x: SVector<T, K>,
    beta: T,
    sigma: T,
}

impl<T: RealField + Copy, const K: usize> Reweighting<T, K> {
    /// The factors it poses the allocator for.
    pub(crate) fn factors(&self) -> &Commands<T> {
        &self.factors
    }

    /// Whether nothing is left to make of it, for a geometry of `count` actuators: its
    /// updates and its weights.
    #[inline(always)]
    fn done(&self, count: usize) -> bool {
        self.next >= count && self.weighed
    }

    /// Whether a factor it poses the allocator for is not 1 (formed when it begins, so
    /// that putting it in force does not look through the factors again).
    pub(crate) fn weak(&self) -> bool {
        self.weak
    }

    /// The actuator whose tell began it, and the factor told.
    pub fn tell(&self) -> (usize, T) {
        // (begun only for an actuator of the vehicle: `VehicleControl::reweighting`)
        (self.actuator, self.factors[self.actuator])
    }
}

#[cfg(test)]
mod tests {
    use super::{Allocator, Priority};
    use crate::{Commands, Geometry, presets};
    use proptest::prelude::*;

    fn hexarotor<T: nalgebra::RealField + Copy>(tilt: f64) -> Allocator<T, 6> {
        let g = Geometry::<T, 6>::new(&presets::hexarotor(
            nalgebra::convert(0.25),
            nalgebra::convert(tilt),
            nalgebra::convert(0.016),
            nalgebra::convert(8.0),
        ))
        .unwrap();
        Allocator::new(g, &[], &[], Priority::Torque).unwrap()
    }

    /// The last stage is skipped where the wrench fixes the command with columns well apart
    /// (the tilted hexarotor), and started where a column is nearly in the others' span (a
    /// hexarotor tilted by 3 mrad in f32, which the geometry accepts) or the actuators
    /// outnumber the rows.
    #[test]
    fn the_last_stage_is_skipped_only_where_it_has_one_point() {
        assert!(hexarotor::<f32>(0.5).fixed);
        assert!(hexarotor::<f64>(0.5).fixed);
        assert!(!hexarotor::<f32>(0.003).fixed);
        let rov = Geometry::<f32, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
        assert!(
            !Allocator::new(rov, &[], &[], Priority::Torque)
                .unwrap()
                .fixed
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// The tilted hexarotor's stages 1 and 2 by the dual method
        /// (docs/maths.md, "Control allocation": stage 1 of a square geometry) answer what the
        /// primal stages answer, to 1e-9 of the largest bound, and take that path on every
        /// demand past the closed form: no rotor held, one, or two (opposite ones leave the
        /// torques' reach flat); with the torque first, or the tilt (stage 1 then the roll and
        /// pitch torques and the thrust along z).
        #[test]
        fn the_dual_stages_answer_what_the_primal_stages_answer(
            us in proptest::collection::vec(0.0f64..=1.0, 6),
            scale in 0.5f64..4.0,
            held in proptest::option::of((0usize..6, 0.0f64..=1.0)),
            second in proptest::option::of((1usize..6, 0.0f64..=1.0)),
            tilt in proptest::bool::ANY,
        ) {
            let mut dual = hexarotor::<f64>(0.5);
            if tilt {
                let priority = Priority::Tilt;
                dual = Allocator::new(*dual.geometry(), &[], &[], priority).unwrap();
            }
            let mut primal = dual;
            (primal.fixed, primal.inverse, primal.facets) = (false, None, None);
            let mut u = Commands::<f64>::zeros();
            for j in 0..6 {
                u[j] = 8.0 * us[j];
            }
            let demand = dual.geometry().wrench(&u) * scale;
            let mut bounds = dual.bounds();
            if let Some((j, at)) = held {
                bounds.fail(j, 8.0 * at);
                if let Some((k, at)) = second {
                    bounds.fail((j + k) % 6, 8.0 * at);
                }
            }
            let (a, b) = (dual.allocate_within(&demand, &bounds), primal.allocate_within(&demand, &bounds));
            prop_assert!((a.u - b.u).amax() <= 1e-9 * 9.0, "{:?} against {:?}", a, b);
            prop_assert_eq!(a.status, b.status);
            if b.iterations > 0 {
                prop_assert!(dual.square_stages(&demand, &bounds).0.is_some(), "{:?}", bounds);
            }
        }

        /// Skipping the last stage changes no bit: the tilted hexarotor's allocations of
        /// demands within reach and up to four times past it, with a rotor failed or not,
        /// equal those that run the last stage, in f32.
        #[test]
        fn skipping_the_last_stage_changes_no_bit(
            us in proptest::collection::vec(0.0f32..=1.0, 6),
            scale in 0.5f32..4.0,
            failed in proptest::option::of((0usize..6, 0.0f32..=1.0)),
        ) {
            let skip = hexarotor::<f32>(0.5);
            let mut run = skip;
            run.fixed = false;
            let mut u = Commands::<f32>::zeros();
            for j in 0..6 {
                u[j] = 8.0 * us[j];
            }
            let demand = skip.geometry().wrench(&u) * scale;
            let mut bounds = skip.bounds();
            if let Some((j, at)) = failed {
                bounds.fail(j, 8.0 * at);
            }
            let (a, b) = (skip.allocate_within(&demand, &bounds), run.allocate_within(&demand, &bounds));
            prop_assert_eq!(a.u.map(f32::to_bits), b.u.map(f32::to_bits));
            prop_assert_eq!(a.status, b.status);
            prop_assert_eq!(a.iterations, b.iterations);
        }
    }

    /// The presets' blocks: the ROV's vertical thrusters move `τx, τy, fz` and its horizontal
    /// ones `τz, fx, fy`; the spacecraft's couples one body axis each; the hexarotor is one
    /// block (nothing falls apart, and the blocks are not formed).
    #[test]
    fn the_presets_fall_into_their_blocks() {
        let rov = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
        let blocks = Allocator::new(rov, &[], &[], Priority::Torque)
            .unwrap()
            .blocks
            .unwrap();
        assert_eq!(blocks.count(), 2);
        let c = |r: usize| (0..2).find(|&c| blocks.has_row(c, r)).unwrap();
        assert!(c(0) == c(1) && c(1) == c(5) && c(2) == c(3) && c(3) == c(4) && c(0) != c(2));
        for j in 0..8 {
            assert!(
                blocks.has_actuator(if j < 4 { c(2) } else { c(0) }, j),
                "thruster {j}"
            );
        }
        let sc = Geometry::<f64, 3>::new(&presets::spacecraft_twelve(0.9, 1.5)).unwrap();
        let blocks = Allocator::new(sc, &[], &[], Priority::Torque)
            .unwrap()
            .blocks
            .unwrap();
        assert_eq!(blocks.count(), 3);
        assert!(hexarotor::<f64>(0.5).blocks.is_none());
    }

    /// The ROV's two blocks are answered by their reach, not by the primal stages they fall
    /// back to (docs/maths.md, "Control allocation": a block of three rows by its reach): on
    /// seeded demands within reach and far past it, with none, one and two thrusters of a
    /// block held, under both priorities, every block's stages answer (`Reach::stages` then
    /// `Reach::last`, or `Reach::two` with two of its thrusters held), and the command is the
    /// primal stages' to 1e-9 of the largest bound.
    #[test]
    fn the_rovs_blocks_are_answered_by_their_reach() {
        use crate::blocks::{Compact, primal};
        use crate::dual::Dual;
        use rand_chacha::ChaCha8Rng;
        use rand_chacha::rand_core::{Rng, SeedableRng};
        let mut rng = ChaCha8Rng::seed_from_u64(47);
        let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
        let rov = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
        let none = |_: &Commands<f64>, _| None;
        let mut by_two = 0;
        for priority in [Priority::Torque, Priority::None] {
            let alloc = Allocator::new(rov, &[], &[], priority).unwrap();
            let blocks = alloc.blocks.unwrap();
            for k in 0..600 {
                let size = [5.0, 50.0, 500.0][k % 3];
                let d = nalgebra::SVector::<f64, 6>::from_fn(|_, _| size * x());
                let mut bounds = alloc.bounds();
                // none, one or two held, the two in one block (4 and 5, or 1 and 2)
                match k % 4 {
                    1 => bounds.fail(k % 8, 40.0 * x()),
                    2 => {
                        bounds.fail(4 + k % 2, 40.0 * x());
                        bounds.fail(5 + k % 2, 40.0 * x());
                    }
                    3 => {
                        bounds.fail(1, 40.0 * x());
                        bounds.fail(2, 40.0 * x());
                    }
                    _ => {}
                }
                for c in 0..2 {
                    let (p, _): (Compact<f64>, _) =
                        super::block_problem(&alloc.geometry, &blocks, c, priority, &d, &bounds);
                    let (w, up) = (Commands::from_element(1.0), Commands::zeros());
                    let reach = alloc.reach.iter().flatten().find(|(b, _)| *b == c).unwrap();
                    let answer = match reach.1.stages(&p, 36) {
                        Dual::Solved { x, .. } => reach.1.last(&p, &w, &up, &x),
                        Dual::Failed { .. } => {
                            by_two += 1;
                            reach.1.two(&p, &w, &up)
                        }
                        Dual::Stopped { .. } => None,
                    };
                    let u = answer.unwrap_or_else(|| panic!("demand {k}, block {c}: no answer"));
                    let start = Commands::from_fn(|j, _| (p.lo[j] + p.hi[j]) / 2.0);
                    let (v, _, stopped) = primal(&p, &w, &up, start, 1000, 0, (1, 3), true, none);
                    assert!(!stopped);
                    let gap = (0..p.m).fold(0.0f64, |a, j| a.max((u[j] - v[j]).abs()));
                    assert!(gap <= 1e-9 * 40.0, "demand {k}, block {c}: {u} against {v}");
                }
            }
        }
        assert!(by_two > 300, "two held in a block: {by_two}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]
        /// The ROV (with and without a surge thruster on its centreline) and the spacecraft
        /// allocated block by block
        /// (docs/maths.md, "Control allocation": geometries in blocks) answer what the whole geometry's active set
        /// answers, to 1e-9 of the largest bound, with the same status: demands within reach
        /// and up to four times past it, actuators held, weights and preferred commands, each
        /// priority, cold and warm.
        #[test]
        fn the_blocks_answer_what_the_whole_active_set_answers(
            us in proptest::collection::vec(-1.0f64..=1.0, 12),
            scale in 0.5f64..4.0,
            held in proptest::option::of((0usize..12, 0.0f64..=1.0)),
            second in proptest::option::of((1usize..12, 0.0f64..=1.0)),
            weights in proptest::collection::vec(0.3f64..3.0, 12),
            preferred in proptest::collection::vec(-1.0f64..=1.0, 12),
            pick in 0usize..3,
            weighted in proptest::bool::ANY,
            vehicle in 0usize..3,
        ) {
            let priority = [Priority::Torque, Priority::None, Priority::Tilt][pick];
            fn compare<const K: usize>(
                blocks: Allocator<f64, K>,
                us: &[f64],
                scale: f64,
                held: Option<(usize, f64)>,
                second: Option<(usize, f64)>,
            ) -> Result<(), TestCaseError> {
                prop_assert!(blocks.blocks.is_some());
                let mut whole = blocks;
                whole.blocks = None;
                let m = blocks.geometry().count();
                let mut bounds = blocks.bounds();
                let (lo, hi) = (bounds.lo, bounds.hi);
                let mut u = Commands::<f64>::zeros();
                for j in 0..m {
                    u[j] = lo[j] + (hi[j] - lo[j]) * (us[j] + 1.0) / 2.0;
                }
                let demand = blocks.geometry().wrench(&u) * scale;
                if let Some((j, at)) = held {
                    let j = j % m;
                    bounds.fail(j, lo[j] + (hi[j] - lo[j]) * at);
                    if let Some((k, at)) = second {
                        let k = (j + k) % m;
                        bounds.fail(k, lo[k] + (hi[k] - lo[k]) * at);
                    }
                }
                let top = hi.amax().max(lo.amax());
                // cold, and warm from another command of the box (then stage 3 has work to do:
                // the closed form that starts a cold allocation is each block's own)
                let mut previous = Commands::<f64>::zeros();
                for j in 0..m {
                    previous[j] = lo[j] + (hi[j] - lo[j]) * (1.0 - us[j]) / 2.0;
                }
                for from in [None, Some(&previous)] {
                    let a = blocks.allocate_from(&demand, &bounds, from);
                    let b = whole.allocate_from(&demand, &bounds, from);
                    prop_assert!((a.u - b.u).amax() <= 1e-9 * (1.0 + top), "{:?} against {:?}", a, b);
                    prop_assert_eq!(a.status, b.status);
                }
                Ok(())
            }
            let (w, p) = if weighted { (&weights[..], &preferred[..]) } else { (&[][..], &[][..]) };
            if vehicle == 0 {
                let g = Geometry::<f64, 3>::new(&presets::spacecraft_twelve(0.9, 1.5)).unwrap();
                let p: Vec<f64> = p.iter().map(|x| 0.75 + 0.75 * x).collect();
                compare(Allocator::new(g, w, &p, priority).unwrap(), &us, scale, held, second)?;
            } else {
                // the ROV, and the ROV with a surge thruster on its centreline (in the
                // horizontal block by `fx` alone: a zero in the torque row `τz`)
                let mut thrusters = presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0).to_vec();
                if vehicle == 2 {
                    thrusters.push(crate::Actuator {
                        position: [0.2, 0.0, 0.0],
                        axis: [1.0, 0.0, 0.0],
                        torque_per_thrust: 0.0,
                        min: -30.0,
                        max: 30.0,
                    });
                }
                let m = thrusters.len();
                let g = Geometry::<f64, 6>::new(&thrusters).unwrap();
                let p: Vec<f64> = p.iter().take(m).map(|x| 20.0 * x).collect();
                let w = &w[..w.len().min(m)];
                compare(Allocator::new(g, w, &p, priority).unwrap(), &us, scale, held, second)?;
            }
        }
    }

    /// A weak actuator's thrust as the variable (`pose_in_thrust`): the rank-one update gives the
    /// Cholesky factor of `B W⁻¹ Bᵀ` with the new weights (to 1e-12 in f64, 1e-5 in f32 of its
    /// largest entry), for one and two weak actuators, and it is the update's (not the bits a
    /// formation gives); where the downdate breaks down (a hexarotor rotor at 10⁻⁴ in f32,
    /// `k² − 1` rounding to −1, its Gram matrix singular to the precision) the factor is the
    /// formed one, bit for bit; every factor 1 is the healthy allocator, bit for bit, also
    /// posed over a weak one.
    #[test]
    fn a_weak_actuators_factor_is_updated_or_formed() {
        fn thrust<T: nalgebra::RealField + Copy>(
            a: &Allocator<T, 6>,
            f: &Commands<T>,
        ) -> Allocator<T, 6> {
            let mut t = *a;
            t.pose_in_thrust(a, f);
            t
        }
        fn gap<T: nalgebra::RealField + Copy>(a: &Allocator<T, 6>) -> T {
            let l = a.gram.unwrap().lower_triangle();
            let g = a.bw * a.geometry.effectiveness().transpose();
            (l * l.transpose() - g).amax() / g.amax()
        }
        let rov = {
            let g = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0));
            Allocator::new(g.unwrap(), &[], &[], Priority::Torque).unwrap()
        };
        let ones = Commands::from_element(1.0);
        assert_eq!(thrust(&rov, &ones), rov);
        let mut half = ones;
        half[2] = 0.5;
        let mut healed = thrust(&rov, &half);
        healed.pose_in_thrust(&rov, &ones);
        assert_eq!(healed, rov);
        for weak in [&[(0, 0.5)][..], &[(3, 0.01)], &[(1, 0.6), (6, 0.25)]] {
            let mut f = ones;
            for &(j, k) in weak {
                f[j] = k;
            }
            let t = thrust(&rov, &f);
            assert!(gap(&t) < 1e-12, "{weak:?}: {}", gap(&t));
            // updated, not formed again (a formation would give other bits)
            let formed = nalgebra::Cholesky::new(t.bw * rov.geometry.effectiveness().transpose());
            assert_ne!(t.gram, formed.map(|c| c.unpack_dirty()), "{weak:?}");
            for &(j, k) in weak {
                assert_eq!(t.weights[j], rov.weights[j] / (k * k));
            }
        }
        let hex = hexarotor::<f32>(0.5);
        let mut f = Commands::from_element(1.0f32);
        for k in [0.5f32, 1e-2] {
            f[2] = k;
            assert!(
                gap(&thrust(&hex, &f)) < 1e-5,
                "{k}: {}",
                gap(&thrust(&hex, &f))
            );
        }
        f[2] = 1e-4;
        let t = thrust(&hex, &f);
        let mut chol = nalgebra::Cholesky::pack_dirty(hex.gram.unwrap());
        chol.rank_one_update(&hex.geometry.effectiveness().column(2), 1e-8 - 1.0);
        assert!(
            chol.l_dirty()[(5, 5)].is_nan(),
            "the downdate breaks down here"
        );
        let formed = nalgebra::Cholesky::new(t.bw * hex.geometry.effectiveness().transpose());
        assert_eq!(t.gram, formed.map(|c| c.unpack_dirty()));
    }

    /// The bits of `l` (a NaN as any NaN, as `Cholesky` leaves it).
    fn bits<T: nalgebra::RealField + Copy, const K: usize>(
        l: &nalgebra::SMatrix<T, K, K>,
    ) -> Vec<Option<T>> {
        l.iter().map(|x| x.partial_cmp(x).map(|_| *x)).collect()
    }

    proptest! {
        /// The hand-written rank-one update (`rank_one_update`, the FPU's square root) gives
        /// nalgebra's `Cholesky::rank_one_update`, bit for bit, in `f64` and `f32`: updates and
        /// downdates of a random factor along a random vector, a downdate that breaks down
        /// (a NaN or negative diagonal) included, and a zero in the vector. Signed zeros are
        /// told apart (a plant that reorders an addition fails it).
        #[test]
        fn the_rank_one_update_is_nalgebras(
            m in proptest::collection::vec(-2.0f64..2.0, 36),
            x in proptest::collection::vec(-3.0f64..3.0, 6),
            sigma in -1.5f64..4.0,
            zero in 0usize..8,
        ) {
            fn check<T: nalgebra::RealField + Copy>(m: &[f64], x: &[f64], sigma: f64, zero: usize) -> Result<(), TestCaseError> {
                let m = nalgebra::SMatrix::<T, 6, 6>::from_iterator(m.iter().map(|v| nalgebra::convert(*v)));
                let a = m * m.transpose() + nalgebra::SMatrix::<T, 6, 6>::identity() * nalgebra::convert::<f64, T>(0.05);
                let mut x = nalgebra::SVector::<T, 6>::from_iterator(x.iter().map(|v| nalgebra::convert(*v)));
                if zero < 6 {
                    x[zero] = T::zero();
                }
                let sigma: T = nalgebra::convert(sigma);
                let chol = nalgebra::Cholesky::new(a).unwrap();
                let mut ours = chol.unpack_dirty();
                super::rank_one_update(&mut ours, &x, sigma);
                let mut theirs = chol;
                theirs.rank_one_update(&x, sigma);
                let theirs = theirs.unpack_dirty();
                prop_assert_eq!(bits(&ours), bits(&theirs));
                // signed zeros too
                let signs = |l: &nalgebra::SMatrix<T, 6, 6>| l.iter().map(|v| v.is_sign_negative()).collect::<Vec<_>>();
                prop_assert_eq!(signs(&ours), signs(&theirs));
                Ok(())
            }
            check::<f64>(&m, &x, sigma, zero)?;
            check::<f32>(&m, &x, sigma, zero)?;
        }
    }
}
