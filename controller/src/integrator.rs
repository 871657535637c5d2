//! RKMK4 on the group and the physical rigid body (docs/maths.md, "Integrating on the group").

use crate::error::{Error, Quantity};
use crate::group::MatrixLieGroup;
use crate::semidirect::Phase;
use crate::validate::{finite, spd_inverse};
use crate::{Real, real};
use nalgebra::{SMatrix, SVector};

/// `dexp⁻¹_{−u}(V) = V + ½[u,V] + (1/12)[u,[u,V]]`, truncated after the terms RKMK4 needs.
///
/// This is the algebra equation for the body-velocity form `Q̇ = Q·hat(V)` (velocity on the
/// right). The `−½` variant belongs to `Q̇ = hat(V)·Q` and would cost two orders.
pub fn dexp_inv_neg<G, T, const N: usize, const M: usize>(
    u: &SVector<T, M>,
    v: &SVector<T, M>,
) -> SVector<T, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
{
    let ad = G::ad(u);
    let uv = ad * v;
    v + uv * real::<T>(0.5) + ad * uv * real::<T>(1.0 / 12.0)
}

/// One RKMK4 step of length `h` from time `t` for the system
/// `Q̇ = Q·hat(V)`, `ṗ = P(t, Q, p)` with `(V, P) = field(t, Q, p)`.
///
/// `Q(t+h) = Q(t)·exp(hat(u))`, with `u` integrated by classical RK4 in the algebra through
/// [`dexp_inv_neg`]; `p` by classical RK4.
pub fn rkmk4_step<G, T, F, const N: usize, const M: usize>(
    x: &Phase<T, N, M>,
    t: T,
    h: T,
    field: F,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
    F: FnMut(T, &SMatrix<T, N, N>, &SVector<T, M>) -> (SVector<T, M>, SVector<T, M>),
{
    rkmk4::<G, T, F, N, M, true>(x, t, h, field)
}

/// [`rkmk4_step`]; when `STAGE_Q` is false the field does not read its configuration
/// argument (it is handed `Q(t)` at every stage), so the stages' configurations
/// `Q·exp(hat(u_i))` are not formed: the same numbers, three exponentials fewer per step.
fn rkmk4<G, T, F, const N: usize, const M: usize, const STAGE_Q: bool>(
    x: &Phase<T, N, M>,
    t: T,
    h: T,
    mut field: F,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
    F: FnMut(T, &SMatrix<T, N, N>, &SVector<T, M>) -> (SVector<T, M>, SVector<T, M>),
{
    let none = SVector::<T, 0>::zeros();
    rkmk4_carrying::<G, T, _, N, M, 0, STAGE_Q>(x, &none, t, h, |s, q, p, _| {
        let (v, pd) = field(s, q, p);
        (v, pd, none)
    })
    .0
}

/// One RKMK4 step of length `h` from time `t` that carries `E` more states `e` in a vector
/// space beside `(Q, p)`, for the system `Q̇ = Q·hat(V)`, `ṗ = P`, `ė = Ė` with
/// `(V, P, Ė) = field(t, Q, p, e)`: `Q` and `p` as [`rkmk4_step`] moves them, `e` by classical
/// RK4 with the same stages (docs/maths.md, "Reaction wheels": the wheels' momenta).
pub fn rkmk4_extended<G, T, F, const N: usize, const M: usize, const E: usize>(
    x: &Phase<T, N, M>,
    e: &SVector<T, E>,
    t: T,
    h: T,
    field: F,
) -> (Phase<T, N, M>, SVector<T, E>)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
    F: FnMut(
        T,
        &SMatrix<T, N, N>,
        &SVector<T, M>,
        &SVector<T, E>,
    ) -> (SVector<T, M>, SVector<T, M>, SVector<T, E>),
{
    rkmk4_carrying::<G, T, F, N, M, E, true>(x, e, t, h, field)
}

/// [`rkmk4_extended`], with [`rkmk4`]'s `STAGE_Q`: the one body of both (with `E = 0` the
/// carried state adds no operation on `Q` or `p`, so their numbers are [`rkmk4`]'s).
fn rkmk4_carrying<G, T, F, const N: usize, const M: usize, const E: usize, const STAGE_Q: bool>(
    x: &Phase<T, N, M>,
    e: &SVector<T, E>,
    t: T,
    h: T,
    mut field: F,
) -> (Phase<T, N, M>, SVector<T, E>)
where
    G: MatrixLieGroup<N, M>,
    T: Real,
    F: FnMut(
        T,
        &SMatrix<T, N, N>,
        &SVector<T, M>,
        &SVector<T, E>,
    ) -> (SVector<T, M>, SVector<T, M>, SVector<T, E>),
{
    let stage_q = |u: &SVector<T, M>| {
        if STAGE_Q { x.q * G::exp(u) } else { x.q }
    };
    let half = h * real(0.5);
    let (v1, pd1, ed1) = field(t, &x.q, &x.p, e);
    let k1 = v1;

    let u2 = k1 * half;
    let (v2, pd2, ed2) = field(
        t + half,
        &stage_q(&u2),
        &(x.p + pd1 * half),
        &(e + ed1 * half),
    );
    let k2 = dexp_inv_neg::<G, T, N, M>(&u2, &v2);

    let u3 = k2 * half;
    let (v3, pd3, ed3) = field(
        t + half,
        &stage_q(&u3),
        &(x.p + pd2 * half),
        &(e + ed2 * half),
    );
    let k3 = dexp_inv_neg::<G, T, N, M>(&u3, &v3);

    let u4 = k3 * h;
    let (v4, pd4, ed4) = field(t + h, &stage_q(&u4), &(x.p + pd3 * h), &(e + ed3 * h));
    let k4 = dexp_inv_neg::<G, T, N, M>(&u4, &v4);

    let sixth = h / real(6.0);
    let two: T = real(2.0);
    let u = (k1 + k2 * two + k3 * two + k4) * sixth;
    (
        Phase {
            q: x.q * G::exp(&u),
            p: x.p + (pd1 + pd2 * two + pd3 * two + pd4) * sixth,
        },
        e + (ed1 + ed2 * two + ed3 * two + ed4) * sixth,
    )
}

/// One RKMK4 step of the physical system `Q̇ = Q·hat(V)`, `ṗ = ad_Vᵀp + τ(t)`, `V = I⁻¹p`
/// (docs/maths.md, "The objects"), for a torque given as a function of time (use a constant
/// closure for zero-order hold).
pub fn physical_step<G, T, F, const N: usize, const M: usize>(
    x: &Phase<T, N, M>,
    t: T,
    h: T,
    inertia_inv: &SMatrix<T, M, M>,
    torque: F,
) -> Phase<T, N, M>
where
    G: MatrixLieGroup<N, M>,
    T: Real,
    F: Fn(T) -> SVector<T, M>,
{
    // The field does not depend on Q: its stages need no configuration.
    rkmk4::<G, T, _, N, M, false>(x, t, h, |s, _q, p| {
        let v = inertia_inv * p;
        (v, G::ad(&v).tr_mul(p) + torque(s))
    })
}

/// A rigid body on the group: the plant. Holds `(Q, p)` and its (true) inertia.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBody<T: Real, G, const N: usize, const M: usize> {
    state: Phase<T, N, M>,
    inertia: SMatrix<T, M, M>,
    inertia_inv: SMatrix<T, M, M>,
    _group: core::marker::PhantomData<G>,
}

impl<T, G, const N: usize, const M: usize> RigidBody<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// A body with inertia `inertia` (SPD) at configuration `q` with body velocity `v`.
    pub fn new(
        inertia: SMatrix<T, M, M>,
        q: SMatrix<T, N, N>,
        v: SVector<T, M>,
    ) -> Result<Self, Error> {
        let inertia_inv = spd_inverse(Quantity::Inertia, &inertia)?;
        finite(Quantity::State, &q)?;
        finite(Quantity::State, &v)?;
        Ok(RigidBody {
            state: Phase { q, p: inertia * v },
            inertia,
            inertia_inv,
            _group: core::marker::PhantomData,
        })
    }

    /// The configuration `Q`.
    pub fn configuration(&self) -> &SMatrix<T, N, N> {
        &self.state.q
    }

    /// The body velocity `V = I⁻¹p` (what a gyro measures).
    pub fn velocity(&self) -> SVector<T, M> {
        self.inertia_inv * self.state.p
    }

    /// The body acceleration `V̇ = I⁻¹(ad_Vᵀ p + τ)` under the torque `τ`: the
    /// Euler–Poincaré equations (docs/maths.md, "The objects") at the current state.
    pub fn velocity_rate(&self, torque: &SVector<T, M>) -> SVector<T, M> {
        let v = self.velocity();
        self.inertia_inv * (G::ad(&v).tr_mul(&self.state.p) + torque)
    }

    /// The state `(Q, p)`.
    pub fn state(&self) -> &Phase<T, N, M> {
        &self.state
    }

    /// The body's inertia.
    pub fn inertia(&self) -> &SMatrix<T, M, M> {
        &self.inertia
    }

    /// Advances by `period` with the body torque held constant and a wrench `world` constant
    /// in world axes at the body's origin (docs/maths.md, "Disturbance rejection"): the body
    /// receives `τ + Rᵀ·world` (per 3-block), `R` the rotation at each RKMK4 stage. On a
    /// group without an [`attitude`](MatrixLieGroup::attitude) world and body axes are one:
    /// the body receives `τ + world`.
    pub fn advance_with_world(
        &mut self,
        torque: &SVector<T, M>,
        world: &SVector<T, M>,
        period: T,
        substeps: usize,
    ) {
        let h = period / real(substeps as f64);
        let inv = self.inertia_inv;
        for _ in 0..substeps {
            self.state = rkmk4_step::<G, T, _, N, M>(&self.state, T::zero(), h, |_, q, p| {
                let v = inv * p;
                let body = match G::attitude(q) {
                    Some(r) => G::rotate_coordinates(&r.transpose(), world),
                    None => *world,
                };
                (v, G::ad(&v).tr_mul(p) + torque + body)
            });
        }
    }

    /// Advances by `period` in `substeps` RKMK4 steps under the body wrench
    /// `wrench(s, Q, V)`, evaluated at every stage: `s` the time since the start of the period,
    /// `Q` and `V = I⁻¹p` the stage's configuration and body velocity (docs/maths.md,
    /// "Vehicle physics": gravity, buoyancy and drag depend on the state, an actuator's lag
    /// on the time).
    pub fn advance_with<F>(&mut self, period: T, substeps: usize, mut wrench: F)
    where
        F: FnMut(T, &SMatrix<T, N, N>, &SVector<T, M>) -> SVector<T, M>,
    {
        let mut none = SVector::<T, 0>::zeros();
        self.advance_carrying(period, substeps, &mut none, |s, q, v, _| {
            (wrench(s, q, v), SVector::zeros())
        });
    }

    /// [`RigidBody::advance_with`] carrying `E` more states `e` beside the body, integrated
    /// with the same RK4 stages: `(wrench, ė) = field(s, Q, V, e)` at every stage
    /// (docs/maths.md, "Reaction wheels": the wheels' momenta and the torques they put on the
    /// body).
    pub fn advance_carrying<F, const E: usize>(
        &mut self,
        period: T,
        substeps: usize,
        e: &mut SVector<T, E>,
        mut field: F,
    ) where
        F: FnMut(
            T,
            &SMatrix<T, N, N>,
            &SVector<T, M>,
            &SVector<T, E>,
        ) -> (SVector<T, M>, SVector<T, E>),
    {
        let h = period / real(substeps as f64);
        let inv = self.inertia_inv;
        for i in 0..substeps {
            let t0 = h * real(i as f64);
            (self.state, *e) =
                rkmk4_extended::<G, T, _, N, M, E>(&self.state, e, t0, h, |s, q, p, x| {
                    let v = inv * p;
                    let (w, xd) = field(s, q, &v, x);
                    (v, G::ad(&v).tr_mul(p) + w, xd)
                });
        }
    }

    /// Advances by `period` with the torque held constant (zero-order hold), in `substeps`
    /// RKMK4 steps.
    pub fn advance(&mut self, torque: &SVector<T, M>, period: T, substeps: usize) {
        let h = period / real(substeps as f64);
        let tau = *torque;
        for _ in 0..substeps {
            self.state = physical_step::<G, T, _, N, M>(
                &self.state,
                T::zero(),
                h,
                &self.inertia_inv,
                |_| tau,
            );
        }
    }
}
