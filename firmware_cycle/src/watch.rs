//! The failure detector a cycle carries (docs/maths.md, "Failure detection"). With the
//! feature `detector` it is `detection`'s, about 9 KB with its ring of periods; without it,
//! nothing at all (`Watcher` has no value, so an engine's `Option<Watcher>` takes no room and
//! its moves on a microcontroller's stack stay small), and a configuration with a detector is
//! refused.

use crate::{Config, ConfigError};
use eqtrack_allocation::{Commands, VehicleControl};
use eqtrack_controller::group::BuiltinGroup;
use eqtrack_serial_wire::Detection;
use nalgebra::{Matrix3, SMatrix, SVector};

/// The detector and what it needs of the last command.
#[cfg(feature = "detector")]
pub(crate) struct Watcher<const M: usize> {
    detector: detection::Detector<f32, M>,
    /// The wrench the last command accounted for: a state whose applied wrench is not
    /// this, bit for bit, was not flown as commanded (held, or safe mode).
    accounted: Option<SVector<f32, M>>,
}

/// Built without the detector: no value of this type exists.
#[cfg(not(feature = "detector"))]
pub(crate) enum Watcher<const M: usize> {}

#[cfg(feature = "detector")]
impl<const M: usize> Watcher<M> {
    /// The detector of `config` (`None` without one), on the model inertia `inertia`.
    pub(crate) fn of(
        config: &Config,
        inertia: SMatrix<f32, M, M>,
    ) -> Result<Option<Self>, ConfigError> {
        let Some(d) = &config.detector else {
            return Ok(None);
        };
        if config.vehicle.is_none() {
            return Err(ConfigError::DetectorWithoutVehicle);
        }
        let settings = d.config::<M>(inertia, config.identity.period as f32)?;
        Ok(Some(Watcher {
            detector: detection::Detector::new(settings).map_err(ConfigError::Detector)?,
            accounted: None,
        }))
    }

    /// A new run: the detector afresh, in place.
    pub(crate) fn restart(&mut self) {
        self.detector.restart();
        self.accounted = None;
    }

    /// The detector's cycle over the period that ended at this state, before the
    /// allocation: forgotten first unless the state followed the last one answered
    /// (`follows`) and the plant applied that answer's wrench (`applied`, bit for bit); what
    /// it finds is told to the allocator, and carried by the command. With reaction wheels,
    /// their `speeds` enter the body's momentum balance.
    pub(crate) fn before<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        control: &mut VehicleControl<f32, M>,
        follows: bool,
        (applied, speeds): (&[f32], &[f32]),
        v: &SVector<f32, M>,
        r_hat: &Matrix3<f32>,
    ) -> Detection {
        let as_sent = failsafe::monitor::applied_as_sent(
            self.accounted.as_ref().map(|a| a.as_slice()),
            applied,
        );
        let d = &mut self.detector;
        if !(follows && as_sent) {
            d.gap();
        }
        let found = d.observe_wheeled::<G, N>(v, r_hat, speeds, control);
        let last = d.statistic();
        let code = |j: usize| u8::try_from(j + 1).unwrap_or(u8::MAX);
        let (suspect, statistic) = if last.testing {
            (code(last.actuator), last.best)
        } else {
            (0, 0.0)
        };
        Detection {
            alarms: d.alarms(),
            suspect,
            statistic,
            detected: found.map_or(0, |f| code(f.actuator)),
            kind: found.map_or(0, |f| u8::try_from(f.kind.code()).unwrap_or(0)),
            value: found.map_or(0.0, |f| f.kind.value()),
            refined: found.is_some_and(|f| f.refined),
        }
    }

    /// After the allocation: the commands it answered, and the wrench they account for.
    pub(crate) fn after(&mut self, u: &Commands<f32>, accounted: SVector<f32, M>) {
        self.detector.commanded(u);
        self.accounted = Some(accounted);
    }
}

#[cfg(not(feature = "detector"))]
impl<const M: usize> Watcher<M> {
    /// `None`; a configuration with a detector is refused (this build has none).
    pub(crate) fn of(
        config: &Config,
        _inertia: SMatrix<f32, M, M>,
    ) -> Result<Option<Self>, ConfigError> {
        match config.detector {
            None => Ok(None),
            Some(_) => Err(ConfigError::DetectorNotBuilt),
        }
    }

    pub(crate) fn restart(&mut self) {
        match *self {}
    }

    #[expect(
        clippy::extra_unused_type_parameters,
        reason = "the signature of the build with the detector"
    )]
    pub(crate) fn before<G: BuiltinGroup<N, M>, const N: usize>(
        &mut self,
        _control: &mut VehicleControl<f32, M>,
        _follows: bool,
        _applied: (&[f32], &[f32]),
        _v: &SVector<f32, M>,
        _r_hat: &Matrix3<f32>,
    ) -> Detection {
        match *self {}
    }

    pub(crate) fn after(&mut self, _u: &Commands<f32>, _accounted: SVector<f32, M>) {
        match *self {}
    }
}
