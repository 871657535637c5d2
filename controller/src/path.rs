//! Desired trajectories given as poses at times: a set-point, a smooth path through waypoints,
//! and the same pieces arriving one by one.
//! The mathematics: docs/maths.md, "Desired trajectories as inputs".
//!
//! Every piece is a [`Segment`]: the geodesic `Q(t) = Q_a·exp(s(σ)·ξ)` from waypoint `a` to
//! waypoint `b`, `ξ = log(Q_a⁻¹ Q_b)`, `σ = (t − t_a)/(t_b − t_a)`, with the quintic time
//! scaling `s(σ) = 10σ³ − 15σ⁴ + 6σ⁵` (`s, s', s''` = 0, 0, 0 at σ = 0 and 1, 0, 0 at σ = 1).
//! Because `ξ` commutes with `exp(sξ)`, the body velocity and acceleration are exact:
//! `V = ṡ·ξ`, `V̇ = s̈·ξ`. Each piece starts and ends at rest with zero acceleration, so the
//! chain of pieces is C² through every waypoint, whatever the rotation between two of them.
//! A [`Path`] holds up to [`MAX_SEGMENTS`] pieces and holds the last pose at rest when no
//! piece covers `t`.

use crate::error::{Error, Quantity};
use crate::group::MatrixLieGroup;
use crate::law::Desired;
use crate::reference::Trajectory;
use crate::validate::finite;
use crate::{Real, real};
use nalgebra::{SMatrix, SVector};

/// How many segments a [`Path`] holds: a path through up to `MAX_SEGMENTS + 1` waypoints.
pub const MAX_SEGMENTS: usize = 32;

/// The quintic time scaling `(s, ds/dσ, d²s/dσ²)` at `σ ∈ [0, 1]`: `s(σ) = 10σ³ − 15σ⁴ + 6σ⁵`
/// of docs/maths.md, "Desired trajectories as inputs".
pub fn quintic<T: Real>(sigma: T) -> (T, T, T) {
    let s = sigma;
    let s2 = s * s;
    let s3 = s2 * s;
    let r = |x: f64| real::<T>(x);
    (
        s3 * (r(10.0) + s * (r(-15.0) + s * r(6.0))),
        s2 * (r(30.0) + s * (r(-60.0) + s * r(30.0))),
        s * (r(60.0) + s * (r(-180.0) + s * r(120.0))),
    )
}

/// A desired pose with its body velocity and acceleration at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSample<T: Real, const N: usize, const M: usize> {
    /// `Q_d(t)`.
    pub q: SMatrix<T, N, N>,
    /// `V_d(t) = vee(Q_d⁻¹ Q̇_d)`.
    pub v: SVector<T, M>,
    /// `V̇_d(t)`.
    pub v_dot: SVector<T, M>,
}

impl<T: Real, const N: usize, const M: usize> PathSample<T, N, M> {
    /// At rest at `q`.
    pub fn rest(q: SMatrix<T, N, N>) -> Self {
        PathSample {
            q,
            v: SVector::zeros(),
            v_dot: SVector::zeros(),
        }
    }

    /// The law's desired state with model inertia `I`: `p_d = I V_d` and the feedforward
    /// `τ_d = I V̇_d − ad_{V_d}ᵀ I V_d` that makes the path a solution of the Euler–Poincaré
    /// equations (docs/maths.md, "Desired trajectories as inputs").
    pub fn desired<G: MatrixLieGroup<N, M>>(&self, inertia: &SMatrix<T, M, M>) -> Desired<T, N, M> {
        let p = inertia * self.v;
        Desired {
            q: self.q,
            p,
            v: self.v,
            tau: inertia * self.v_dot - G::ad(&self.v).transpose() * p,
        }
    }
}

/// One piece: the geodesic from `start` at `t0` to `start·exp(twist)` at `t1`, timed by
/// [`quintic`] (at rest at both ends).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment<T: Real, const N: usize, const M: usize> {
    /// Start time.
    pub t0: T,
    /// End time (`> t0`).
    pub t1: T,
    /// The pose at `t0`.
    pub start: SMatrix<T, N, N>,
    /// `ξ = log(Q_start⁻¹ Q_end)`: the body-frame displacement over the piece.
    pub twist: SVector<T, M>,
}

impl<T: Real, const N: usize, const M: usize> Segment<T, N, M> {
    /// The piece from pose `a` at `t0` to pose `b` at `t1` (the shorter way round: the
    /// principal logarithm of `a⁻¹b`, rotation angle at most π).
    pub fn between<G: MatrixLieGroup<N, M>>(
        t0: T,
        a: &SMatrix<T, N, N>,
        t1: T,
        b: &SMatrix<T, N, N>,
    ) -> Self {
        Segment {
            t0,
            t1,
            start: *a,
            twist: G::log(&G::compose(&G::inverse(a), b)),
        }
    }

    /// Finite numbers and `t1 > t0`.
    pub fn check(&self) -> Result<(), Error> {
        finite(Quantity::Reference, &self.start)?;
        finite(Quantity::Reference, &self.twist)?;
        if !(self.t0.is_finite() && self.t1.is_finite()) {
            return Err(Error::NonFinite(Quantity::Reference));
        }
        if self.t1 <= self.t0 {
            return Err(Error::NotPositive(Quantity::Period));
        }
        Ok(())
    }

    /// The pose at `t1`.
    pub fn end<G: MatrixLieGroup<N, M>>(&self) -> SMatrix<T, N, N> {
        G::compose(&self.start, &G::exp(&self.twist))
    }

    /// `Q_d, V_d, V̇_d` at `t` (clamped to `[t0, t1]`): `Q = start·exp(s·ξ)`, `V = ṡ·ξ`,
    /// `V̇ = s̈·ξ` (docs/maths.md, "Desired trajectories as inputs").
    pub fn sample<G: MatrixLieGroup<N, M>>(&self, t: T) -> PathSample<T, N, M> {
        let span = self.t1 - self.t0;
        let sigma = ((t - self.t0) / span).clamp(T::zero(), T::one());
        let (s, ds, dds) = quintic(sigma);
        PathSample {
            q: G::compose(&self.start, &G::exp(&(self.twist * s))),
            v: self.twist * (ds / span),
            v_dot: self.twist * (dds / (span * span)),
        }
    }
}

/// Segments in time order, and the pose held where none covers `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct Path<T: Real, G, const N: usize, const M: usize> {
    segments: heapless::Deque<Segment<T, N, M>, MAX_SEGMENTS>,
    /// Held before the first segment (and after the last, once every segment is retired).
    rest: SMatrix<T, N, N>,
    _group: core::marker::PhantomData<G>,
}

impl<T, G, const N: usize, const M: usize> Path<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// A set-point: `Q_d = q`, `V_d = 0`, `τ_d = 0` for all time (more segments may follow).
    pub fn hold(q: SMatrix<T, N, N>) -> Result<Self, Error> {
        finite(Quantity::Reference, &q)?;
        Ok(Path {
            segments: heapless::Deque::new(),
            rest: q,
            _group: core::marker::PhantomData,
        })
    }

    /// The path through `poses[i]` at `times[i]`: at rest at `poses[0]` until `times[0]`,
    /// one [`Segment`] between consecutive waypoints, at rest at the last pose after the last
    /// time. Times must increase strictly; at most [`MAX_SEGMENTS`]` + 1` waypoints.
    pub fn through(times: &[T], poses: &[SMatrix<T, N, N>]) -> Result<Self, Error> {
        if times.len() != poses.len() {
            return Err(Error::WrongShape {
                quantity: Quantity::Reference,
                expected: times.len(),
                found: poses.len(),
            });
        }
        let Some(first) = poses.first() else {
            return Err(Error::WrongShape {
                quantity: Quantity::Reference,
                expected: 1,
                found: 0,
            });
        };
        let mut path = Path::hold(*first)?;
        for i in 1..poses.len() {
            let seg = Segment::between::<G>(times[i - 1], &poses[i - 1], times[i], &poses[i]);
            path.push(seg).map_err(|e| match e {
                Error::NotPositive(_) => Error::NotIncreasing { index: i },
                other => other,
            })?;
        }
        Ok(path)
    }

    /// Appends a segment; it must be valid ([`Segment::check`]), start no earlier than the
    /// last one ends, and fit in the capacity.
    pub fn push(&mut self, seg: Segment<T, N, M>) -> Result<(), Error> {
        seg.check()?;
        if let Some(last) = self.segments.back()
            && seg.t0 < last.t1
        {
            return Err(Error::NotIncreasing {
                index: self.segments.len(),
            });
        }
        self.segments
            .push_back(seg)
            .map_err(|_| Error::TooManySegments {
                capacity: MAX_SEGMENTS,
            })
    }

    /// The segments held.
    pub fn segments(&self) -> impl Iterator<Item = &Segment<T, N, M>> {
        self.segments.iter()
    }

    /// The end of the last segment (the set-point when there is none).
    pub fn last_pose(&self) -> SMatrix<T, N, N> {
        self.segments.back().map_or(self.rest, |s| s.end::<G>())
    }

    /// The end time of the last segment (`None`: no segment).
    pub fn end_time(&self) -> Option<T> {
        self.segments.back().map(|s| s.t1)
    }

    /// Drops the segments that ended before `t`, keeping the pose the last of them ends at:
    /// frees capacity for streamed segments.
    pub fn retire(&mut self, t: T) {
        while let Some(front) = self.segments.front()
            && front.t1 < t
        {
            self.rest = front.end::<G>();
            self.segments.pop_front();
        }
    }

    /// `Q_d, V_d, V̇_d` at `t`: the segment whose interval holds `t`, else at rest at the
    /// end of the last segment that ended before `t` (or at the held pose before them all).
    pub fn sample(&self, t: T) -> PathSample<T, N, M> {
        match self.segments.iter().rev().find(|s| s.t0 <= t) {
            Some(s) if t <= s.t1 => s.sample::<G>(t),
            Some(s) => PathSample::rest(s.end::<G>()),
            None => PathSample::rest(self.rest),
        }
    }

    /// Whether a segment covers `t`.
    pub fn covers(&self, t: T) -> bool {
        self.segments.iter().any(|s| s.t0 <= t && t <= s.t1)
    }
}

/// A [`Path`] stepped at the control period: the [`Trajectory`] of a set-point, a waypoint
/// path or a streamed one.
#[derive(Debug, Clone, PartialEq)]
pub struct PathReference<T: Real, G, const N: usize, const M: usize> {
    path: Path<T, G, N, M>,
    inertia: SMatrix<T, M, M>,
    period: T,
    step: u64,
}

impl<T, G, const N: usize, const M: usize> PathReference<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// Steps `path` at `period` with the controller's model inertia (for `p_d` and `τ_d`).
    pub fn new(
        path: Path<T, G, N, M>,
        inertia: SMatrix<T, M, M>,
        period: T,
    ) -> Result<Self, Error> {
        crate::validate::spd_inverse(Quantity::Inertia, &inertia)?;
        crate::validate::period(period)?;
        Ok(PathReference {
            path,
            inertia,
            period,
            step: 0,
        })
    }

    /// The path (to push streamed segments into).
    pub fn path_mut(&mut self) -> &mut Path<T, G, N, M> {
        &mut self.path
    }

    /// The path.
    pub fn path(&self) -> &Path<T, G, N, M> {
        &self.path
    }

    /// `Q_d, V_d, V̇_d` at the current time.
    pub fn sample(&self) -> PathSample<T, N, M> {
        self.path.sample(self.time())
    }
}

impl<T, G, const N: usize, const M: usize> Trajectory<T, N, M> for PathReference<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    fn time(&self) -> T {
        real::<T>(self.step as f64) * self.period
    }
    fn period(&self) -> T {
        self.period
    }
    fn step_index(&self) -> u64 {
        self.step
    }
    fn desired(&self) -> Desired<T, N, M> {
        self.sample().desired::<G>(&self.inertia)
    }
    fn advance(&mut self) {
        self.step += 1;
        let t = self.time();
        self.path.retire(t);
    }
}
