//! The closed loop in one place: controller, reference and plant (used by the simulator and
//! the firmware, and the sequence the process pair reproduces across processes).
//!
//! One control cycle at `t_k`: measure `(Q, V)` → law with the reference at `t_k` →
//! saturate → hold `τ_k` (plus any disturbance) over `[t_k, t_{k+1})` while the plant is
//! integrated → advance the reference to `t_{k+1}`.

use crate::Real;
use crate::disturbance::{Rejection, RejectionConfig};
use crate::error::{Error, Quantity};
use crate::group::MatrixLieGroup;
use crate::integrator::RigidBody;
use crate::law::{Controller, Desired, LawOutput};
use crate::reference::{Reference, Trajectory};
use crate::tracking::{ErrorNorms, error_norms};
use crate::validate::finite;
use nalgebra::{SMatrix, SVector};

/// What one cycle of the loop saw and did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<T: Real, const N: usize, const M: usize> {
    /// `t_k`.
    pub t: T,
    /// The plant's configuration at `t_k`.
    pub q: SMatrix<T, N, N>,
    /// The plant's body velocity at `t_k`.
    pub v: SVector<T, M>,
    /// The desired state at `t_k`.
    pub desired: Desired<T, N, M>,
    /// The law's output (torque after saturation, Lyapunov function, tracking error).
    pub output: LawOutput<T, N, M>,
}

impl<T: Real, const N: usize, const M: usize> Sample<T, N, M> {
    /// The error norms of this sample.
    pub fn norms<G: MatrixLieGroup<N, M>>(&self) -> ErrorNorms<T> {
        error_norms::<G, T, N, M>(
            &self.q,
            &self.desired.q,
            &self.output.error,
            &self.output.velocity_error,
        )
    }
}

/// Controller, reference and plant stepping together. The reference is any [`Trajectory`]
/// (by default the feedforward-series [`Reference`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoop<T: Real, G, const N: usize, const M: usize, R = Reference<T, G, N, M>> {
    /// The controller.
    pub controller: Controller<T, G, N, M>,
    /// The desired trajectory (its period is the control period).
    pub reference: R,
    /// The plant.
    pub plant: RigidBody<T, G, N, M>,
    disturbance: SVector<T, M>,
    world_disturbance: Option<SVector<T, M>>,
    rejection: Option<Rejection<T, M>>,
    /// The torque applied over the last period (the law's output; zero before the first).
    applied: SVector<T, M>,
    plant_substeps: usize,
}

impl<T: Real, G, const N: usize, const M: usize, R> ClosedLoop<T, G, N, M, R> {
    /// The constant body-frame disturbance the plant receives on top of the torque.
    pub fn disturbance(&self) -> &SVector<T, M> {
        &self.disturbance
    }

    /// The wrench constant in world axes at the body's origin, if any.
    pub fn world_disturbance(&self) -> Option<&SVector<T, M>> {
        self.world_disturbance.as_ref()
    }

    /// The disturbance-rejection terms' state, if any run.
    pub fn rejection(&self) -> Option<&Rejection<T, M>> {
        self.rejection.as_ref()
    }
}

impl<T, G, const N: usize, const M: usize, R> ClosedLoop<T, G, N, M, R>
where
    T: Real,
    G: MatrixLieGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    /// Assembles a loop; the control period is the reference's.
    pub fn new(
        controller: Controller<T, G, N, M>,
        reference: R,
        plant: RigidBody<T, G, N, M>,
        plant_substeps: usize,
    ) -> Result<Self, Error> {
        if plant_substeps == 0 {
            return Err(Error::NotPositive(Quantity::Substeps));
        }
        Ok(ClosedLoop {
            controller,
            reference,
            plant,
            disturbance: SVector::zeros(),
            world_disturbance: None,
            rejection: None,
            applied: SVector::zeros(),
            plant_substeps,
        })
    }

    /// Runs the law with the disturbance-rejection terms of `config` (docs/maths.md,
    /// "Disturbance rejection"), fed with the torque the loop applied over each period. A
    /// configuration with no term leaves the loop as it was.
    pub fn with_rejection(mut self, config: RejectionConfig<T, M>) -> Result<Self, Error> {
        self.rejection = Rejection::of(config, self.controller.config().torque_limit.as_ref())?;
        Ok(self)
    }

    /// Adds a wrench constant in world axes at the body's origin (rotated into the body at
    /// every integrator stage) to what the plant receives.
    pub fn with_world_disturbance(mut self, world: SVector<T, M>) -> Result<Self, Error> {
        finite(Quantity::Disturbance, &world)?;
        self.world_disturbance = Some(world);
        Ok(self)
    }

    /// Replaces the body-frame disturbance from the next cycle on (a step disturbance).
    pub fn set_disturbance(&mut self, disturbance: SVector<T, M>) -> Result<(), Error> {
        finite(Quantity::Disturbance, &disturbance)?;
        self.disturbance = disturbance;
        Ok(())
    }

    /// Adds a constant body-frame disturbance torque to what the plant receives.
    pub fn with_disturbance(mut self, disturbance: SVector<T, M>) -> Result<Self, Error> {
        finite(Quantity::Disturbance, &disturbance)?;
        self.disturbance = disturbance;
        Ok(self)
    }

    /// The current time `t_k`.
    pub fn time(&self) -> T {
        self.reference.time()
    }

    /// One control cycle; returns what it saw at `t_k` and the torque it held.
    pub fn step(&mut self) -> Result<Sample<T, N, M>, Error> {
        let q = *self.plant.configuration();
        let v = self.plant.velocity();
        self.step_measured(&q, &v)
    }

    /// One control cycle whose wrench reaches the plant through `actuate` (a vehicle's
    /// allocation, actuators and environment: docs/maths.md, "Vehicle physics"): the law at
    /// `(q̂, v̂)` with its rejection terms, then `actuate(plant, wrench, period)` advances the
    /// plant over the period and returns the wrench the terms take as applied. The
    /// disturbances set on the loop are `actuate`'s to apply.
    pub fn step_actuated<A>(
        &mut self,
        q_hat: &SMatrix<T, N, N>,
        v_hat: &SVector<T, M>,
        actuate: A,
    ) -> Result<Sample<T, N, M>, Error>
    where
        A: FnOnce(&mut RigidBody<T, G, N, M>, &SVector<T, M>, T) -> SVector<T, M>,
    {
        let (sample, period) = self.law(q_hat, v_hat)?;
        self.applied = actuate(&mut self.plant, &sample.output.torque, period);
        self.reference.advance();
        Ok(sample)
    }

    /// One control cycle with the law handed `(q̂, v̂)` (an estimate of the plant's state at
    /// `t_k`) instead of the exact state; the sample records the plant's true state.
    pub fn step_measured(
        &mut self,
        q_hat: &SMatrix<T, N, N>,
        v_hat: &SVector<T, M>,
    ) -> Result<Sample<T, N, M>, Error> {
        let (sample, period) = self.law(q_hat, v_hat)?;
        self.applied = sample.output.torque;
        let applied = sample.output.torque + self.disturbance;
        match &self.world_disturbance {
            None => self.plant.advance(&applied, period, self.plant_substeps),
            Some(w) => self
                .plant
                .advance_with_world(&applied, w, period, self.plant_substeps),
        }
        self.reference.advance();
        Ok(sample)
    }

    /// The law at `t_k` on `(q̂, v̂)`, with the rejection terms fed the wrench applied over
    /// the last period: the cycle's sample (the plant's true state at `t_k`) and the period.
    fn law(
        &mut self,
        q_hat: &SMatrix<T, N, N>,
        v_hat: &SVector<T, M>,
    ) -> Result<(Sample<T, N, M>, T), Error> {
        let t = self.reference.time();
        let q = *self.plant.configuration();
        let v = self.plant.velocity();
        let desired = self.reference.desired();
        let period = self.reference.period();
        let output = match &mut self.rejection {
            None => self.controller.compute(q_hat, v_hat, &desired)?,
            Some(r) => self.controller.compute_rejecting(
                r,
                q_hat,
                v_hat,
                &desired,
                &self.applied,
                period,
                true,
            )?,
        };
        Ok((
            Sample {
                t,
                q,
                v,
                desired,
                output,
            },
            period,
        ))
    }
}
