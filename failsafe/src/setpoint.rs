//! What an engaged action flies (docs/failsafe.md, "What each action flies"): the desired state
//! the law is handed in place of the reference. [`Supervised`] wraps a reference; while
//! nominal it is the reference, bit for bit.

use crate::Action;
use core::marker::PhantomData;
use eqtrack_controller::Real;
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::group::so3::log_so3;
use eqtrack_controller::law::Desired;
use eqtrack_controller::reference::Trajectory;
use nalgebra::{SMatrix, SVector, Vector3};

/// The speeds the vertical actions fly at (m/s, positive).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rates<T> {
    /// `descend`'s.
    pub descend: T,
    /// `surface`'s.
    pub ascend: T,
}

/// What is flown.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Flying<T: Real, const N: usize> {
    /// The reference.
    Reference,
    /// A set-point at the pose the action engaged at.
    Hold(SMatrix<T, N, N>),
    /// The estimate itself at rest: the law's damping alone, `τ = −K_d V`.
    Damp,
    /// The pose it engaged at, moving along world z at `rate` (signed) from `t0`.
    Vertical(SMatrix<T, N, N>, T, T),
    /// Rising at `rate` from the height and attitude it engaged at, horizontally wherever the
    /// estimate is, at its horizontal velocity.
    Surface(SMatrix<T, N, N>, T, T),
}

/// What an engaged action flies, without the reference it stands in for: the state an action
/// engaged with, the model inertia and the rates. Allocation-free. [`Supervised`] wraps a
/// reference with one (the in-process simulation); a controller that keeps its reference apart
/// (the pair's responder) holds one beside it and asks [`Setpoint::desired`] for the state to
/// fly, handing it the reference's.
#[derive(Debug, Clone)]
pub struct Setpoint<T: Real, G, const N: usize, const M: usize> {
    inertia: SMatrix<T, M, M>,
    rates: Rates<T>,
    flying: Flying<T, N>,
    estimate: (SMatrix<T, N, N>, SVector<T, M>),
    group: PhantomData<G>,
}

impl<T, G, const N: usize, const M: usize> Setpoint<T, G, N, M>
where
    T: Real,
    G: BuiltinGroup<N, M>,
{
    /// Flying the reference, with the model inertia (for `p_d = I V_d`) and the rates; `q` is
    /// the estimate until one is observed.
    pub fn new(q: SMatrix<T, N, N>, inertia: SMatrix<T, M, M>, rates: Rates<T>) -> Self {
        Setpoint {
            inertia,
            rates,
            flying: Flying::Reference,
            estimate: (q, SVector::zeros()),
            group: PhantomData,
        }
    }

    /// The estimate the law is handed this cycle (the pose an action engages at).
    pub fn observe(&mut self, q: &SMatrix<T, N, N>, v: &SVector<T, M>) {
        self.estimate = (*q, *v);
    }

    /// Flies `action` from time `t0` on (`None` or `warn`: the reference), starting from the
    /// last estimate observed. The vertical actions exist on SE(3) only (elsewhere they hold).
    pub fn engage(&mut self, action: Option<Action>, t0: T) {
        let q = self.estimate.0;
        let se3 = N == 4 && M == 6;
        self.flying = match action {
            None | Some(Action::Warn) => Flying::Reference,
            Some(Action::Hold) => Flying::Hold(q),
            Some(Action::Damp | Action::Disarm) => Flying::Damp,
            Some(Action::Descend) if se3 => Flying::Vertical(q, t0, -self.rates.descend),
            Some(Action::Surface) if se3 => Flying::Surface(q, t0, self.rates.ascend),
            Some(Action::Descend | Action::Surface) => Flying::Hold(q),
        };
    }

    /// The desired state flown at time `t`: the reference's `reference` while it is flown
    /// (bit for bit), else the engaged action's set-point
    /// (docs/failsafe.md, "What each action flies").
    pub fn desired(&self, reference: &Desired<T, N, M>, t: T) -> Desired<T, N, M> {
        match self.flying {
            Flying::Reference => *reference,
            Flying::Hold(q) => Self::at_rest(q),
            Flying::Damp => Self::at_rest(self.estimate.0),
            Flying::Vertical(q0, t0, rate) => {
                let dz = rate * (t - t0);
                let mut q = q0;
                q[(2, N - 1)] += dz;
                self.moving(q, &Vector3::new(T::zero(), T::zero(), rate))
            }
            Flying::Surface(q0, t0, rate) => {
                let (q_hat, v_hat) = self.estimate;
                let mut q = q0;
                q[(0, N - 1)] = q_hat[(0, N - 1)];
                q[(1, N - 1)] = q_hat[(1, N - 1)];
                q[(2, N - 1)] += rate * (t - t0);
                // the estimate's world velocity, its horizontal part kept: no horizontal effort
                let lin = Vector3::new(v_hat[3], v_hat[4], v_hat[5]);
                let world = G::rotation(&q_hat) * lin;
                self.moving(q, &Vector3::new(world[0], world[1], rate))
            }
        }
    }

    /// One tick of `monitor` at time `t`, before the law: the estimate `(q̂, v̂)` observed, the
    /// tracking error measured against what is flown (`reference`, or the engaged action's
    /// set-point, which does not run away while the reference goes on without the vehicle),
    /// the manager stepped with the other causes' `flags`, and on a transition the new action
    /// engaged. Returns the transition, if any.
    pub fn supervise(
        &mut self,
        monitor: &mut crate::monitor::Monitor<T>,
        (q_hat, v_hat): (&SMatrix<T, N, N>, &SVector<T, M>),
        (reference, t): (&Desired<T, N, M>, T),
        flags: crate::monitor::Flags,
    ) -> Option<crate::Transition> {
        self.observe(q_hat, v_hat);
        let flown = self.desired(reference, t);
        let errors = tracking_errors::<T, G, N, M>(q_hat, &flown.q);
        let transition = monitor.tick(errors, flags);
        if let Some(tr) = transition {
            self.engage(tr.to.action(), t);
        }
        transition
    }

    /// The desired state at rest at `q`.
    fn at_rest(q: SMatrix<T, N, N>) -> Desired<T, N, M> {
        Desired {
            q,
            p: SVector::zeros(),
            v: SVector::zeros(),
            tau: SVector::zeros(),
        }
    }

    /// The desired state at pose `q` moving with world-frame linear velocity `w` (SE(3)): the
    /// body twist `V_d = (0, Rᵀw)`, `p_d = I V_d`, and the feedforward of a constant twist,
    /// `τ_d = −ad_{V_d}ᵀ p_d` (docs/maths.md, "Desired trajectories as inputs", with `V̇_d = 0`).
    fn moving(&self, q: SMatrix<T, N, N>, w: &Vector3<T>) -> Desired<T, N, M> {
        let r = G::rotation(&q);
        let body = r.tr_mul(w);
        let mut v = SVector::<T, M>::zeros();
        for i in 0..3 {
            v[3 + i] = body[i];
        }
        let p = self.inertia * v;
        Desired {
            q,
            p,
            v,
            tau: -G::ad_transpose_mul(&v, &p),
        }
    }
}

/// A reference under the failsafe manager: the reference while nominal, the engaged action's
/// set-point otherwise. Allocation-free; the caller hands it each cycle's estimate and steps
/// the manager through [`Supervised::supervise`] before the law runs.
#[derive(Debug, Clone)]
pub struct Supervised<T: Real, G, R, const N: usize, const M: usize> {
    inner: R,
    setpoint: Setpoint<T, G, N, M>,
}

impl<T, G, R, const N: usize, const M: usize> Supervised<T, G, R, N, M>
where
    T: Real,
    G: BuiltinGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    /// `inner` under supervision, with the model inertia (for `p_d = I V_d`) and the rates.
    pub fn new(inner: R, inertia: SMatrix<T, M, M>, rates: Rates<T>) -> Self {
        let q = inner.desired().q;
        Supervised {
            inner,
            setpoint: Setpoint::new(q, inertia, rates),
        }
    }

    /// The reference it wraps.
    pub fn inner(&self) -> &R {
        &self.inner
    }

    /// One tick of `monitor` before the law ([`Setpoint::supervise`] at the reference's time).
    pub fn supervise(
        &mut self,
        monitor: &mut crate::monitor::Monitor<T>,
        estimate: (&SMatrix<T, N, N>, &SVector<T, M>),
        flags: crate::monitor::Flags,
    ) -> Option<crate::Transition> {
        let reference = self.inner.desired();
        let t = self.inner.time();
        self.setpoint
            .supervise(monitor, estimate, (&reference, t), flags)
    }

    /// The estimate the law is handed this cycle (see [`Setpoint::observe`]), for a caller
    /// that follows a manager run elsewhere.
    pub fn observe(&mut self, q: &SMatrix<T, N, N>, v: &SVector<T, M>) {
        self.setpoint.observe(q, v);
    }

    /// Flies `action` from now on (see [`Setpoint::engage`]).
    pub fn engage(&mut self, action: Option<Action>) {
        self.setpoint.engage(action, self.inner.time());
    }
}

/// The attitude error `∠(R_dᵀR)` (rad, in `[0, π]`) and, on SE(3), the position error
/// `‖x − x_d‖` (m; 0 on SO(3)) of pose `q` against the desired `q_d`.
pub fn tracking_errors<T, G, const N: usize, const M: usize>(
    q: &SMatrix<T, N, N>,
    q_d: &SMatrix<T, N, N>,
) -> (T, T)
where
    T: Real,
    G: BuiltinGroup<N, M>,
{
    let angle = log_so3(&G::rotation(q_d).tr_mul(&G::rotation(q))).norm();
    let distance = if N == 4 {
        (q.fixed_view::<3, 1>(0, N - 1) - q_d.fixed_view::<3, 1>(0, N - 1)).norm()
    } else {
        T::zero()
    };
    (angle, distance)
}

impl<T, G, R, const N: usize, const M: usize> Trajectory<T, N, M> for Supervised<T, G, R, N, M>
where
    T: Real,
    G: BuiltinGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    fn time(&self) -> T {
        self.inner.time()
    }
    fn period(&self) -> T {
        self.inner.period()
    }
    fn step_index(&self) -> u64 {
        self.inner.step_index()
    }
    fn desired(&self) -> Desired<T, N, M> {
        self.setpoint
            .desired(&self.inner.desired(), self.inner.time())
    }
    fn advance(&mut self) {
        self.inner.advance();
    }
}
