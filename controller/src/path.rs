//! Desired trajectories given as poses at times: a set-point, a smooth path through waypoints,
//! and the same pieces arriving one by one.
//! The mathematics: docs/maths.md, "Desired trajectories as inputs";
//! docs/maths.md, "Paths that fly through their waypoints".
//!
//! Every piece is a [`Segment`] of one of two [`Shape`]s:
//!
//! - [`Shape::Rest`] (`path = "stop"`): the geodesic `Q(t) = Q_a·exp(s(σ)·ξ)` from waypoint `a`
//!   to waypoint `b`, `ξ = log(Q_a⁻¹ Q_b)`, `σ = (t − t_a)/(t_b − t_a)`, with the quintic time
//!   scaling `s(σ) = 10σ³ − 15σ⁴ + 6σ⁵` (`s, s', s''` = 0, 0, 0 at σ = 0 and 1, 0, 0 at
//!   σ = 1). Because `ξ` commutes with `exp(sξ)`, the body velocity and acceleration are
//!   exact: `V = ṡ·ξ`, `V̇ = s̈·ξ`. Each piece starts and ends at rest with zero
//!   acceleration, so the chain of pieces is C² through every waypoint.
//! - [`Shape::Through`] (`path = "through"`): the quintic Hermite piece in cumulative Bézier
//!   form `Q(t) = Q_a·∏_{j=1..5} exp(B̃_j(σ)·v_j)`, whose `v_j` are fixed by the poses, body
//!   velocities and body accelerations at both ends ([`Segment::hermite`]); `V` and `V̇` follow
//!   from the recursion of Sommer et al. (CVPR 2020). Consecutive pieces share the pose,
//!   velocity and acceleration at their common waypoint, so the chain is C² without stopping.
//!
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

/// The cumulative Bernstein basis of degree 5 and its first two derivatives at `σ ∈ [0, 1]`:
/// `B̃_j(σ) = Σ_{k=j..5} C(5,k) σ^k (1−σ)^{5−k}`, `B̃_j' = 5·B⁴_{j−1}`,
/// `B̃_j'' = 20·(B³_{j−2} − B³_{j−1})`, for `j = 1..5` (index `j − 1`):
/// docs/maths.md, "Paths that fly through their waypoints".
pub fn cumulative_bernstein<T: Real>(sigma: T) -> ([T; 5], [T; 5], [T; 5]) {
    let u = sigma;
    let s = T::one() - u;
    let r = |x: f64| real::<T>(x);
    let (u2, s2) = (u * u, s * s);
    let (u3, s3) = (u2 * u, s2 * s);
    // the Bernstein polynomials of degree 5, 4 and 3
    let b5 = [
        s3 * s2,
        r(5.0) * u * s2 * s2,
        r(10.0) * u2 * s3,
        r(10.0) * u3 * s2,
        r(5.0) * u2 * u2 * s,
        u3 * u2,
    ];
    let b4 = [
        s2 * s2,
        r(4.0) * u * s3,
        r(6.0) * u2 * s2,
        r(4.0) * u3 * s,
        u2 * u2,
    ];
    let b3 = [s3, r(3.0) * u * s2, r(3.0) * u2 * s, u3];
    let mut value = [T::zero(); 5];
    let mut acc = T::zero();
    for j in (1..=5).rev() {
        acc += b5[j];
        value[j - 1] = acc;
    }
    let mut first = [T::zero(); 5];
    let mut second = [T::zero(); 5];
    for j in 1..=5 {
        first[j - 1] = r(5.0) * b4[j - 1];
        let lower = if j >= 2 { b3[j - 2] } else { T::zero() };
        let upper = if j <= 4 { b3[j - 1] } else { T::zero() };
        second[j - 1] = r(20.0) * (lower - upper);
    }
    (value, first, second)
}

/// How a [`Segment`] moves from its start pose to its end pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape<T: Real, const M: usize> {
    /// The geodesic `start·exp(s(σ)·ξ)` timed by [`quintic`]: at rest at both ends
    /// (`path = "stop"`).
    Rest {
        /// `ξ = log(Q_start⁻¹ Q_end)`: the body-frame displacement over the piece.
        twist: SVector<T, M>,
    },
    /// The quintic Hermite piece `start·∏_{j=1..5} exp(B̃_j(σ)·v_j)` ([`cumulative_bernstein`],
    /// [`Segment::hermite`]) (`path = "through"`).
    Through {
        /// `v_1 … v_5`: body-frame displacements of the cumulative Bézier form.
        v: [SVector<T, M>; 5],
    },
}

/// One piece of a path from `start` at `t0` to its end pose at `t1`, shaped by [`Shape`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment<T: Real, const N: usize, const M: usize> {
    /// Start time.
    pub t0: T,
    /// End time (`> t0`).
    pub t1: T,
    /// The pose at `t0`.
    pub start: SMatrix<T, N, N>,
    /// The motion over the piece.
    pub shape: Shape<T, M>,
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
            shape: Shape::Rest {
                twist: G::log(&G::compose(&G::inverse(a), b)),
            },
        }
    }

    /// The quintic Hermite piece from `a` (pose, body velocity, body acceleration) at `t0` to
    /// `b` at `t1`, in cumulative Bézier form
    /// (docs/maths.md, "Paths that fly through their waypoints"): with `h = t1 − t0`,
    /// `v_1 = h·V_a/5`, `v_2 = v_1 + h²·V̇_a/20`, `v_5 = h·V_b/5`,
    /// `v_4 = v_5 − (h²/20)·Ad_{exp(v_5)} V̇_b`, and
    /// `v_3 = log(exp(v_2)⁻¹ exp(v_1)⁻¹ Q_a⁻¹ Q_b exp(v_5)⁻¹ exp(v_4)⁻¹)`, so that the piece
    /// starts at `(Q_a, V_a, V̇_a)` and ends at `(Q_b, V_b, V̇_b)` exactly. With zero velocities
    /// and accelerations it is the geodesic of [`Segment::between`] timed by [`quintic`].
    pub fn hermite<G: MatrixLieGroup<N, M>>(
        t0: T,
        a: &PathSample<T, N, M>,
        t1: T,
        b: &PathSample<T, N, M>,
    ) -> Self {
        let h = t1 - t0;
        let fifth = h / real::<T>(5.0);
        let twentieth = h * h / real::<T>(20.0);
        let v1 = a.v * fifth;
        let v2 = v1 + a.v_dot * twentieth;
        let v5 = b.v * fifth;
        let e5 = G::exp(&v5);
        let v4 = v5 - G::adjoint(&e5) * b.v_dot * twentieth;
        let head = G::compose(&G::exp(&v1), &G::exp(&v2));
        let tail = G::compose(&G::exp(&v4), &e5);
        let middle = G::compose(
            &G::compose(&G::inverse(&head), &G::compose(&G::inverse(&a.q), &b.q)),
            &G::inverse(&tail),
        );
        Segment {
            t0,
            t1,
            start: a.q,
            shape: Shape::Through {
                v: [v1, v2, G::log(&middle), v4, v5],
            },
        }
    }

    /// Finite numbers and `t1 > t0`.
    pub fn check(&self) -> Result<(), Error> {
        finite(Quantity::Reference, &self.start)?;
        match &self.shape {
            Shape::Rest { twist } => finite(Quantity::Reference, twist)?,
            Shape::Through { v } => {
                for vj in v {
                    finite(Quantity::Reference, vj)?;
                }
            }
        }
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
        match &self.shape {
            Shape::Rest { twist } => G::compose(&self.start, &G::exp(twist)),
            Shape::Through { v } => v
                .iter()
                .fold(self.start, |q, vj| G::compose(&q, &G::exp(vj))),
        }
    }

    /// The body velocity and acceleration at `t1` (zero for a [`Shape::Rest`] piece).
    pub fn end_motion<G: MatrixLieGroup<N, M>>(&self) -> PathSample<T, N, M> {
        match &self.shape {
            Shape::Rest { .. } => PathSample::rest(self.end::<G>()),
            Shape::Through { .. } => self.sample::<G>(self.t1),
        }
    }

    /// `Q_d, V_d, V̇_d` at `t` (clamped to `[t0, t1]`). [`Shape::Rest`]: `Q = start·exp(s·ξ)`,
    /// `V = ṡ·ξ`, `V̇ = s̈·ξ` (docs/maths.md, "Desired trajectories as inputs").
    /// [`Shape::Through`]: with `A_j = exp(B̃_j v_j)`, `Q = start·A_1⋯A_5` and, for
    /// `j = 1..5` from `ω_0 = ω̇_0 = 0`, `ω_j = Ad_{A_j⁻¹} ω_{j−1} + B̃_j'·v_j`,
    /// `ω̇_j = Ad_{A_j⁻¹} ω̇_{j−1} + B̃_j'·ad_{ω_j} v_j + B̃_j''·v_j`; `V = ω_5/h`,
    /// `V̇ = ω̇_5/h²`
    /// (docs/maths.md, "Paths that fly through their waypoints").
    pub fn sample<G: MatrixLieGroup<N, M>>(&self, t: T) -> PathSample<T, N, M> {
        let span = self.t1 - self.t0;
        let sigma = ((t - self.t0) / span).clamp(T::zero(), T::one());
        match &self.shape {
            Shape::Rest { twist } => {
                let (s, ds, dds) = quintic(sigma);
                PathSample {
                    q: G::compose(&self.start, &G::exp(&(*twist * s))),
                    v: *twist * (ds / span),
                    v_dot: *twist * (dds / (span * span)),
                }
            }
            Shape::Through { v } => {
                let (b, db, ddb) = cumulative_bernstein(sigma);
                let mut q = self.start;
                let mut w = SVector::<T, M>::zeros();
                let mut w_dot = SVector::<T, M>::zeros();
                for j in 0..5 {
                    let a = G::exp(&(v[j] * b[j]));
                    q = G::compose(&q, &a);
                    let back = G::adjoint(&G::inverse(&a));
                    w = back * w + v[j] * db[j];
                    w_dot = back * w_dot + G::ad(&w) * v[j] * db[j] + v[j] * ddb[j];
                }
                PathSample {
                    q,
                    v: w / span,
                    v_dot: w_dot / (span * span),
                }
            }
        }
    }
}

/// Whether a waypoint's body velocity is given or chosen, for [`Path::flying`].
pub type GivenVelocity<T, const M: usize> = Option<SVector<T, M>>;

/// The body velocity and acceleration at every waypoint of a through-path
/// (docs/maths.md, "Choosing the velocities at the waypoints"): the unwrapped coordinates
/// `p_0 = 0`, `p_{i+1} = p_i + ξ_i` with `ξ_i = log(Q_i⁻¹ Q_{i+1})`, a cubic spline through
/// `(t_i, p_i)` clamped at every fixed knot — the first and last waypoint (at rest), a
/// waypoint whose velocity is given, and a waypoint next to a leg without motion
/// (`ξ = 0`: the data says hold, so it is at rest) — with the slopes of the free knots from
/// the spline's C² conditions. The accelerations are the spline's (the mean of its left and
/// right values at a fixed knot), zero at the first and last waypoint and next to a hold.
/// Fills `velocity[..n]`, `acceleration[..n]`; allocation-free.
pub fn waypoint_motion<T: Real, G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    times: &[T],
    poses: &[SMatrix<T, N, N>],
    given: &[GivenVelocity<T, M>],
    velocity: &mut [SVector<T, M>],
    acceleration: &mut [SVector<T, M>],
) -> Result<(), Error> {
    check_waypoint_inputs(
        times,
        poses.len(),
        given,
        velocity.len().min(acceleration.len()),
    )?;
    let n = times.len();
    let zero = SVector::<T, M>::zeros();
    let mut slope = [zero; MAX_SEGMENTS]; // δ_i = ξ_i / h_i
    let mut span = [T::zero(); MAX_SEGMENTS]; // h_i
    let mut hold = [false; MAX_SEGMENTS];
    for i in 0..n.saturating_sub(1) {
        let xi = G::log(&G::compose(&G::inverse(&poses[i]), &poses[i + 1]));
        finite(Quantity::Reference, &xi)?;
        span[i] = times[i + 1] - times[i];
        slope[i] = xi / span[i];
        hold[i] = xi.iter().all(|x| *x == T::zero());
    }
    let fixed =
        |i: usize| i == 0 || i + 1 == n || given[i].is_some() || hold[i] || (i > 0 && hold[i - 1]);
    let two = real::<T>(2.0);
    for i in 0..n {
        velocity[i] = given[i].unwrap_or(zero);
    }
    // a clamped spline on each run of free knots between two fixed ones
    let mut a = 0;
    while a + 1 < n {
        let mut b = a + 1;
        while !fixed(b) {
            b += 1;
        }
        if b > a + 1 {
            clamped_run(a, b, &span, &slope, velocity);
        }
        a = b;
    }
    let four = real::<T>(4.0);
    let six = real::<T>(6.0);
    for i in 0..n {
        acceleration[i] = if i == 0 || i + 1 == n || hold[i] || hold[i - 1] {
            zero
        } else {
            // the cubic on each side: p''(t_i⁺) from leg i, p''(t_i⁻) from leg i − 1
            let right = (slope[i] * six - velocity[i] * four - velocity[i + 1] * two) / span[i];
            let left =
                (velocity[i - 1] * two + velocity[i] * four - slope[i - 1] * six) / span[i - 1];
            (right + left) / two
        };
    }
    Ok(())
}

/// The inputs of [`waypoint_motion`] checked: matching lengths, within capacity (`room`: the
/// shorter output slice), given velocities finite and zero at the ends, times increasing.
fn check_waypoint_inputs<T: Real, const M: usize>(
    times: &[T],
    poses: usize,
    given: &[GivenVelocity<T, M>],
    room: usize,
) -> Result<(), Error> {
    let n = times.len();
    if poses != n || given.len() != n {
        return Err(Error::WrongShape {
            quantity: Quantity::Reference,
            expected: n,
            found: if poses != n { poses } else { given.len() },
        });
    }
    if n > MAX_SEGMENTS + 1 || room < n {
        return Err(Error::TooManySegments {
            capacity: MAX_SEGMENTS,
        });
    }
    for (i, g) in given.iter().enumerate() {
        if let Some(v) = g {
            finite(Quantity::Reference, v)?;
            if (i == 0 || i + 1 == n) && v.iter().any(|x| *x != T::zero()) {
                return Err(Error::NotAtRest { index: i });
            }
        }
    }
    for i in 1..n {
        // NaN times are refused too
        if times[i].partial_cmp(&times[i - 1]) != Some(core::cmp::Ordering::Greater) {
            return Err(Error::NotIncreasing { index: i });
        }
    }
    Ok(())
}

/// The slopes of the free knots `a+1 .. b−1` between the fixed knots `a` and `b` of a clamped
/// cubic spline (docs/maths.md, "Choosing the velocities at the waypoints"), by the Thomas
/// algorithm: row i reads `h_i m_{i−1} + 2(h_{i−1}+h_i) m_i + h_{i−1} m_{i+1} =
/// 3(h_i δ_{i−1} + h_{i−1} δ_i)`, with `m_a`, `m_b` known (in `velocity`).
fn clamped_run<T: Real, const M: usize>(
    a: usize,
    b: usize,
    span: &[T],
    slope: &[SVector<T, M>],
    velocity: &mut [SVector<T, M>],
) {
    let zero = SVector::<T, M>::zeros();
    let three = real::<T>(3.0);
    let two = real::<T>(2.0);
    let mut c_prime = [T::zero(); MAX_SEGMENTS + 1];
    let mut d_prime = [zero; MAX_SEGMENTS + 1];
    for i in a + 1..b {
        let lower = span[i];
        let diag = two * (span[i - 1] + span[i]);
        let upper = span[i - 1];
        let mut rhs = (slope[i - 1] * span[i] + slope[i] * span[i - 1]) * three;
        if i == a + 1 {
            rhs -= velocity[a] * lower;
        }
        if i == b - 1 {
            rhs -= velocity[b] * upper;
        }
        let (denominator, carried) = if i == a + 1 {
            (diag, rhs)
        } else {
            (diag - lower * c_prime[i - 1], rhs - d_prime[i - 1] * lower)
        };
        c_prime[i] = if i == b - 1 {
            T::zero()
        } else {
            upper / denominator
        };
        d_prime[i] = carried / denominator;
    }
    velocity[b - 1] = d_prime[b - 1];
    for i in (a + 1..b - 1).rev() {
        velocity[i] = d_prime[i] - velocity[i + 1] * c_prime[i];
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

    /// The C² path through `poses[i]` at `times[i]` that does not stop at its interior
    /// waypoints: one [`Segment::hermite`] per leg, with the body velocities `given` where
    /// they are `Some` (zero at the first and last waypoint) and the others chosen by
    /// [`waypoint_motion`]. At rest at `poses[0]` until `times[0]` and at the last pose after
    /// the last time. With two waypoints (nothing in between: at rest at both ends, zero
    /// acceleration) it is [`Path::through`]'s path up to rounding
    /// (docs/maths.md, "Paths that fly through their waypoints"). A leg whose end misses its
    /// waypoint by more than `√ε` relative to the pose (numbers too large to keep their digits)
    /// is refused ([`Error::MissesWaypoint`]).
    pub fn flying(
        times: &[T],
        poses: &[SMatrix<T, N, N>],
        given: &[GivenVelocity<T, M>],
    ) -> Result<Self, Error> {
        let Some(first) = poses.first() else {
            return Err(Error::WrongShape {
                quantity: Quantity::Reference,
                expected: 1,
                found: 0,
            });
        };
        let zero = SVector::<T, M>::zeros();
        let mut velocity = [zero; MAX_SEGMENTS + 1];
        let mut acceleration = [zero; MAX_SEGMENTS + 1];
        waypoint_motion::<T, G, N, M>(times, poses, given, &mut velocity, &mut acceleration)?;
        let mut path = Path::hold(*first)?;
        let knot = |i: usize| PathSample {
            q: poses[i],
            v: velocity[i],
            v_dot: acceleration[i],
        };
        // how far a leg's end may be from its waypoint: √ε relative to the pose's size
        let tolerance = T::default_epsilon().sqrt();
        for i in 1..poses.len() {
            let seg = Segment::hermite::<G>(times[i - 1], &knot(i - 1), times[i], &knot(i));
            path.push(seg).map_err(|e| match e {
                Error::NotPositive(_) => Error::NotIncreasing { index: i },
                other => other,
            })?;
            let miss = (seg.end::<G>() - poses[i]).norm();
            // a NaN miss is refused too
            let bound = tolerance * poses[i].norm().max(T::one());
            if miss
                .partial_cmp(&bound)
                .is_none_or(|o| o == core::cmp::Ordering::Greater)
            {
                return Err(Error::MissesWaypoint { index: i });
            }
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
