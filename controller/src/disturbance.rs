//! Disturbance rejection: a momentum observer and a geometric integral term with anti-windup
//! (docs/maths.md, "Disturbance rejection").
//!
//! Both terms need state between cycles and the torque the plant actually applied over the
//! last period (after saturation, held commands or safe mode); the law itself stays a pure
//! function. [`Rejection`] holds the state; [`Controller::compute_rejecting`] runs the law
//! with it:
//!
//! ```text
//! τ = sat(τ_law − d̂_b − K_I z)
//! ```
//!
//! with `d̂_b` the observer's estimate in the body frame and `z` the integral of
//! `(V − V_d) + c ⊙ Aᵀ grad Υ(Q_E)`. No allocation, no `std`, any scalar, both groups.

use crate::Real;
use crate::error::{Error, Quantity};
use crate::group::MatrixLieGroup;
use crate::law::{Controller, Desired, ErrorFrame, Formed, Law, LawOutput, saturate};
use crate::tracking::{lyapunov, potential_gradient};
use crate::validate::finite;
use nalgebra::{Matrix3, SMatrix, SVector};

/// The frame in which the observer estimates the disturbance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Frame {
    /// Body axes: constant for a centre of mass off the axis, a misaligned thruster.
    #[default]
    Body,
    /// World axes, acting at the body's origin: constant for a steady wind or a gravity
    /// mis-compensation while the body rotates.
    World,
}

impl Frame {
    /// `"body"` or `"world"`.
    pub fn name(self) -> &'static str {
        match self {
            Frame::Body => "body",
            Frame::World => "world",
        }
    }

    /// Parses `"body"` or `"world"`.
    pub fn from_name(name: &str) -> Option<Frame> {
        [Frame::Body, Frame::World]
            .into_iter()
            .find(|f| f.name() == name)
    }
}

/// The momentum observer's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObserverConfig<T: Real, const M: usize> {
    /// The gain `L` per axis (1/s, each > 0): the estimation error decays as `exp(−L t)`.
    pub gain: SVector<T, M>,
    /// Optional clamp of the estimate per axis (each > 0).
    pub limit: Option<SVector<T, M>>,
    /// The frame of the estimate.
    pub frame: Frame,
}

/// The integral term's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegralConfig<T: Real, const M: usize> {
    /// `K_I` per axis (each > 0).
    pub ki: SVector<T, M>,
    /// `c` per axis (each > 0): the weight of the configuration error in the integrand.
    pub c: SVector<T, M>,
    /// The clamp of the integral's torque `|K_I z|` per axis (each > 0). `None`: half the
    /// controller's torque limit, or no clamp if it has none.
    pub limit: Option<SVector<T, M>>,
    /// Anti-windup: no integration that deepens a saturated axis, and the clamp. Off only
    /// to show what windup does.
    pub anti_windup: bool,
}

/// Which terms run (both `None`: the plain law).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RejectionConfig<T: Real, const M: usize> {
    /// The momentum observer.
    pub observer: Option<ObserverConfig<T, M>>,
    /// The geometric integral.
    pub integral: Option<IntegralConfig<T, M>>,
}

impl<T: Real, const M: usize> Default for RejectionConfig<T, M> {
    fn default() -> Self {
        RejectionConfig {
            observer: None,
            integral: None,
        }
    }
}

impl<T: Real, const M: usize> RejectionConfig<T, M> {
    /// Whether any term runs.
    pub fn any(&self) -> bool {
        self.observer.is_some() || self.integral.is_some()
    }
}

/// What the previous cycle saw (the observer's anchor).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Anchor<T: Real, const M: usize> {
    /// `μ_{k−1} = I V_{k−1}`.
    mu: SVector<T, M>,
    /// `ad_{V_{k−1}}ᵀ μ_{k−1}`.
    gyro: SVector<T, M>,
}

/// The state of the disturbance-rejection terms between cycles (no allocation; `Copy`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rejection<T: Real, const M: usize> {
    config: RejectionConfig<T, M>,
    /// The clamp of `z` per axis (`limit / K_I`), resolved against the torque limit.
    z_max: Option<SVector<T, M>>,
    /// The torque limit the anti-windup rule compares the applied torque with.
    torque_limit: Option<SVector<T, M>>,
    /// `(h, (1 − e^{−L h})/h)`: the period last checked and the observer's discrete gain
    /// for it.
    gain: Option<(T, SVector<T, M>)>,
    anchor: Option<Anchor<T, M>>,
    /// `R_{k−1}`: the anchor's rotation (kept for the world frame only).
    anchor_r: Matrix3<T>,
    /// `d̂` in the observer's frame.
    estimate: SVector<T, M>,
    /// `z`, body frame.
    z: SVector<T, M>,
}

/// Rotates each 3-block of `w` by `r` (SO(3): the torque; SE(3): torque and force). With
/// `r = Rᵀ` it takes a wrench in world axes at the body's origin to the body frame.
pub fn rotate_blocks<T: Real, const M: usize>(r: &Matrix3<T>, w: &SVector<T, M>) -> SVector<T, M> {
    let mut out = *w;
    for b in 0..M / 3 {
        let v = r * w.fixed_rows::<3>(3 * b);
        out.fixed_rows_mut::<3>(3 * b).copy_from(&v);
    }
    out
}

fn positive<T: Real, const M: usize>(q: Quantity, v: &SVector<T, M>) -> Result<(), Error> {
    finite(q, v)?;
    if v.iter().any(|x| *x <= T::zero()) {
        return Err(Error::NotPositive(q));
    }
    Ok(())
}

impl<T: Real, const M: usize> Rejection<T, M> {
    /// The terms of `config` if it has any ([`Rejection::new`]), else `None`: the plain law.
    pub fn of(
        config: RejectionConfig<T, M>,
        torque_limit: Option<&SVector<T, M>>,
    ) -> Result<Option<Self>, Error> {
        if config.any() {
            Rejection::new(config, torque_limit).map(Some)
        } else {
            Ok(None)
        }
    }

    /// Validates the settings (gains, `c`, limits: finite and > 0) against the controller's
    /// torque limit and starts with zero estimates.
    pub fn new(
        config: RejectionConfig<T, M>,
        torque_limit: Option<&SVector<T, M>>,
    ) -> Result<Self, Error> {
        if let Some(o) = &config.observer {
            positive(Quantity::ObserverGain, &o.gain)?;
            if let Some(l) = &o.limit {
                positive(Quantity::ObserverLimit, l)?;
            }
        }
        let mut z_max = None;
        if let Some(i) = &config.integral {
            positive(Quantity::IntegralGain, &i.ki)?;
            positive(Quantity::IntegralWeight, &i.c)?;
            if let Some(l) = &i.limit {
                positive(Quantity::IntegralLimit, l)?;
            }
            let half: T = crate::real(0.5);
            let limit = i.limit.or_else(|| torque_limit.map(|l| l * half));
            if i.anti_windup {
                z_max = limit.map(|l| l.component_div(&i.ki));
            }
        }
        Ok(Rejection {
            config,
            z_max,
            torque_limit: torque_limit.copied(),
            gain: None,
            anchor: None,
            anchor_r: Matrix3::identity(),
            estimate: SVector::zeros(),
            z: SVector::zeros(),
        })
    }

    /// The same terms under new settings (validated as [`Rejection::new`] validates them),
    /// continuing where they were (docs/live.md, "Tuning a running pair"): the observer's
    /// estimate and the anchor carry over, and the integral `z` is rescaled by
    /// `K_I / K_I'` per axis so that its torque `−K_I z` does not jump when `K_I` changes
    /// (it then moves at the new rate). The clamp of `z` is recomputed (and applies from
    /// the next update); the observer's discrete gain is recomputed at the next cycle.
    pub fn retuned(&self, config: RejectionConfig<T, M>) -> Result<Self, Error> {
        let fresh = Rejection::new(config, self.torque_limit.as_ref())?;
        let z = match (&self.config.integral, &fresh.config.integral) {
            (Some(old), Some(new)) => self.z.component_mul(&old.ki.component_div(&new.ki)),
            _ => self.z,
        };
        Ok(Rejection {
            config: fresh.config,
            z_max: fresh.z_max,
            gain: None,
            z,
            ..*self
        })
    }

    /// The settings.
    pub fn config(&self) -> &RejectionConfig<T, M> {
        &self.config
    }

    /// The observer's estimate `d̂` in its own frame (zero without an observer).
    pub fn estimate(&self) -> &SVector<T, M> {
        &self.estimate
    }

    /// The integral `z` (body frame; zero without the term).
    pub fn integral_state(&self) -> &SVector<T, M> {
        &self.z
    }

    /// The clamp of the integral's torque per axis in force (`None`: unclamped).
    pub fn integral_limit(&self) -> Option<SVector<T, M>> {
        let i = self.config.integral.as_ref()?;
        self.z_max.map(|z| z.component_mul(&i.ki))
    }

    /// Forgets the anchor: the next cycle re-anchors instead of updating (the estimates and
    /// the integral are kept). For a cycle that does not follow the last one processed.
    pub fn reanchor(&mut self) {
        self.anchor = None;
    }

    /// Checks the period `h` (finite, > 0) and caches the observer's discrete gain
    /// `(1 − e^{−L h})/h` for it: the work is done only when `h` changes.
    fn set_period(&mut self, h: T) -> Result<(), Error> {
        if self.gain.is_some_and(|(p, _)| p == h) {
            return Ok(());
        }
        crate::validate::period(h)?;
        let gain = self.config.observer.map_or(SVector::zeros(), |o| o.gain);
        self.gain = Some((h, gain.map(|l| (T::one() - (-(l * h)).exp()) / h)));
        Ok(())
    }

    /// The momentum observer's step (docs/maths.md, "The momentum observer"):
    ///
    /// ```text
    /// r_k = μ_k − μ_{k−1} − h(½(ad_{V_{k−1}}ᵀμ_{k−1} + ad_{V_k}ᵀμ_k) + τ_{k−1} + d̂_{k−1})
    /// d̂_k = sat(d̂_{k−1} + ℓ ⊙ r_k),   ℓ = (1 − e^{−L h})/h
    /// ```
    ///
    /// (world frame: `d̂_{k−1}` enters through `R̄ᵀ = ½(R_{k−1} + R_k)ᵀ` and `r_k` leaves
    /// through `R̄`). Returns the estimate in the body frame at `t_k`.
    #[inline]
    fn observe<G: MatrixLieGroup<N, M>, const N: usize>(
        &mut self,
        mu: &SVector<T, M>,
        gyro: &SVector<T, M>,
        r: &Matrix3<T>,
        applied: &SVector<T, M>,
        h: T,
    ) -> SVector<T, M> {
        let Some(o) = &self.config.observer else {
            return SVector::zeros();
        };
        if let (Some(a), Some((_, ell))) = (&self.anchor, &self.gain) {
            let half: T = crate::real(0.5);
            let base = mu - a.mu - (a.gyro + gyro) * (h * half) - applied * h;
            self.estimate += match o.frame {
                Frame::Body => (base - self.estimate * h).component_mul(ell),
                Frame::World => {
                    let mean = (self.anchor_r + r) * half;
                    let body = base - G::rotate_coordinates(&mean.transpose(), &self.estimate) * h;
                    G::rotate_coordinates(&mean, &body).component_mul(ell)
                }
            };
            saturate(&mut self.estimate, o.limit.as_ref());
        }
        match o.frame {
            Frame::Body => self.estimate,
            Frame::World => {
                self.anchor_r = *r;
                G::rotate_coordinates(&r.transpose(), &self.estimate)
            }
        }
    }

    /// The integral's step (docs/maths.md, "The geometric integral"):
    ///
    /// ```text
    /// z_k = clamp(z_{k−1} + h((V − V_d) + c ⊙ Aᵀ grad Υ(Q_E)))
    /// ```
    ///
    /// without the increments that deepen an axis the applied torque saturated (PX4's rule).
    /// Returns the integral's torque `−K_I ⊙ z_k` (body frame).
    #[inline]
    fn integrate(
        &mut self,
        integrand: &SVector<T, M>,
        applied: &SVector<T, M>,
        h: T,
        update: bool,
    ) -> SVector<T, M> {
        let Some(i) = &self.config.integral else {
            return SVector::zeros();
        };
        if update {
            for a in 0..M {
                let step = integrand[a] * h;
                // the integral's torque moves by −K_I·step: skip it if that deepens a
                // saturated axis
                let deepens = i.anti_windup
                    && self.torque_limit.is_some_and(|l| {
                        (applied[a] >= l[a] && step < T::zero())
                            || (applied[a] <= -l[a] && step > T::zero())
                    });
                if !deepens {
                    self.z[a] += step;
                }
            }
            if let Some(z_max) = &self.z_max {
                for a in 0..M {
                    self.z[a] = self.z[a].clamp(-z_max[a], z_max[a]);
                }
            }
        }
        -i.ki.component_mul(&self.z)
    }
}

impl<T, G, const N: usize, const M: usize> Controller<T, G, N, M>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
{
    /// Restores the terms' state as it was before a cycle (for replay): the observer's
    /// estimate (in its own frame), the integral `z`, and the anchor of the state `(q, v)`
    /// processed before (`None`: no anchor, the next cycle re-anchors). The anchor is formed
    /// exactly as [`Controller::compute_rejecting`] forms it.
    pub fn restore_rejection(
        &self,
        rejection: &mut Rejection<T, M>,
        estimate: &SVector<T, M>,
        z: &SVector<T, M>,
        previous: Option<(&SMatrix<T, N, N>, &SVector<T, M>)>,
    ) {
        rejection.estimate = *estimate;
        rejection.z = *z;
        rejection.anchor = previous.map(|(q, v)| {
            let mu = self.config().inertia * v;
            if rejection
                .config
                .observer
                .is_some_and(|o| o.frame == Frame::World)
                && let Some(r) = G::attitude(q)
            {
                rejection.anchor_r = r;
            }
            Anchor {
                gyro: G::ad_transpose_mul(v, &mu),
                mu,
            }
        });
    }

    /// One evaluation of the law with the disturbance-rejection terms of `rejection`
    /// (docs/maths.md, "Disturbance rejection"): the checks of [`Controller::compute`], then
    /// the observer's and the integral's steps with `applied`, the torque the plant applied
    /// over the last period `h`, and `τ = sat(τ_law − d̂_b − K_I z)`.
    ///
    /// `follows`: this state is the one right after the last one `rejection` saw (period
    /// `h` later). When it is not (the first state, or states were skipped), the terms
    /// re-anchor: the estimate and the integral are kept, not updated.
    #[allow(clippy::too_many_arguments)]
    pub fn compute_rejecting(
        &self,
        rejection: &mut Rejection<T, M>,
        q: &SMatrix<T, N, N>,
        v: &SVector<T, M>,
        desired: &Desired<T, N, M>,
        applied: &SVector<T, M>,
        h: T,
        follows: bool,
    ) -> Result<LawOutput<T, N, M>, Error> {
        let Formed {
            torque: tau,
            error,
            velocity_error,
        } = self.checked_raw_torque(q, v, desired)?;
        finite(Quantity::AppliedTorque, applied)?;
        rejection.set_period(h)?;
        let update = follows && rejection.anchor.is_some();
        if !update {
            rejection.anchor = None;
        }
        let c = self.config();
        let mu = c.inertia * v;
        let gyro = G::ad_transpose_mul(v, &mu);
        // the world frame needs the attitude; the body frame never reads it
        let r = match rejection.config.observer {
            Some(o) if o.frame == Frame::World => {
                G::attitude(q).ok_or(Error::NoAttitude { group: G::NAME })?
            }
            _ => Matrix3::identity(),
        };
        let observer = rejection.observe::<G, N>(&mu, &gyro, &r, applied, h);
        let mut torque = tau - observer;
        let integral = match &rejection.config.integral {
            Some(i) => {
                let grad = potential_gradient::<G, T, N, M>(&error.q, &c.k);
                // the gradient in the body frame: at the reference it already is
                let eps = match (c.law, c.error_frame) {
                    (Law::Eqt, ErrorFrame::Reference | ErrorFrame::Recentred) => grad,
                    _ => G::adjoint(&desired.q).tr_mul(&grad),
                };
                let integrand = velocity_error + i.c.component_mul(&eps);
                let integral = rejection.integrate(&integrand, applied, h, update);
                torque += integral;
                integral
            }
            None => SVector::zeros(),
        };
        rejection.anchor = Some(Anchor { mu, gyro });
        finite(Quantity::Torque, &torque)?;
        let saturated = saturate(&mut torque, c.torque_limit.as_ref());
        Ok(LawOutput {
            torque,
            saturated,
            lyapunov: lyapunov(&error.q, &velocity_error, &c.inertia, &c.k),
            error,
            velocity_error,
            observer,
            integral,
        })
    }
}
