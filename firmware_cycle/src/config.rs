//! What the firmware is built with: the scenario's controller settings in `f32`, as postcard
//! bytes (the host writes them from a scenario; the firmware's build includes them).

use eqtrack_controller::group::BuiltinGroup;
use eqtrack_controller::reference::{AxisTorque, CosTerm, Feedforward};
use eqtrack_controller::{
    Controller, ControllerConfig, ErrorFrame, IntegralConfig, Law, ObserverConfig, Reference,
    RejectionConfig,
};
use eqtrack_serial_wire::Hello;
use heapless::Vec;
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// One cosine term of a feedforward axis: `amplitude·cos(frequency·t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Term {
    /// Amplitude.
    pub amplitude: f32,
    /// Angular frequency (rad/s).
    pub frequency: f32,
    /// Phase (rad).
    pub phase: f32,
}

/// One feedforward axis: `offset + Σ terms`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// The constant part.
    pub offset: f32,
    /// The cosine terms (at most 8).
    pub terms: Vec<Term, 8>,
}

/// The desired trajectory: the feedforward series integrated from `(Q_d(0), V_d(0))`
/// (docs/maths.md, "Integrating on the group").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// `Q_d(0)`, row-major (n² entries).
    pub q0: Vec<f32, 16>,
    /// `V_d(0)` (m entries).
    pub v0: Vec<f32, 6>,
    /// The feedforward torque, one axis per wrench component (m axes).
    pub axes: Vec<Axis, 6>,
    /// RKMK4 substeps per control period.
    pub substeps: u32,
}

/// The momentum observer's settings (docs/maths.md, "The momentum observer").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Observer {
    /// The gain `L` per axis.
    pub gain: Vec<f32, 6>,
    /// The clamp of the estimate per axis.
    pub limit: Option<Vec<f32, 6>>,
    /// World axes (else body axes).
    pub world: bool,
}

/// The geometric integral's settings (docs/maths.md, "The geometric integral").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Integral {
    /// `K_I` per axis.
    pub ki: Vec<f32, 6>,
    /// `c` per axis.
    pub c: Vec<f32, 6>,
    /// The clamp of `|K_I z|` per axis.
    pub limit: Option<Vec<f32, 6>>,
    /// Anti-windup.
    pub anti_windup: bool,
}

/// The controller a firmware is built with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// The identity it answers a `Hello` with: group (1 SO(3), 2 SE(3)), the control period,
    /// the scenario's fingerprint and name.
    pub identity: Hello,
    /// The law: its index in `eqtrack_controller::Law::ALL` (0 EqT, 1 GT, 2 nog, 3 asym).
    pub law: u8,
    /// Where EqT forms its error: its index in `eqtrack_controller::ErrorFrame::ALL` (0 reference,
    /// 1 world, 2 recentred).
    pub error_frame: u8,
    /// The local origin (m, world axes; zero on SO(3) and for a law that depends on where the
    /// world origin is): every position the firmware sees is relative to it, the
    /// reference's start here and the states' and position fixes' on the line, so the `f32`
    /// cycle works with small numbers however far from the world origin the vehicle flies
    /// (docs/invariance.md, "In f32, far from the origin"). The firmware itself never adds
    /// it back.
    pub origin: [f64; 3],
    /// The model inertia `I`, row-major (m² entries).
    pub inertia: Vec<f32, 36>,
    /// The potential weight `K`, row-major (n² entries).
    pub k: Vec<f32, 16>,
    /// The damping `K_d`, row-major (m² entries).
    pub kd: Vec<f32, 36>,
    /// The per-axis torque limit.
    pub torque_limit: Option<Vec<f32, 6>>,
    /// The desired trajectory.
    pub reference: Series,
    /// The momentum observer, if it runs.
    pub observer: Option<Observer>,
    /// The geometric integral, if it runs.
    pub integral: Option<Integral>,
    /// The estimator, where the scenario has sensors: the states carry samples, and the law
    /// is handed the estimate.
    pub estimator: Option<crate::Estimator>,
    /// The vehicle, where the scenario has one: the law's wrench is allocated to it.
    pub vehicle: Option<crate::Vehicle>,
    /// The failure detector, where the scenario has `[fault_detection]` (with a vehicle): it
    /// runs before each allocation and tells the allocator what it finds.
    pub detector: Option<crate::Detector>,
    /// The failsafe manager, where the scenario has `[failsafe]` (docs/failsafe.md).
    pub failsafe: Option<Failsafe>,
}

/// The failsafe manager's settings (docs/failsafe.md), as the scenario's `[failsafe]` gives
/// them at the firmware's control period.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Failsafe {
    /// Each cause's action code (`failsafe::Action::code`; 0: the cause is ignored), in the
    /// order of `failsafe::Cause::ALL`: link, estimator, actuators, tracking.
    pub actions: [u8; 4],
    /// Ticks a cause's flag must stay down before it clears (at least 1).
    pub clear_ticks: u32,
    /// `descend_rate` (m/s).
    pub descend_rate: f32,
    /// `ascend_rate` (m/s).
    pub ascend_rate: f32,
    /// `tracking_limit_attitude` (rad).
    pub limit_attitude: Option<f32>,
    /// `tracking_limit_position` (m).
    pub limit_position: Option<f32>,
    /// The actuators' time constant (s, ≥ 0): the thrust-axis law turns a spinning body's
    /// torques ahead by it (docs/failsafe.md, "The thrust-axis law").
    pub lag: f32,
    /// `actuators_residual` (N·m): an allocation that could not meet its torque by more
    /// raises `actuators` (`None`: only the span test does).
    pub actuators_residual: Option<f32>,
}

impl Failsafe {
    /// The manager's configuration and limits: refused when an action code is not one.
    pub(crate) fn manager(
        &self,
    ) -> Result<(failsafe::Config, failsafe::monitor::Limits<f32>), ConfigError> {
        let mut actions = [None; 4];
        for (a, code) in actions.iter_mut().zip(self.actions) {
            *a = match code {
                0 => None,
                c => Some(
                    *failsafe::Action::ALL
                        .get(usize::from(c) - 1)
                        .ok_or(ConfigError::Failsafe)?,
                ),
            };
        }
        let finite = |x: Option<f32>| x.is_none_or(|x| x.is_finite() && x > 0.0);
        if !(finite(self.limit_attitude)
            && finite(self.limit_position)
            && finite(self.actuators_residual)
            && finite(Some(self.descend_rate))
            && finite(Some(self.ascend_rate))
            && self.lag.is_finite()
            && self.lag >= 0.0)
        {
            return Err(ConfigError::Failsafe);
        }
        Ok((
            failsafe::Config {
                actions,
                clear_ticks: self.clear_ticks.max(1),
            },
            failsafe::monitor::Limits {
                attitude: self.limit_attitude,
                position: self.limit_position,
            },
        ))
    }
}

/// Why a [`Config`] cannot make a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ConfigError {
    /// The bytes are not a postcard `Config`.
    Bytes,
    /// Too long for the buffer given to [`Config::to_bytes`].
    TooLong,
    /// Not a group code (1 SO(3), 2 SE(3)).
    Group(u8),
    /// Not a law index.
    Law(u8),
    /// Not an error-frame index.
    ErrorFrame(u8),
    /// A local origin that is not finite, or not zero on SO(3) (which has no positions).
    Origin,
    /// A vector with the wrong number of entries for the group: which, and how many.
    Shape(&'static str, usize),
    /// The controller refused the settings.
    Controller(eqtrack_controller::Error),
    /// The estimator refused its settings.
    Estimator(eqtrack_estimator::EstimatorError),
    /// The estimator's innovation gate: a threshold or band bound that is not a finite
    /// number > 0, a noise that is not a finite number ≥ 0, a window of 0, or a rejection
    /// count outside 1 to 8.
    Gate,
    /// The vehicle's actuators, wheels or allocation settings are refused (which: the key,
    /// e.g. `wheel.inertia`).
    Vehicle(&'static str),
    /// The failure detector's settings are refused.
    Detector(detection::ConfigError),
    /// A failure detector without a vehicle to watch.
    DetectorWithoutVehicle,
    /// A failure detector, and this build has none (the crate's feature `detector`).
    DetectorNotBuilt,
    /// The failsafe manager's settings are refused (an action code that is none, a limit or
    /// a rate that is not a positive finite number).
    Failsafe,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Bytes => f.write_str("not a firmware configuration (postcard)"),
            ConfigError::TooLong => f.write_str("the configuration does not fit the buffer"),
            ConfigError::Group(g) => write!(f, "group code {g} (expected 1 so3 or 2 se3)"),
            ConfigError::Law(l) => write!(f, "law index {l} (expected 0 to 3)"),
            ConfigError::ErrorFrame(i) => write!(f, "error-frame index {i} (expected 0 to 2)"),
            ConfigError::Origin => f.write_str(
                "the local origin: three finite numbers, and zero on so3 (it has no positions)",
            ),
            ConfigError::Shape(what, n) => write!(f, "{what}: {n} entries, not the group's"),
            ConfigError::Controller(e) => write!(f, "{e}"),
            ConfigError::Estimator(e) => write!(f, "estimator: {e}"),
            ConfigError::Gate => f.write_str(
                "estimator gate: its thresholds and bands must be finite and > 0, its noises finite and ≥ 0, its window at least 1, its rejections 1 to 8",
            ),
            ConfigError::Vehicle(what) => write!(f, "vehicle: `{what}` is refused"),
            ConfigError::Detector(e) => write!(f, "detector: {e}"),
            ConfigError::DetectorWithoutVehicle => {
                f.write_str("detector: there is no vehicle for it to watch")
            }
            ConfigError::Failsafe => f.write_str(
                "failsafe: an action code that is none, or a limit or rate that is not a positive finite number",
            ),
            ConfigError::DetectorNotBuilt => f.write_str(
                "detector: this build has no failure detector (build firmware_cycle with the feature `detector`)",
            ),
        }
    }
}

impl From<eqtrack_controller::Error> for ConfigError {
    fn from(e: eqtrack_controller::Error) -> Self {
        ConfigError::Controller(e)
    }
}

/// The largest encoded configuration.
pub const MAX_CONFIG: usize = 4096;

impl Config {
    /// The postcard bytes, into `out`; returns their length.
    pub fn to_bytes(&self, out: &mut [u8]) -> Result<usize, ConfigError> {
        postcard::to_slice(self, out)
            .map(|b| b.len())
            .map_err(|_| ConfigError::TooLong)
    }

    /// A configuration from [`Config::to_bytes`]'s bytes (nothing may be left over).
    pub fn from_bytes(bytes: &[u8]) -> Result<Config, ConfigError> {
        match postcard::take_from_bytes::<Config>(bytes) {
            Ok((c, [])) => Ok(c),
            _ => Err(ConfigError::Bytes),
        }
    }

    /// The law.
    pub fn law(&self) -> Result<Law, ConfigError> {
        Law::ALL
            .get(usize::from(self.law))
            .copied()
            .ok_or(ConfigError::Law(self.law))
    }

    /// The local origin, checked: finite, and zero on SO(3).
    pub fn origin(&self) -> Result<[f64; 3], ConfigError> {
        let finite = self.origin.iter().all(|x| x.is_finite());
        let so3_at_zero = self.identity.group != 1 || self.origin == [0.0; 3];
        (finite && so3_at_zero)
            .then_some(self.origin)
            .ok_or(ConfigError::Origin)
    }

    /// Where EqT forms its error.
    pub fn error_frame(&self) -> Result<ErrorFrame, ConfigError> {
        ErrorFrame::ALL
            .get(usize::from(self.error_frame))
            .copied()
            .ok_or(ConfigError::ErrorFrame(self.error_frame))
    }

    /// The controller on group `G`.
    pub fn controller<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Controller<f32, G, N, M>, ConfigError> {
        Ok(Controller::new(ControllerConfig {
            law: self.law()?,
            error_frame: self.error_frame()?,
            inertia: matrix::<M, M>("inertia", &self.inertia)?,
            k: matrix::<N, N>("k", &self.k)?,
            kd: matrix::<M, M>("kd", &self.kd)?,
            torque_limit: self
                .torque_limit
                .as_ref()
                .map(|l| vector::<M>("torque_limit", l))
                .transpose()?,
        })?)
    }

    /// The reference generator on group `G`.
    pub fn reference<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Reference<f32, G, N, M>, ConfigError> {
        let r = &self.reference;
        if r.axes.len() != M {
            return Err(ConfigError::Shape("reference.axes", r.axes.len()));
        }
        let mut ff = Feedforward::<f32, M>::zero();
        for (i, axis) in r.axes.iter().enumerate() {
            let mut terms: Vec<CosTerm<f32>, 8> = Vec::new();
            for t in &axis.terms {
                // at most 8 terms: the vectors have the same capacity
                let _ = terms.push(CosTerm {
                    amplitude: t.amplitude,
                    frequency: t.frequency,
                    phase: t.phase,
                });
            }
            ff.axes[i] = AxisTorque::new(i, axis.offset, &terms)?;
        }
        Ok(Reference::new(
            matrix::<N, N>("reference.q0", &r.q0)?,
            vector::<M>("reference.v0", &r.v0)?,
            matrix::<M, M>("inertia", &self.inertia)?,
            ff,
            self.identity.period as f32,
            r.substeps as usize,
        )?)
    }

    /// The disturbance-rejection terms.
    pub fn rejection<const M: usize>(&self) -> Result<RejectionConfig<f32, M>, ConfigError> {
        let limit =
            |what, l: &Option<Vec<f32, 6>>| l.as_ref().map(|l| vector::<M>(what, l)).transpose();
        Ok(RejectionConfig {
            observer: match &self.observer {
                None => None,
                Some(o) => Some(ObserverConfig {
                    gain: vector::<M>("observer.gain", &o.gain)?,
                    limit: limit("observer.limit", &o.limit)?,
                    frame: if o.world {
                        eqtrack_controller::Frame::World
                    } else {
                        eqtrack_controller::Frame::Body
                    },
                }),
            },
            integral: match &self.integral {
                None => None,
                Some(i) => Some(IntegralConfig {
                    ki: vector::<M>("integral.ki", &i.ki)?,
                    c: vector::<M>("integral.c", &i.c)?,
                    limit: limit("integral.limit", &i.limit)?,
                    anti_windup: i.anti_windup,
                }),
            },
        })
    }
}

fn matrix<const R: usize, const C: usize>(
    what: &'static str,
    xs: &[f32],
) -> Result<SMatrix<f32, R, C>, ConfigError> {
    if xs.len() != R * C {
        return Err(ConfigError::Shape(what, xs.len()));
    }
    Ok(SMatrix::from_row_slice(xs))
}

fn vector<const M: usize>(what: &'static str, xs: &[f32]) -> Result<SVector<f32, M>, ConfigError> {
    if xs.len() != M {
        return Err(ConfigError::Shape(what, xs.len()));
    }
    Ok(SVector::from_row_slice(xs))
}
