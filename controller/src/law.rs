//! The control laws and the run-time [`Controller`]:
//! docs/maths.md, "The EqT law";
//! docs/maths.md, "The four SO(3) laws of the extended paper";
//! docs/maths.md, "The safe-mode law and saturation".

use crate::Real;
use crate::error::{Error, Quantity};
use crate::group::{GroupKind, MatrixLieGroup};
use crate::semidirect::Phase;
use crate::tracking::{Lyapunov, lyapunov, potential_gradient, tracking_error};
use crate::validate::{finite, spd_inverse, sum};
use core::marker::PhantomData;
use nalgebra::{SMatrix, SVector};

/// The control law, chosen at run time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Law {
    /// The equivariant tracking law (any group).
    Eqt,
    /// Geometric tracking (Bullo & Lewis 2005), SO(3) only.
    Gt,
    /// EqT without the gyroscopic term `ω̃×Iω_d`, SO(3) only.
    Nog,
    /// The asymmetric variant of the extended paper, SO(3) only.
    Asym,
}

impl Law {
    /// All laws, in the order of the extended paper.
    pub const ALL: [Law; 4] = [Law::Eqt, Law::Gt, Law::Nog, Law::Asym];

    /// The lower-case name (`"eqt"`, `"gt"`, `"nog"`, `"asym"`).
    pub fn name(self) -> &'static str {
        match self {
            Law::Eqt => "eqt",
            Law::Gt => "gt",
            Law::Nog => "nog",
            Law::Asym => "asym",
        }
    }

    /// Parses a lower-case name.
    pub fn from_name(name: &str) -> Option<Law> {
        Law::ALL.iter().copied().find(|l| l.name() == name)
    }

    /// Whether the law exists on the built-in group `group`.
    pub fn defined_for(self, group: GroupKind) -> bool {
        self == Law::Eqt || group == GroupKind::So3
    }

    /// Whether the law exists on the group type `G`: EqT on every group, the SO(3) closed
    /// forms (GT, nog, asym) on [`So3`](crate::So3) only, whoever else has n = m = 3.
    pub fn defined_on<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> bool {
        self == Law::Eqt || core::any::TypeId::of::<G>() == core::any::TypeId::of::<crate::So3>()
    }
}

/// Where the EqT law forms its tracking error and applies its gains
/// (docs/maths.md, "World-frame invariance").
///
/// A scenario's `[controller] error_frame`; the default is [`ErrorFrame::Reference`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ErrorFrame {
    /// The transported-error law: the left-invariant error `Q_L = Q_d⁻¹Q` and the velocity
    /// error `e = V − Ad_{Q_L⁻¹}V_d`, gains acting on both. Moving the world by any rigid
    /// motion leaves its wrench unchanged, and `L̇ = −eᵀK_d e` exactly ([`eqt_transported`]).
    #[default]
    Reference,
    /// The papers' law as written ([`eqt`]): the right-invariant error `Q_E = Q Q_d⁻¹` with
    /// gains in world axes. On SE(3) its damping grows with the reference's distance from
    /// the world origin.
    World,
    /// The papers' law evaluated in a world frame placed at the reference's current pose
    /// ([`eqt_recentred`]): invariant, and on SO(3) with isotropic gains equal to
    /// [`ErrorFrame::World`]; its `L̇` carries a term that damping does not dominate.
    Recentred,
}

impl ErrorFrame {
    /// Every error frame, the default first.
    pub const ALL: [ErrorFrame; 3] = [
        ErrorFrame::Reference,
        ErrorFrame::World,
        ErrorFrame::Recentred,
    ];

    /// The lower-case name used in scenario files (`"reference"`, `"world"`, `"recentred"`).
    pub fn name(self) -> &'static str {
        match self {
            ErrorFrame::Reference => "reference",
            ErrorFrame::World => "world",
            ErrorFrame::Recentred => "recentred",
        }
    }

    /// Parses a lower-case name.
    pub fn from_name(name: &str) -> Option<ErrorFrame> {
        ErrorFrame::ALL.iter().copied().find(|f| f.name() == name)
    }
}

/// The desired state at the current time, as the law needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Desired<T: Real, const N: usize, const M: usize> {
    /// `Q_d`.
    pub q: SMatrix<T, N, N>,
    /// `p_d = I V_d` (model inertia).
    pub p: SVector<T, M>,
    /// `V_d`.
    pub v: SVector<T, M>,
    /// The feedforward torque `τ_d(t)`.
    pub tau: SVector<T, M>,
}

/// The EqT law on any group (docs/maths.md, "The EqT law"):
///
/// ```text
/// τ_E = −ad_{A V_d}ᵀ p_E − K_d V_E − grad,   grad_i = ⟨Q_Eᵀ(Q_E − I)K, E_i⟩_F
/// τ   = τ_d + Aᵀ (τ_E − ad_{V_E}ᵀ A⁻ᵀ p_d)
/// ```
///
/// `p` is the momentum formed with the model inertia. Returns `τ` and the tracking error.
#[allow(clippy::too_many_arguments)]
pub fn eqt<G, T, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    v: &SVector<T, M>,
    p: &SVector<T, M>,
    desired: &Desired<T, N, M>,
    k: &SMatrix<T, N, N>,
    kd: &SMatrix<T, M, M>,
) -> (SVector<T, M>, Phase<T, N, M>)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    // Q_d⁻¹ and Ad_{Q_d⁻¹} once, for the error and the law (tracking_error forms the same)
    let qd_inv = G::inverse(&desired.q);
    let a_inv = G::adjoint(&qd_inv);
    let e = crate::tracking::error_from::<G, T, N, M>(q, p, &qd_inv, &a_inv, &desired.p);
    let a = G::adjoint(&desired.q);
    let v_e = a * (v - desired.v);
    let grad = potential_gradient::<G, T, N, M>(&e.q, k);
    let tau_e = -G::ad(&(a * desired.v)).tr_mul(&e.p) - kd * v_e - grad;
    let tau = desired.tau + a.tr_mul(&(tau_e - G::ad(&v_e).tr_mul(&a_inv.tr_mul(&desired.p))));
    (tau, e)
}

/// What the EqT law forms besides its torque: the tracking error and the velocity error
/// that the Lyapunov function reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Formed<T: Real, const N: usize, const M: usize> {
    /// The torque before saturation.
    pub torque: SVector<T, M>,
    /// The tracking error: `(Q_E, p_E)` in the world frame, `(Q_L, I e)` at the reference.
    pub error: Phase<T, N, M>,
    /// The velocity error: `V − V_d` in the world frame, `e = V − Ad_{Q_L⁻¹}V_d` at the
    /// reference ([`ErrorFrame::Reference`]).
    pub velocity_error: SVector<T, M>,
}

/// The transported-error law, [`ErrorFrame::Reference`]
/// (docs/maths.md, "The law at the reference"):
///
/// ```text
/// Q_L = Q_d⁻¹Q,   W = Ad_{Q_L⁻¹} V_d,   e = V − W,   V̇_d = I⁻¹(τ_d + ad_{V_d}ᵀ p_d)
/// τ = −ad_Wᵀ I V + I (Ad_{Q_L⁻¹} V̇_d − ad_e W) − K_d e − grad Υ(Q_L)
/// ```
///
/// with the left-trivialised gradient `grad_i = ⟨Q_Lᵀ(Q_L − I)K, E_i⟩_F`. Every quantity is
/// in the body frame, so moving the world (`Q ↦ TQ`, `Q_d ↦ TQ_d`) changes nothing; along the
/// continuous closed loop `L = ½eᵀIe + Υ(Q_L)` has `L̇ = −eᵀK_d e`. `p = I V` is the momentum
/// with the model inertia `I`, `inertia_inv` its inverse.
#[allow(clippy::too_many_arguments)]
pub fn eqt_transported<G, T, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    v: &SVector<T, M>,
    p: &SVector<T, M>,
    desired: &Desired<T, N, M>,
    k: &SMatrix<T, N, N>,
    kd: &SMatrix<T, M, M>,
    inertia: &SMatrix<T, M, M>,
    inertia_inv: &SMatrix<T, M, M>,
) -> Formed<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let AtReference { q_l, b, w, e } = AtReference::of::<G>(q, v, desired);
    let vd_dot = inertia_inv * (desired.tau + G::ad_transpose_mul(&desired.v, &desired.p));
    let grad = potential_gradient::<G, T, N, M>(&q_l, k);
    let torque =
        inertia * (b * vd_dot - G::ad(&e) * w) - G::ad_transpose_mul(&w, p) - kd * e - grad;
    Formed {
        torque,
        error: Phase {
            q: q_l,
            p: inertia * e,
        },
        velocity_error: e,
    }
}

/// The errors at the reference (docs/maths.md, "The law at the reference"): `Q_L = Q_d⁻¹Q`,
/// `B = Ad_{Q_L⁻¹}`, `W = B V_d` and `e = V − W`, formed in one place for the law and for
/// [`ControllerConfig::errors`].
struct AtReference<T: Real, const N: usize, const M: usize> {
    q_l: SMatrix<T, N, N>,
    b: SMatrix<T, M, M>,
    w: SVector<T, M>,
    e: SVector<T, M>,
}

impl<T: Real, const N: usize, const M: usize> AtReference<T, N, M> {
    #[inline(always)]
    fn of<G: MatrixLieGroup<N, M>>(
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
    ) -> Self {
        let q_l = G::between(&desired.q, q);
        let b = G::adjoint(&G::inverse(&q_l));
        let w = b * desired.v;
        AtReference {
            q_l,
            b,
            w,
            e: v - w,
        }
    }
}

/// The papers' law evaluated in a world frame placed at the reference's current pose,
/// [`ErrorFrame::Recentred`] (docs/maths.md, "Re-centring, the other invariant form"): [`eqt`] at
/// `Q' = Q_d⁻¹Q` with `Q_d' = I`, that is
///
/// ```text
/// τ = τ_d − ad_{V_d}ᵀ I ṽ − K_d ṽ − grad Υ(Q_L) − ad_ṽᵀ p_d,   ṽ = V − V_d,   Q_L = Q_d⁻¹Q
/// ```
pub fn eqt_recentred<G, T, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    v: &SVector<T, M>,
    p: &SVector<T, M>,
    desired: &Desired<T, N, M>,
    k: &SMatrix<T, N, N>,
    kd: &SMatrix<T, M, M>,
) -> (SVector<T, M>, Phase<T, N, M>)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let q_l = G::between(&desired.q, q);
    let at_identity = Desired {
        q: G::identity(),
        ..*desired
    };
    eqt::<G, T, N, M>(&q_l, v, p, &at_identity, k, kd)
}

/// Whether the papers' world-frame damping stays stable under the zero-order hold at the
/// reference pose `q_d` (docs/maths.md, "Where the world-frame law breaks"): held over a
/// period `h`, the damping alone maps `V ↦ (1 − h I⁻¹D) V` with `D = Ad_{Q_d}ᵀ K_d Ad_{Q_d}`,
/// stable while `h·λ_max(I⁻¹D) < 2`, that is while `2I − hD` is positive definite.
pub fn world_damping_holds<G, T, const N: usize, const M: usize>(
    q_d: &SMatrix<T, N, N>,
    inertia: &SMatrix<T, M, M>,
    kd: &SMatrix<T, M, M>,
    h: T,
) -> bool
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let a = G::adjoint(q_d);
    let d = a.tr_mul(&(kd * a));
    nalgebra::Cholesky::new(inertia * crate::real::<T>(2.0) - d * h).is_some()
}

/// Clamps each axis of `tau` to `[−l_i, l_i]` (no limit: unchanged); true when any axis was
/// clamped (docs/maths.md, "The safe-mode law and saturation"). The one saturation of the
/// project: the law, the safe mode and every plant use it.
pub fn saturate<T: Real, const M: usize>(
    tau: &mut SVector<T, M>,
    limit: Option<&SVector<T, M>>,
) -> bool {
    let mut clamped = false;
    if let Some(l) = limit {
        for i in 0..M {
            let c = tau[i].clamp(-l[i], l[i]);
            clamped |= c != tau[i];
            tau[i] = c;
        }
    }
    clamped
}

/// The safe-mode law: damping only, `τ = sat(−K_d V)` with the body velocity `V`
/// (docs/maths.md, "The safe-mode law and saturation"). It brings the body to rest instead of
/// tracking; a plant applies it when the controller's commands stop arriving.
pub fn safe_mode_torque<T: Real, const M: usize>(
    kd: &SMatrix<T, M, M>,
    v: &SVector<T, M>,
    limit: Option<&SVector<T, M>>,
) -> SVector<T, M> {
    let mut tau = -(kd * v);
    saturate(&mut tau, limit);
    tau
}

/// The SO(3) closed forms of the extended paper.
///
/// With `ω̃ = ω − ω_d`, `R_E = R R_dᵀ`, `prop = R_dᵀ (K R_E − R_Eᵀ K)^∨`.
pub mod so3 {
    use crate::{Real, real};
    use nalgebra::{Matrix3, Vector3};

    /// Everything an SO(3) closed-form law reads.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct So3LawInput<T: Real> {
        /// Attitude `R`.
        pub r: Matrix3<T>,
        /// Body angular velocity `ω`.
        pub omega: Vector3<T>,
        /// Desired attitude `R_d`.
        pub r_d: Matrix3<T>,
        /// Desired body angular velocity `ω_d`.
        pub omega_d: Vector3<T>,
        /// Feedforward torque `τ_d`.
        pub tau_d: Vector3<T>,
        /// Model inertia `I`.
        pub inertia: Matrix3<T>,
        /// Potential weight `K`.
        pub k: Matrix3<T>,
        /// Damping `K_d`.
        pub kd: Matrix3<T>,
    }

    /// `prop = R_dᵀ (K R_E − R_Eᵀ K)^∨`.
    pub fn proportional<T: Real>(x: &So3LawInput<T>) -> Vector3<T> {
        let r_e = x.r * x.r_d.transpose();
        let m = x.k * r_e - r_e.transpose() * x.k;
        x.r_d.tr_mul(&Vector3::new(m[(2, 1)], m[(0, 2)], m[(1, 0)]))
    }

    /// `R_dᵀ K_d R_d ω̃`.
    fn damping<T: Real>(x: &So3LawInput<T>, w_err: &Vector3<T>) -> Vector3<T> {
        x.r_d.tr_mul(&(x.kd * (x.r_d * w_err)))
    }

    /// EqT: `τ = τ_d + ω̃×Iω_d + ω_d×Iω̃ − R_dᵀK_dR_d ω̃ − prop`.
    pub fn eqt<T: Real>(x: &So3LawInput<T>) -> Vector3<T> {
        let we = x.omega - x.omega_d;
        x.tau_d + we.cross(&(x.inertia * x.omega_d)) + x.omega_d.cross(&(x.inertia * we))
            - damping(x, &we)
            - proportional(x)
    }

    /// GT: `τ = τ_d + ½I(ω×ω_d) + ½ω×Iω_d + ½ω_d×Iω − ω_d×Iω_d − K_d ω̃ − prop`.
    pub fn gt<T: Real>(x: &So3LawInput<T>) -> Vector3<T> {
        let h: T = real(0.5);
        let we = x.omega - x.omega_d;
        let iwd = x.inertia * x.omega_d;
        x.tau_d
            + x.inertia * x.omega.cross(&x.omega_d) * h
            + x.omega.cross(&iwd) * h
            + x.omega_d.cross(&(x.inertia * x.omega)) * h
            - x.omega_d.cross(&iwd)
            - x.kd * we
            - proportional(x)
    }

    /// nog: `τ = τ_d + ω_d×Iω̃ − R_dᵀK_dR_d ω̃ − prop`.
    pub fn nog<T: Real>(x: &So3LawInput<T>) -> Vector3<T> {
        let we = x.omega - x.omega_d;
        x.tau_d + x.omega_d.cross(&(x.inertia * we)) - damping(x, &we) - proportional(x)
    }

    /// asym: `τ = τ_d + ω̃×Iω_d + ½ω_d×Iω̃ + ½I(ω×ω_d) − R_dᵀK_dR_d ω̃ − prop`.
    pub fn asym<T: Real>(x: &So3LawInput<T>) -> Vector3<T> {
        let h: T = real(0.5);
        let we = x.omega - x.omega_d;
        x.tau_d
            + we.cross(&(x.inertia * x.omega_d))
            + x.omega_d.cross(&(x.inertia * we)) * h
            + x.inertia * x.omega.cross(&x.omega_d) * h
            - damping(x, &we)
            - proportional(x)
    }

    /// The closed form of `law` for a controller whose group is SO(3) (n = m = 3; the
    /// generic signature lets [`Controller`] call it for any group). `Controller::new` admits
    /// GT, nog and asym only on SO(3); for any other size this returns zero.
    pub(crate) fn dispatch<T: Real, const N: usize, const M: usize>(
        law: crate::Law,
        q: &nalgebra::SMatrix<T, N, N>,
        v: &nalgebra::SVector<T, M>,
        desired: &super::Desired<T, N, M>,
        c: &super::ControllerConfig<T, N, M>,
    ) -> nalgebra::SVector<T, M> {
        if N != 3 || M != 3 {
            return nalgebra::SVector::zeros();
        }
        fn m3<T: Real, const R: usize>(x: &nalgebra::SMatrix<T, R, R>) -> Matrix3<T> {
            Matrix3::from_fn(|i, j| x[(i, j)])
        }
        fn v3<T: Real, const R: usize>(x: &nalgebra::SVector<T, R>) -> Vector3<T> {
            Vector3::from_fn(|i, _| x[i])
        }
        let x = So3LawInput {
            r: m3(q),
            omega: v3(v),
            r_d: m3(&desired.q),
            omega_d: v3(&desired.v),
            tau_d: v3(&desired.tau),
            inertia: m3(&c.inertia),
            k: m3(&c.k),
            kd: m3(&c.kd),
        };
        let tau = match law {
            crate::Law::Eqt => eqt(&x),
            crate::Law::Gt => gt(&x),
            crate::Law::Nog => nog(&x),
            crate::Law::Asym => asym(&x),
        };
        nalgebra::SVector::from_fn(|i, _| tau[i])
    }

    /// The seed paper's SO(3) formula with scalar gains:
    /// `τ̃ = −k_v Ω̃ + (R_dΩ_d)×p_E − (k_p/2)(R_E − R_Eᵀ)^∨`, `τ = τ_d + R_dᵀτ̃ + (Ω − Ω_d)×p_d`.
    pub fn seed<T: Real>(x: &So3LawInput<T>, k_p: T, k_v: T) -> Vector3<T> {
        let r_e = x.r * x.r_d.transpose();
        let w_tilde = x.r_d * (x.omega - x.omega_d);
        let p = x.inertia * x.omega;
        let p_d = x.inertia * x.omega_d;
        let p_e = x.r_d * (p - p_d);
        let m = r_e - r_e.transpose();
        let tau_tilde = -w_tilde * k_v + (x.r_d * x.omega_d).cross(&p_e)
            - Vector3::new(m[(2, 1)], m[(0, 2)], m[(1, 0)]) * (k_p * real(0.5));
        x.tau_d + x.r_d.tr_mul(&tau_tilde) + (x.omega - x.omega_d).cross(&p_d)
    }
}

/// The configuration of a [`Controller`]: law, model inertia, gains, optional saturation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerConfig<T: Real, const N: usize, const M: usize> {
    /// The law.
    pub law: Law,
    /// Where EqT forms its error and applies its gains (the comparison laws GT, nog and asym
    /// are the extended paper's closed forms and always act in the world frame).
    pub error_frame: ErrorFrame,
    /// The model inertia `I` (m×m, symmetric positive definite).
    pub inertia: SMatrix<T, M, M>,
    /// The potential weight `K` (n×n, symmetric positive definite). A scenario file calls it
    /// `controller.kp` (the papers' `k_p`); `scenario::Scenario::controller_config` is the one
    /// place that maps the one to the other.
    pub k: SMatrix<T, N, N>,
    /// The damping `K_d` (m×m, symmetric positive definite).
    pub kd: SMatrix<T, M, M>,
    /// Optional per-axis torque limit (each entry > 0): `τ_i` is clamped to `[−l_i, l_i]`.
    pub torque_limit: Option<SVector<T, M>>,
}

/// What one evaluation of the controller returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawOutput<T: Real, const N: usize, const M: usize> {
    /// The torque to apply (after saturation), never non-finite.
    pub torque: SVector<T, M>,
    /// Whether any axis was clamped.
    pub saturated: bool,
    /// The Lyapunov function at this state (model inertia).
    pub lyapunov: Lyapunov<T>,
    /// The tracking error `(Q_E, p_E)`.
    pub error: Phase<T, N, M>,
    /// The velocity error: `V − V_d`, or `e = V − Ad_{Q_L⁻¹}V_d` with
    /// [`ErrorFrame::Reference`].
    pub velocity_error: SVector<T, M>,
    /// The disturbance observer's estimate `d̂_b` (body frame), subtracted from the law's
    /// torque (zero without the observer; see [`crate::disturbance`]).
    pub observer: SVector<T, M>,
    /// The integral's torque `−K_I z` (body frame), added to the law's torque (zero without
    /// the integral).
    pub integral: SVector<T, M>,
}

impl<T: Real, const N: usize, const M: usize> ControllerConfig<T, N, M> {
    /// The error frame in force: [`ControllerConfig::error_frame`] for EqT, the world frame
    /// for the comparison laws (their closed forms have no other).
    pub fn error_frame_in_force(&self) -> ErrorFrame {
        match self.law {
            Law::Eqt => self.error_frame,
            _ => ErrorFrame::World,
        }
    }

    /// The tracking error and the velocity error this configuration's law forms at the state
    /// `(q, v)` (the model inertia's momentum), as [`LawOutput::error`] and
    /// [`LawOutput::velocity_error`] report them: `(Q Q_d⁻¹, A⁻ᵀ(p − p_d))` and `V − V_d` in
    /// the world frame; `(Q_L, I e)` and `e = V − Ad_{Q_L⁻¹}V_d` at the reference;
    /// `(Q_L, I(V − V_d))` and `V − V_d` re-centred. Records and summaries use it, so they
    /// show what the law saw.
    pub fn errors<G: MatrixLieGroup<N, M>>(
        &self,
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
    ) -> (Phase<T, N, M>, SVector<T, M>) {
        let q_l = || G::between(&desired.q, q);
        match self.error_frame_in_force() {
            ErrorFrame::World => {
                let state = Phase {
                    q: *q,
                    p: self.inertia * v,
                };
                let reference = Phase {
                    q: desired.q,
                    p: desired.p,
                };
                (
                    tracking_error::<G, T, N, M>(&state, &reference),
                    v - desired.v,
                )
            }
            ErrorFrame::Reference => {
                let AtReference { q_l, e, .. } = AtReference::of::<G>(q, v, desired);
                (
                    Phase {
                        q: q_l,
                        p: self.inertia * e,
                    },
                    e,
                )
            }
            ErrorFrame::Recentred => {
                let e = v - desired.v;
                (
                    Phase {
                        q: q_l(),
                        p: self.inertia * e,
                    },
                    e,
                )
            }
        }
    }
}

/// A validated controller: gains and inertia are checked once, here; the per-cycle path
/// checks only that the state is finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Controller<T: Real, G, const N: usize, const M: usize> {
    config: ControllerConfig<T, N, M>,
    inertia_inv: SMatrix<T, M, M>,
    _group: PhantomData<G>,
}

impl<T, G, const N: usize, const M: usize> Controller<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// Validates the configuration (SPD inertia and gains, positive finite limits, law defined
    /// on the group) and builds the controller.
    pub fn new(config: ControllerConfig<T, N, M>) -> Result<Self, Error> {
        if !config.law.defined_on::<G, N, M>() {
            return Err(Error::LawNotDefined {
                law: config.law,
                group: G::NAME,
            });
        }
        let inertia_inv = spd_inverse(Quantity::Inertia, &config.inertia)?;
        spd_inverse(Quantity::PotentialGain, &config.k)?;
        spd_inverse(Quantity::DampingGain, &config.kd)?;
        if let Some(l) = &config.torque_limit {
            finite(Quantity::TorqueLimit, l)?;
            if l.iter().any(|x| *x <= T::zero()) {
                return Err(Error::NotPositive(Quantity::TorqueLimit));
            }
        }
        Ok(Controller {
            config,
            inertia_inv,
            _group: PhantomData,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &ControllerConfig<T, N, M> {
        &self.config
    }

    /// `I⁻¹` of the model inertia.
    pub fn inertia_inverse(&self) -> &SMatrix<T, M, M> {
        &self.inertia_inv
    }

    /// The torque before saturation, the tracking error and the velocity error, for the
    /// measured configuration `q` and body velocity `v` (no checks; see
    /// [`Controller::compute`]).
    pub fn raw_torque(
        &self,
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
    ) -> Formed<T, N, M> {
        let c = &self.config;
        let p = c.inertia * v;
        let world = |(torque, error)| Formed {
            torque,
            error,
            velocity_error: v - desired.v,
        };
        match (c.law, c.error_frame) {
            (Law::Eqt, ErrorFrame::Reference) => eqt_transported::<G, T, N, M>(
                q,
                v,
                &p,
                desired,
                &c.k,
                &c.kd,
                &c.inertia,
                &self.inertia_inv,
            ),
            (Law::Eqt, ErrorFrame::World) => {
                world(eqt::<G, T, N, M>(q, v, &p, desired, &c.k, &c.kd))
            }
            (Law::Eqt, ErrorFrame::Recentred) => {
                world(eqt_recentred::<G, T, N, M>(q, v, &p, desired, &c.k, &c.kd))
            }
            (law, _) => {
                let (error, velocity_error) = c.errors::<G>(q, v, desired);
                Formed {
                    torque: so3::dispatch(law, q, v, desired, c),
                    error,
                    velocity_error,
                }
            }
        }
    }

    /// The safe-mode torque `sat(−K_d V)` with this controller's damping and limit
    /// (docs/maths.md, "The safe-mode law and saturation"); see [`safe_mode_torque`].
    pub fn safe_mode_torque(&self, v: &SVector<T, M>) -> SVector<T, M> {
        safe_mode_torque(&self.config.kd, v, self.config.torque_limit.as_ref())
    }

    /// [`Controller::raw_torque`] between the checks: the state and the reference finite
    /// before, the torque finite after. Inlined into its two callers: returned through a
    /// `Result`, the error and the torque were copied twice more (on a Cortex-M4F some
    /// hundreds of instructions of `memcpy` a cycle, BENCHMARKS.md section 17).
    #[inline(always)]
    pub(crate) fn checked_raw_torque(
        &self,
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
    ) -> Result<Formed<T, N, M>, Error> {
        // one sum of every input: finite, every entry is (the usual case); else each input
        // is looked at in turn, to name the one that is not
        let inputs = sum(q)
            + sum(v)
            + sum(&desired.q)
            + sum(&desired.p)
            + sum(&desired.v)
            + sum(&desired.tau);
        if !inputs.is_finite() {
            finite(Quantity::State, q)?;
            finite(Quantity::State, v)?;
            finite(Quantity::Reference, &desired.q)?;
            finite(Quantity::Reference, &desired.p)?;
            finite(Quantity::Reference, &desired.v)?;
            finite(Quantity::Reference, &desired.tau)?;
        }
        let formed = self.raw_torque(q, v, desired);
        finite(Quantity::Torque, &formed.torque)?;
        Ok(formed)
    }

    /// One evaluation of the law: checks the state is finite, computes the torque, saturates
    /// it, and evaluates the Lyapunov function. Never returns a non-finite torque.
    ///
    /// On the desired trajectory the tracking error is the identity, `L = 0`, and the torque
    /// is the feedforward; off it, the law pulls back, and a NaN state is refused:
    ///
    /// ```
    /// use eqtrack_controller::group::{MatrixLieGroup, So3};
    /// use eqtrack_controller::law::Desired;
    /// use eqtrack_controller::{Controller, ControllerConfig, ErrorFrame, Law};
    /// use nalgebra::{Matrix3, Vector3};
    ///
    /// let inertia = Matrix3::new(0.824, 0.0, 0.12, 0.0, 1.135, 0.0, 0.12, 0.0, 1.759);
    /// let law = Controller::<f64, So3, 3, 3>::new(ControllerConfig {
    ///     law: Law::Eqt,
    ///     error_frame: ErrorFrame::Reference,
    ///     inertia,
    ///     k: Matrix3::identity() * 0.5,
    ///     kd: Matrix3::identity() * 0.5,
    ///     torque_limit: None,
    /// })?;
    /// let q_d = So3::exp(&Vector3::new(0.1, -0.2, 0.3));
    /// let v_d = Vector3::new(0.5, 0.0, -0.25);
    /// let desired = Desired { q: q_d, p: inertia * v_d, v: v_d, tau: Vector3::new(0.1, 0.2, 0.3) };
    ///
    /// let on = law.compute(&q_d, &v_d, &desired)?;
    /// assert!(on.lyapunov.total.abs() < 1e-15);
    /// assert!((on.torque - desired.tau).norm() < 1e-12);
    ///
    /// let off = law.compute(&(q_d * So3::exp(&Vector3::new(0.0, 0.0, 0.5))), &v_d, &desired)?;
    /// assert!(off.lyapunov.total > 0.0);
    /// assert!(law.compute(&q_d, &Vector3::new(f64::NAN, 0.0, 0.0), &desired).is_err());
    /// # Ok::<(), eqtrack_controller::Error>(())
    /// ```
    pub fn compute(
        &self,
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
    ) -> Result<LawOutput<T, N, M>, Error> {
        let Formed {
            torque: mut tau,
            error,
            velocity_error,
        } = self.checked_raw_torque(q, v, desired)?;
        let saturated = saturate(&mut tau, self.config.torque_limit.as_ref());
        let lyapunov = lyapunov(
            &error.q,
            &velocity_error,
            &self.config.inertia,
            &self.config.k,
        );
        Ok(LawOutput {
            torque: tau,
            saturated,
            lyapunov,
            error,
            velocity_error,
            observer: SVector::zeros(),
            integral: SVector::zeros(),
        })
    }
}
