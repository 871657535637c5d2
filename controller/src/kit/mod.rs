//! The property kit (feature `kit`): what every [`MatrixLieGroup`] must satisfy, and what the
//! law's proof promises on it, checked numerically and each failure named
//! (docs/groups.md, "Add your own group").
//!
//! * [`check_group`]: the group's identities on algebra samples the caller chooses
//!   (docs/maths.md, "Conventions"); typically some near zero, some of moderate size and,
//!   for a group with a rotation in it, some near its cut locus (a rotation angle near π),
//!   where `log` is hardest.
//! * [`check_error_dynamics`]: the error-dynamics theorem along two trajectories of the
//!   extended system, by central differences
//!   (docs/maths.md, "Tracking error and its dynamics").
//! * [`check_lyapunov`]: the law's `L` along the continuous closed loop, its rate against
//!   the rate docs/maths.md states for the configured error frame, and no rise where that
//!   rate is `−eᵀK_d e ≤ 0`.
//! * [`check`]: all three, with eqtrack's default tolerances.
//!
//! eqtrack's own groups run it in their tests; a group written outside this crate runs the
//! same functions:
//!
//! ```
//! use eqtrack_controller::group::So3;
//! use eqtrack_controller::kit::{check_group, sample};
//! let samples: [_; 12] = core::array::from_fn(|i| sample::<3>(7, i as u64, 1.5));
//! assert!(check_group::<So3, f64, 3, 3>(&samples, 1e-9).is_ok());
//! ```

use crate::group::MatrixLieGroup;
use crate::integrator::{dexp_inv_neg, rkmk4_step};
use crate::law::Desired;
use crate::semidirect::{Input, Phase, input_action, vector_field};
use crate::tracking::{error_input, potential_gradient, torque_from_error_torque, tracking_error};
use crate::{Controller, ControllerConfig, ErrorFrame, Law, Real, real};
use nalgebra::{SMatrix, SVector};

/// A property a group failed: its name, the sample it failed on (the index of the first of
/// the samples it used), and the error against the tolerance (both relative to the size of
/// the numbers compared).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Failure {
    /// The property, as the kit names it (e.g. `"ad against the commutator"`).
    pub property: &'static str,
    /// The index of the sample.
    pub sample: usize,
    /// The error found.
    pub error: f64,
    /// The tolerance it exceeded.
    pub tolerance: f64,
}

/// Counts the checks a kit function makes; the first to exceed its tolerance (or to be NaN)
/// is the [`Failure`].
#[derive(Default)]
struct Checks(usize);

impl Checks {
    fn check(
        &mut self,
        property: &'static str,
        sample: usize,
        error: f64,
        tolerance: f64,
    ) -> Result<(), Failure> {
        self.0 += 1;
        if error <= tolerance {
            Ok(())
        } else {
            Err(Failure {
                property,
                sample,
                error,
                tolerance,
            })
        }
    }
}

impl core::fmt::Display for Failure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "the group fails `{}` at sample {}: error {:e} above {:e}",
            self.property, self.sample, self.error, self.tolerance
        )
    }
}

/// A deterministic algebra sample for the kit: sample `i` of stream `seed`, each coordinate
/// uniform in `[−scale, scale]` (SplitMix64, so the same on every machine).
pub fn sample<const M: usize>(seed: u64, i: u64, scale: f64) -> SVector<f64, M> {
    let mut state = seed ^ i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    SVector::<f64, M>::from_fn(|_, _| {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        ((z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * scale
    })
}

/// The largest entry of `a − b` against `1 +` the largest entry of either.
fn relative<T: Real, const R: usize, const C: usize>(
    a: &SMatrix<T, R, C>,
    b: &SMatrix<T, R, C>,
) -> f64 {
    let f = |x: T| nalgebra::try_convert::<T, f64>(x).unwrap_or(f64::NAN);
    let size = 1.0 + f(a.amax()).max(f(b.amax()));
    f((a - b).amax()) / size
}

/// `Σ_{k≤40} Xᵏ/k!`, the truncated series of the matrix exponential.
fn exp_series<T: Real, const N: usize>(x: &SMatrix<T, N, N>) -> SMatrix<T, N, N> {
    let mut sum = SMatrix::<T, N, N>::identity();
    let mut term = SMatrix::<T, N, N>::identity();
    for k in 1..=40 {
        term = term * x / real::<T>(f64::from(k));
        sum += term;
    }
    sum
}

/// Checks group `G` in the scalar `T` on `samples` (algebra coordinates, cast to `T`), each
/// property within `tol` relative to the size of the numbers compared (the associativity and
/// the adjoint's identities, which compose three products, within `10·tol`). For each sample
/// `a` with the next two `b`, `c` (cyclically):
///
/// - the axioms: the identity on both sides, the inverse on both sides and equal to the matrix
///   inverse, associativity;
/// - `Ad(a)Ad(b) = Ad(ab)` and `X hat(v) X⁻¹ = hat(Ad_X v)`;
/// - `ad_a b = vee([hat a, hat b])`, and `ad_transpose_mul` equal to `ad(a)ᵀ μ`;
/// - `vee(hat a) = a`, `hat a = Σ aᵢ Eᵢ`, the Frobenius coordinates through the basis;
/// - `between(x, y) = x⁻¹ y`;
/// - `exp` against its series, and `log(exp a) = a` (for samples within the principal
///   branch: a sample past the cut locus is the caller's mistake);
/// - `dexp⁻¹` against finite differences of `exp`: the series RKMK4 uses
///   ([`dexp_inv_neg`]), held to its truncation (`|a|⁴/100`, on `a` scaled to at most 0.3).
///
/// Returns the number of checks made, or the first property that fails.
pub fn check_group<G, T, const N: usize, const M: usize>(
    samples: &[SVector<f64, M>],
    tol: f64,
) -> Result<usize, Failure>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let n = samples.len();
    let mut checks = Checks::default();
    let cast = |v: &SVector<f64, M>| SVector::<T, M>::from_fn(|i, _| real(v[i]));
    for i in 0..n {
        let (va, vb, vc) = (
            cast(&samples[i]),
            cast(&samples[(i + 1) % n]),
            cast(&samples[(i + 2) % n]),
        );
        let (x, y, z) = (G::exp(&va), G::exp(&vb), G::exp(&vc));
        let id = G::identity::<T>();
        let e = relative(&G::compose(&id, &x), &x).max(relative(&G::compose(&x, &id), &x));
        checks.check("identity", i, e, tol)?;
        let inv = G::inverse(&x);
        let e = relative(&G::compose(&x, &inv), &id).max(relative(&G::compose(&inv, &x), &id));
        checks.check("inverse", i, e, tol)?;
        let e = x
            .try_inverse()
            .map_or(f64::INFINITY, |m| relative(&inv, &m));
        checks.check("inverse equals the matrix inverse", i, e, tol)?;
        let l = G::compose(&G::compose(&x, &y), &z);
        let r = G::compose(&x, &G::compose(&y, &z));
        checks.check("associativity", i, relative(&l, &r), 10.0 * tol)?;
        let adab = G::adjoint(&x) * G::adjoint(&y);
        let e = relative(&adab, &G::adjoint(&G::compose(&x, &y)));
        checks.check("Ad(a)Ad(b) = Ad(ab)", i, e, 10.0 * tol)?;
        let lhs = x * G::hat(&vc) * inv;
        let e = relative(&lhs, &G::hat(&(G::adjoint(&x) * vc)));
        checks.check("X hat(v) X⁻¹ = hat(Ad_X v)", i, e, 10.0 * tol)?;
        let comm = G::hat(&va) * G::hat(&vb) - G::hat(&vb) * G::hat(&va);
        let e = relative(&(G::ad(&va) * vb), &G::vee(&comm));
        checks.check("ad against the commutator", i, e, tol)?;
        let e = relative(&G::ad_transpose_mul(&va, &vc), &G::ad(&va).tr_mul(&vc));
        checks.check("ad_transpose_mul equals ad(a)ᵀ μ", i, e, tol)?;
        checks.check(
            "vee(hat(v)) = v",
            i,
            relative(&G::vee(&G::hat(&va)), &va),
            tol,
        )?;
        let mut sum = SMatrix::<T, N, N>::zeros();
        for k in 0..M {
            sum += G::basis::<T>(k) * va[k];
        }
        checks.check("hat(v) = Σ vᵢ Eᵢ", i, relative(&sum, &G::hat(&va)), tol)?;
        let mm = x * z.transpose();
        let via_basis = SVector::<T, M>::from_fn(|k, _| mm.dot(&G::basis::<T>(k)));
        let e = relative(&G::frobenius_coordinates(&mm), &via_basis);
        checks.check("the Frobenius coordinates", i, e, tol)?;
        let e = relative(&G::between(&x, &y), &G::compose(&inv, &y));
        checks.check("between(x, y) = x⁻¹ y", i, e, 10.0 * tol)?;
        let e = relative(&x, &exp_series(&G::hat(&va)));
        checks.check("exp against its series", i, e, 10.0 * tol)?;
        checks.check("log(exp(v)) = v", i, relative(&G::log(&x), &va), 10.0 * tol)?;
        let e = dexp_error::<G, N, M>(&samples[i], &samples[(i + 1) % n]);
        checks.check("dexp⁻¹ against finite differences", i, e.0, e.1)?;
    }
    Ok(checks.0)
}

/// `dexp⁻¹_{−u}` of the body velocity finite differences give for the curve
/// `exp(u + s δ)` at `s = 0`, against `δ`; in `f64`, on `u` scaled so that `‖ad_u‖_F ≤ 0.3`.
/// Returns the error and what the truncated series and the differences allow: the first term
/// the series leaves out is `B₄/4! ad_u⁴ = −ad_u⁴/720`, so `‖ad_u‖_F⁴/500 + 10⁻⁷` (at most
/// 1.7·10⁻⁵).
fn dexp_error<G, const N: usize, const M: usize>(
    u: &SVector<f64, M>,
    delta: &SVector<f64, M>,
) -> (f64, f64)
where
    G: MatrixLieGroup<N, M>,
{
    let size = G::ad(u).norm();
    let u = if size > 0.3 { u * (0.3 / size) } else { *u };
    let h = 1e-5;
    let q = G::exp(&u);
    let ahead = G::exp(&(u + delta * h));
    let behind = G::exp(&(u - delta * h));
    // Q⁻¹ dQ/ds: the body velocity V of the curve, and dexp⁻¹_{−u}(V) = δ
    let v = G::vee(&(G::inverse(&q) * (ahead - behind) / (2.0 * h)));
    let back = dexp_inv_neg::<G, f64, N, M>(&u, &v);
    let scale = 1.0 + delta.amax();
    let err = (back - delta).amax() / scale;
    let r = G::ad(&u).norm();
    (err, r * r * r * r / 500.0 + 1e-7)
}

/// A symmetric positive-definite `D × D` matrix for the kit: `AᵀA/D + floor·I`, `A` from
/// [`sample`] (stream `seed`), off-diagonal terms included.
pub fn spd<const D: usize>(seed: u64, floor: f64) -> SMatrix<f64, D, D> {
    let a = SMatrix::<f64, D, D>::from_fn(|i, j| sample::<1>(seed, (i * D + j) as u64, 1.0)[0]);
    a.transpose() * a / (D as f64) + SMatrix::identity() * floor
}

/// Smooth, arbitrary inputs `(V(t), τ(t))` of the extended system from two samples.
fn free_input<const M: usize>(t: f64, v: &SVector<f64, M>, tau: &SVector<f64, M>) -> Input<f64, M> {
    Input {
        v: SVector::<f64, M>::from_fn(|i, _| v[i] + 0.7 * libm::sin(1.3 * t + i as f64 + v[0])),
        tau: SVector::<f64, M>::from_fn(|i, _| tau[i] * libm::cos(0.9 * t + 2.0 * i as f64)),
    }
}

/// The error-dynamics theorem (docs/maths.md, "Tracking error and its dynamics"): along two
/// trajectories of the extended system `Q̇ = Q hat(V)`, `ṗ = ad_Vᵀ p + τ` with arbitrary
/// smooth inputs (stream `seed`), `d/dt (Q_E, p_E) = f(E, (V_E, τ_E))` by central differences
/// (within `10⁻⁵` of the rate's size), `(V_E, τ_E) = ψ((Q_d, p_d)⁻¹, (V − V_d, τ − τ_d))`, and the
/// torque recovered from `τ_E` (within `10⁻⁹` relative). Returns the number of checks made.
pub fn check_error_dynamics<G, const N: usize, const M: usize>(seed: u64) -> Result<usize, Failure>
where
    G: MatrixLieGroup<N, M>,
{
    let mut checks = Checks::default();
    let s = |i: u64| sample::<M>(seed, i, 1.0);
    let start = |i: u64| Phase::<f64, N, M> {
        q: G::exp(&s(i)),
        p: s(i + 1),
    };
    let (h, steps) = (1e-3, 600);
    let (mut x, mut xd) = (start(0), start(2));
    let (va, ta, vb, tb) = (s(4), s(5), s(6), s(7));
    let field = |v: SVector<f64, M>, tau: SVector<f64, M>| {
        move |t: f64, _q: &SMatrix<f64, N, N>, p: &SVector<f64, M>| {
            let u = free_input::<M>(t, &v, &tau);
            (u.v, G::ad(&u.v).tr_mul(p) + u.tau)
        }
    };
    // the errors at the last two steps, with the time and the reference at the later one
    let mut older: Option<Phase<f64, N, M>> = None;
    let mut last: Option<(f64, Phase<f64, N, M>, Phase<f64, N, M>)> = None;
    for k in 0..=steps {
        let t = k as f64 * h;
        let e = tracking_error::<G, f64, N, M>(&x, &xd);
        // the centre of the difference is step k − 1
        if let (Some(before), Some((tc, xdc, ec))) = (older, last)
            && k % 97 == 2
        {
            let u = free_input::<M>(tc, &va, &ta);
            let ud = free_input::<M>(tc, &vb, &tb);
            let ue = error_input::<G, f64, N, M>(&xdc, &u, &ud);
            let rhs = vector_field::<G, f64, N, M>(&ec, &ue);
            let scale = 1.0 + rhs.q_dot.amax() + rhs.p_dot.amax();
            let fd_q = (e.q - before.q) / (2.0 * h);
            let fd_p = (e.p - before.p) / (2.0 * h);
            let err = (fd_q - rhs.q_dot).amax().max((fd_p - rhs.p_dot).amax()) / scale;
            checks.check("the error-dynamics theorem", k - 1, err, 1e-5)?;
            let diff = Input {
                v: u.v - ud.v,
                tau: u.tau - ud.tau,
            };
            let via_psi = input_action::<G, f64, N, M>(&xdc.inverse::<G>(), &diff);
            let err = relative(&via_psi.v, &ue.v).max(relative(&via_psi.tau, &ue.tau));
            checks.check(
                "the error inputs are ψ of the differences",
                k - 1,
                err,
                1e-9,
            )?;
            let tau = torque_from_error_torque::<G, f64, N, M>(&xdc, &ud.tau, &ue.v, &ue.tau);
            let err = relative(&tau, &u.tau);
            checks.check(
                "the torque recovered from the error torque",
                k - 1,
                err,
                1e-9,
            )?;
        }
        older = last.map(|l| l.2);
        last = Some((t, xd, e));
        x = rkmk4_step::<G, f64, _, N, M>(&x, t, h, field(va, ta));
        xd = rkmk4_step::<G, f64, _, N, M>(&xd, t, h, field(vb, tb));
    }
    Ok(checks.0)
}

/// The `L̇` docs/maths.md states for the law's error frame, at one state: `−eᵀK_d e` at the
/// reference ("The law at the reference"), `−V_Eᵀ K_d V_E` with `V_E = Ad_{Q_d} e` in world
/// axes ("The EqT law"), and for re-centring `−eᵀK_d e + ⟨grad Υ(Q_L), V_d − Ad_{Q_L⁻¹}V_d⟩`
/// ("World-frame invariance").
fn stated_rate<G, const N: usize, const M: usize>(
    c: &ControllerConfig<f64, N, M>,
    q: &SMatrix<f64, N, N>,
    q_d: &SMatrix<f64, N, N>,
    v_d: &SVector<f64, M>,
    e: &SVector<f64, M>,
) -> f64
where
    G: MatrixLieGroup<N, M>,
{
    match c.error_frame {
        ErrorFrame::Reference => -(c.kd * e).dot(e),
        ErrorFrame::World => {
            let ve = G::adjoint(q_d) * e;
            -(c.kd * ve).dot(&ve)
        }
        ErrorFrame::Recentred => {
            let q_l = G::between(q_d, q);
            let grad = potential_gradient::<G, f64, N, M>(&q_l, &c.k);
            -(c.kd * e).dot(e) + grad.dot(&(v_d - G::adjoint(&G::inverse(&q_l)) * v_d))
        }
    }
}

/// A state `(Q, V, Q_d, V_d)` of the continuous closed loop.
type LoopState<const N: usize, const M: usize> = (
    SMatrix<f64, N, N>,
    SVector<f64, M>,
    SMatrix<f64, N, N>,
    SVector<f64, M>,
);

/// A state's rate `(V, V̇, V_d, V̇_d)`, the configurations' rates as body velocities.
type LoopRate<const M: usize> = [SVector<f64, M>; 4];

/// The continuous closed loop of [`check_lyapunov`]: the law, the plant with the model's
/// inertia, and a reference with the constant body acceleration `accel`.
struct ContinuousLoop<G, const N: usize, const M: usize> {
    law: Controller<f64, G, N, M>,
    accel: SVector<f64, M>,
}

impl<G: MatrixLieGroup<N, M>, const N: usize, const M: usize> ContinuousLoop<G, N, M> {
    /// The reference at `(Q_d, V_d)` with the feed-forward `τ_d = I a − ad_{V_d}ᵀ I V_d` that
    /// gives it the acceleration `a`.
    fn desired(&self, x: &LoopState<N, M>) -> Desired<f64, N, M> {
        let inertia = self.law.config().inertia;
        Desired {
            q: x.2,
            p: inertia * x.3,
            v: x.3,
            tau: inertia * self.accel - G::ad(&x.3).tr_mul(&(inertia * x.3)),
        }
    }

    /// The state's rate, or `None` where the law refuses the state.
    fn rate(&self, x: &LoopState<N, M>) -> Option<LoopRate<M>> {
        let out = self.law.compute(&x.0, &x.1, &self.desired(x)).ok()?;
        let momentum = self.law.config().inertia * x.1;
        let v_dot = self.law.inertia_inverse() * (G::ad(&x.1).tr_mul(&momentum) + out.torque);
        Some([x.1, v_dot, x.3, self.accel])
    }

    /// `x` moved along the rate `k` for `h` seconds (configurations by the exponential).
    fn moved(x: &LoopState<N, M>, k: &LoopRate<M>, h: f64) -> LoopState<N, M> {
        (
            x.0 * G::exp(&(k[0] * h)),
            x.1 + k[1] * h,
            x.2 * G::exp(&(k[2] * h)),
            x.3 + k[3] * h,
        )
    }

    /// One RK4 step of `h` in the algebra (frozen-frame increments, fine at small `h`), or
    /// `None` where the law refuses a stage.
    fn step(&self, x: &LoopState<N, M>, h: f64) -> Option<LoopState<N, M>> {
        let k1 = self.rate(x)?;
        let k2 = self.rate(&Self::moved(x, &k1, h / 2.0))?;
        let k3 = self.rate(&Self::moved(x, &k2, h / 2.0))?;
        let k4 = self.rate(&Self::moved(x, &k3, h))?;
        let avg: LoopRate<M> =
            core::array::from_fn(|i| (k1[i] + k2[i] * 2.0 + k3[i] * 2.0 + k4[i]) / 6.0);
        Some(Self::moved(x, &avg, h))
    }
}

/// The law's Lyapunov function along the continuous closed loop
/// (docs/maths.md, "The EqT law"): the plant's inertia equal to the model's, the torque evaluated at every stage of
/// RK4 steps of `10⁻⁴` s (no hold), a reference with a constant body acceleration and the
/// feed-forward torque that carries it, from an initial error drawn from stream `seed`.
/// Over 4 000 steps, the central difference of `L` equals the stated rate for
/// `config.error_frame` within `10⁻⁵` of `1 + |L̇|`, and where that rate is a damping term
/// (`Reference`, `World`) `L` never rises by more than `10⁻¹⁰(1 + L₀)` in a step. The law is
/// EqT whatever `config.law` says, without a torque limit. Returns the number of checks made.
pub fn check_lyapunov<G, const N: usize, const M: usize>(
    config: &ControllerConfig<f64, N, M>,
    seed: u64,
) -> Result<usize, Failure>
where
    G: MatrixLieGroup<N, M>,
{
    let fail = |property: &'static str, sample: usize, error: f64, tolerance: f64| Failure {
        property,
        sample,
        error,
        tolerance,
    };
    let refused = |k: usize| {
        fail(
            "the law answers every state of the loop",
            k,
            f64::INFINITY,
            0.0,
        )
    };
    let c = ControllerConfig {
        law: Law::Eqt,
        torque_limit: None,
        ..*config
    };
    let law = Controller::<f64, G, N, M>::new(c).map_err(|_| {
        fail(
            "the controller accepts the configuration",
            0,
            f64::INFINITY,
            0.0,
        )
    })?;
    let s = |i: u64, scale: f64| sample::<M>(seed, i, scale);
    let sim = ContinuousLoop {
        law,
        accel: s(0, 0.5),
    };
    let h = 1e-4;
    let mut x: LoopState<N, M> = (G::exp(&s(1, 1.0)), s(2, 1.0), G::exp(&s(3, 1.0)), s(4, 1.0));
    let mut checks = Checks::default();
    // (L, stated L̇) at the last two steps, and L at the start
    let mut window = [(f64::NAN, f64::NAN); 2];
    let mut first = f64::NAN;
    for k in 0..4000 {
        let out = law
            .compute(&x.0, &x.1, &sim.desired(&x))
            .map_err(|_| refused(k))?;
        let l = out.lyapunov.total;
        let stated = stated_rate::<G, N, M>(&c, &x.0, &x.2, &x.3, &out.velocity_error);
        if k == 0 {
            first = l;
        }
        if k >= 2 {
            let measured = (l - window[0].0) / (2.0 * h);
            let expected = window[1].1;
            let err = (measured - expected).abs() / (1.0 + expected.abs());
            checks.check("L̇ is the stated rate", k - 1, err, 1e-5)?;
        }
        if k >= 1 && c.error_frame != ErrorFrame::Recentred {
            let rise = (l - window[1].0) / (1.0 + first.abs());
            checks.check("L never rises", k, rise, 1e-10)?;
        }
        window = [window[1], (l, stated)];
        x = sim.step(&x, h).ok_or(refused(k))?;
    }
    Ok(checks.0)
}

/// How many checks [`check`] made, by part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Report {
    /// [`check_group`] in `f64` and in `f32`.
    pub group: usize,
    /// [`check_error_dynamics`].
    pub error_dynamics: usize,
    /// [`check_lyapunov`], in each of the three error frames.
    pub lyapunov: usize,
}

/// The whole kit with eqtrack's tolerances: [`check_group`] on `samples` in `f64` within
/// `10⁻⁹` and in `f32` within `2·10⁻⁵`, [`check_error_dynamics`] and [`check_lyapunov`] with
/// `config` in each [`ErrorFrame`], all from stream `seed`.
pub fn check<G, const N: usize, const M: usize>(
    samples: &[SVector<f64, M>],
    config: &ControllerConfig<f64, N, M>,
    seed: u64,
) -> Result<Report, Failure>
where
    G: MatrixLieGroup<N, M>,
{
    let group =
        check_group::<G, f64, N, M>(samples, 1e-9)? + check_group::<G, f32, N, M>(samples, 2e-5)?;
    let error_dynamics = check_error_dynamics::<G, N, M>(seed)?;
    let mut lyapunov = 0;
    for frame in [
        ErrorFrame::Reference,
        ErrorFrame::World,
        ErrorFrame::Recentred,
    ] {
        let c = ControllerConfig {
            error_frame: frame,
            ..*config
        };
        lyapunov += check_lyapunov::<G, N, M>(&c, seed)?;
    }
    Ok(Report {
        group,
        error_dynamics,
        lyapunov,
    })
}

#[cfg(test)]
mod tests;
