//! `[sensors]` and `[estimator]`: what the simulated board measures and how the plant side
//! turns it into the state it hands the law (docs/maths.md, "Sensor models" and
//! "Estimators"). Both tables are optional: without `[estimator]` (or with
//! `kind = "truth"`) the law sees the exact state, as before they existed.

use crate::{ScenarioError, Validator};
use eqtrack_controller::GroupKind;
use eqtrack_controller::group::so3::exp_so3;
use eqtrack_estimator::{FilterKind, MAX_DIRECTIONS as SLOTS, Settings};
use nalgebra::Vector3;
use serde::Deserialize;

pub mod fault;
pub mod gate;

pub use fault::{Sensor, SensorFault, SensorFaultKind};

/// At most this many direction sensors (the estimator's fixed capacity).
pub const MAX_DIRECTIONS: usize = 4;

/// Standard gravity (m/s²); the world's `g = (0, 0, −9.81)`.
pub const GRAVITY: f64 = 9.81;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSensors {
    seed: Option<i64>,
    gyro: Option<RawGyro>,
    #[serde(default)]
    directions: Vec<RawDirection>,
    accelerometer: Option<RawNoise>,
    position: Option<RawPosition>,
    #[serde(default)]
    fault: Vec<fault::RawSensorFault>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGyro {
    #[serde(default)]
    noise: f64,
    bias: Option<Vec<f64>>,
    #[serde(default)]
    bias_walk: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDirection {
    world: Vec<f64>,
    #[serde(default)]
    noise: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    #[serde(default)]
    noise: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPosition {
    #[serde(default)]
    noise: f64,
    rate_hz: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawEstimator {
    kind: String,
    kp: Option<f64>,
    ki: Option<f64>,
    weights: Option<Vec<f64>>,
    bias_limit: Option<f64>,
    accel_gate: Option<f64>,
    initial_attitude: Option<Vec<f64>>,
    gyro_noise: Option<f64>,
    bias_walk: Option<f64>,
    direction_noise: Option<Vec<f64>>,
    initial_attitude_std: Option<f64>,
    initial_bias_std: Option<f64>,
    gate: Option<bool>,
    false_alarm_rate: Option<f64>,
    health_window: Option<f64>,
}

/// The gyro: `ω(t_k) + b_k + n`, `n ~ N(0, noise²/h)` per axis, `b_{k+1} = b_k + N(0,
/// bias_walk²·h)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSpec {
    /// Rate noise density (rad/s/√Hz).
    pub noise: f64,
    /// The bias at t = 0 (rad/s).
    pub bias: [f64; 3],
    /// Bias random walk (rad/s²/√Hz).
    pub bias_walk: f64,
}

/// A direction sensor: `normalize(Rᵀd + σ n)`, `n ~ N(0, 1)` per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionSpec {
    /// The unit world direction `d` (`world` normalised).
    pub world: [f64; 3],
    /// `σ`, per axis (unitless).
    pub noise: f64,
}

/// A position fix: `x + N(0, noise²)` per axis, at `rate_hz`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSpec {
    /// Standard deviation per axis (m).
    pub noise: f64,
    /// Fixes per second.
    pub rate_hz: f64,
}

/// `[sensors]`: the simulated board's sensors, all drawn from one seeded stream.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorsSpec {
    /// Seed of the sensors' random stream.
    pub seed: u64,
    /// The gyro.
    pub gyro: GyroSpec,
    /// Direction sensors, in the list's order.
    pub directions: Vec<DirectionSpec>,
    /// SE(3): the accelerometer's noise (m/s² per sample, per axis).
    pub accelerometer: Option<f64>,
    /// SE(3): position fixes.
    pub position: Option<PositionSpec>,
    /// Scripted faults (`[[sensors.fault]]`), in the table's order; none overlap on one
    /// sensor.
    pub faults: Vec<SensorFault>,
}

/// Which state the law is handed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorKind {
    /// The exact state (today's behaviour; the default).
    Truth,
    /// The complementary filter (docs/maths.md, "The complementary filter on SO(3)").
    Complementary,
    /// The equivariant filter (docs/maths.md, "The equivariant filter for attitude and gyro bias").
    Eqf,
}

impl EstimatorKind {
    /// The scenario's spelling.
    pub fn name(self) -> &'static str {
        match self {
            EstimatorKind::Truth => "truth",
            EstimatorKind::Complementary => "complementary",
            EstimatorKind::Eqf => "eqf",
        }
    }
}

/// `[estimator]`: the filter's kind, gains and guards.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorSpec {
    /// The kind.
    pub kind: EstimatorKind,
    /// Complementary: `k_P` (1/s).
    pub kp: f64,
    /// Complementary: `k_I` (1/s²).
    pub ki: f64,
    /// Complementary: `k_i`, one per direction in the list's order, and on SE(3) one more
    /// for the accelerometer.
    pub weights: Vec<f64>,
    /// EqF: the noise model and start.
    pub eqf: Option<EqfSpec>,
    /// Clamp of each bias component (rad/s).
    pub bias_limit: Option<f64>,
    /// SE(3): skip the accelerometer as a direction when `| |f| − g |` exceeds this (m/s²).
    pub accel_gate: Option<f64>,
    /// The initial attitude estimate (rotation vector); `None`: TRIAD from the first two
    /// direction samples.
    pub initial_attitude: Option<[f64; 3]>,
    /// The innovation gate and health monitor (`gate = true`); `None`: off.
    pub gate: Option<gate::GateSpec>,
}

/// `[estimator]` with `kind = "eqf"`: the filter's noise model (physical units; each
/// defaults to the `[sensors]` value, "matched") and its start.
#[derive(Debug, Clone, PartialEq)]
pub struct EqfSpec {
    /// The gyro's rate noise density (rad/s/√Hz); default `sensors.gyro.noise`.
    pub gyro_noise: f64,
    /// The gyro bias's random walk (rad/s²/√Hz); default `sensors.gyro.bias_walk`.
    pub bias_walk: f64,
    /// Each direction's noise (unitless), in the list's order, and on SE(3) the
    /// accelerometer's as a direction last; default the sensors' (the accelerometer's
    /// `noise / 9.81`). Each must be > 0.
    pub direction_noise: Vec<f64>,
    /// The attitude's standard deviation at the start (rad); default 0.1.
    pub initial_attitude_std: f64,
    /// The bias's standard deviation at the start (rad/s); default the largest component
    /// of `sensors.gyro.bias`, or 0.05 when it is zero.
    pub initial_bias_std: f64,
}

impl EstimatorSpec {
    /// Whether the law sees an estimate (anything but `truth`).
    pub fn estimates(&self) -> bool {
        self.kind != EstimatorKind::Truth
    }
}

impl Default for EstimatorSpec {
    fn default() -> Self {
        EstimatorSpec {
            kind: EstimatorKind::Truth,
            kp: 0.0,
            ki: 0.0,
            weights: Vec::new(),
            eqf: None,
            bias_limit: None,
            accel_gate: None,
            initial_attitude: None,
            gate: None,
        }
    }
}

impl Validator<'_> {
    /// A number that must be finite and ≥ 0.
    pub(crate) fn non_negative(&self, key: &str, x: f64) -> Result<f64, ScenarioError> {
        if !x.is_finite() || x < 0.0 {
            return Err(self.err(key, format!("must be a finite number ≥ 0, got {x}")));
        }
        Ok(x)
    }

    pub(crate) fn positive(&self, key: &str, x: f64) -> Result<f64, ScenarioError> {
        if !x.is_finite() || x <= 0.0 {
            return Err(self.err(key, format!("must be a finite number > 0, got {x}")));
        }
        Ok(x)
    }

    fn three(&self, key: &str, xs: &[f64], why: &str) -> Result<[f64; 3], ScenarioError> {
        let v = self.vector(key, xs, 3, why)?;
        Ok([v[0], v[1], v[2]])
    }

    /// `[sensors]`.
    pub(crate) fn sensors(
        &self,
        raw: &RawSensors,
        group: GroupKind,
    ) -> Result<SensorsSpec, ScenarioError> {
        let seed = match raw.seed {
            None => 0,
            Some(s) if s >= 0 => s as u64,
            Some(s) => return Err(self.err("sensors.seed", format!("must be ≥ 0, got {s}"))),
        };
        let gyro = match &raw.gyro {
            None => GyroSpec {
                noise: 0.0,
                bias: [0.0; 3],
                bias_walk: 0.0,
            },
            Some(g) => GyroSpec {
                noise: self.non_negative("sensors.gyro.noise", g.noise)?,
                bias: match &g.bias {
                    None => [0.0; 3],
                    Some(b) => self.three("sensors.gyro.bias", b, "rad/s per body axis")?,
                },
                bias_walk: self.non_negative("sensors.gyro.bias_walk", g.bias_walk)?,
            },
        };
        if raw.directions.len() > MAX_DIRECTIONS {
            return Err(self.err(
                "sensors.directions",
                format!(
                    "at most {MAX_DIRECTIONS} directions, got {}",
                    raw.directions.len()
                ),
            ));
        }
        let mut directions = Vec::new();
        for (j, d) in raw.directions.iter().enumerate() {
            let key = format!("sensors.directions[{j}]");
            let w = self.three(&format!("{key}.world"), &d.world, "a world direction")?;
            let norm = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            if norm < 1e-9 {
                return Err(self.err(&format!("{key}.world"), "a direction must not be zero"));
            }
            directions.push(DirectionSpec {
                world: w.map(|x| x / norm),
                noise: self.non_negative(&format!("{key}.noise"), d.noise)?,
            });
        }
        let se3_only = |key: &str| {
            self.err(
                key,
                "only se3 scenarios have it (on so3, an accelerometer on a body that does not \
                 translate is the direction \"up\": list it in `directions`)",
            )
        };
        let accelerometer = match (&raw.accelerometer, group) {
            (None, _) => None,
            (Some(_), GroupKind::So3 | GroupKind::Se2) => {
                return Err(se3_only("sensors.accelerometer"));
            }
            (Some(a), GroupKind::Se3) => {
                Some(self.non_negative("sensors.accelerometer.noise", a.noise)?)
            }
        };
        let position = match (&raw.position, group) {
            (None, _) => None,
            (Some(_), GroupKind::So3 | GroupKind::Se2) => return Err(se3_only("sensors.position")),
            (Some(p), GroupKind::Se3) => Some(PositionSpec {
                noise: self.non_negative("sensors.position.noise", p.noise)?,
                rate_hz: self.positive("sensors.position.rate_hz", p.rate_hz)?,
            }),
        };
        let present = fault::Present {
            directions: directions.len(),
            accelerometer: accelerometer.is_some(),
            position: position.is_some(),
        };
        let faults = self.sensor_faults(&raw.fault, &present)?;
        Ok(SensorsSpec {
            seed,
            gyro,
            directions,
            accelerometer,
            position,
            faults,
        })
    }

    /// `[estimator]`, checked against `[sensors]`.
    pub(crate) fn estimator(
        &self,
        raw: &RawEstimator,
        sensors: Option<&SensorsSpec>,
        group: GroupKind,
        period: f64,
    ) -> Result<EstimatorSpec, ScenarioError> {
        let kind = self.estimator_kind(&raw.kind)?;
        self.foreign_keys(raw, kind)?;
        if kind == EstimatorKind::Truth {
            return Ok(EstimatorSpec::default());
        }
        let (sensors, sources) = self.filter_sensors(sensors, kind, group)?;
        let eqf = match kind {
            EstimatorKind::Eqf => Some(self.eqf(raw, sensors, sources)?),
            _ => None,
        };
        let kp = self.non_negative("estimator.kp", raw.kp.unwrap_or(1.0))?;
        let ki = self.non_negative("estimator.ki", raw.ki.unwrap_or(0.3))?;
        let weights = self.weights(raw.weights.as_deref(), sources, group)?;
        let bias_limit = raw
            .bias_limit
            .map(|x| self.positive("estimator.bias_limit", x))
            .transpose()?;
        let accel_gate = self.accel_gate(raw.accel_gate, group)?;
        let initial_attitude = raw
            .initial_attitude
            .as_ref()
            .map(|r| self.three("estimator.initial_attitude", r, "a rotation vector"))
            .transpose()?;
        let gate = self.gate(raw, kind, sensors, sources, period)?;
        Ok(EstimatorSpec {
            kind,
            kp,
            ki,
            weights,
            eqf,
            bias_limit,
            accel_gate,
            initial_attitude,
            gate,
        })
    }

    /// `estimator.kind`: `truth`, `complementary` or `eqf`.
    fn estimator_kind(&self, name: &str) -> Result<EstimatorKind, ScenarioError> {
        match name {
            "truth" => Ok(EstimatorKind::Truth),
            "complementary" => Ok(EstimatorKind::Complementary),
            "eqf" => Ok(EstimatorKind::Eqf),
            other => Err(self.err(
                "estimator.kind",
                format!("unknown kind `{other}` (expected truth, complementary or eqf)"),
            )),
        }
    }

    /// Refuses the first key given that `kind` does not take: `truth` takes none, each filter
    /// not the other's.
    fn foreign_keys(&self, raw: &RawEstimator, kind: EstimatorKind) -> Result<(), ScenarioError> {
        let complementary_keys = [
            ("kp", raw.kp.is_some()),
            ("ki", raw.ki.is_some()),
            ("weights", raw.weights.is_some()),
        ];
        let eqf_keys = [
            ("gyro_noise", raw.gyro_noise.is_some()),
            ("bias_walk", raw.bias_walk.is_some()),
            ("direction_noise", raw.direction_noise.is_some()),
            ("initial_attitude_std", raw.initial_attitude_std.is_some()),
            ("initial_bias_std", raw.initial_bias_std.is_some()),
        ];
        let refuse = |keys: &[(&str, bool)], why: &str| match keys.iter().find(|(_, g)| *g) {
            Some((k, _)) => Err(self.err(&format!("estimator.{k}"), why)),
            None => Ok(()),
        };
        match kind {
            EstimatorKind::Truth => {
                let shared = [
                    ("bias_limit", raw.bias_limit.is_some()),
                    ("accel_gate", raw.accel_gate.is_some()),
                    ("initial_attitude", raw.initial_attitude.is_some()),
                    ("gate", raw.gate.is_some()),
                    ("false_alarm_rate", raw.false_alarm_rate.is_some()),
                    ("health_window", raw.health_window.is_some()),
                ];
                let why = "kind = \"truth\" hands the law the exact state: it takes no gains";
                refuse(&complementary_keys, why)?;
                refuse(&eqf_keys, why)?;
                refuse(&shared, why)
            }
            EstimatorKind::Complementary => {
                // behind the gate, direction_noise is the noise model the gate tests against
                let gated = raw.gate == Some(true);
                let keys: Vec<(&str, bool)> = eqf_keys
                    .iter()
                    .copied()
                    .filter(|(k, _)| !(gated && *k == "direction_noise"))
                    .collect();
                refuse(
                    &keys,
                    "a key of kind = \"eqf\" (the complementary filter takes kp, ki and \
                     weights, and behind the gate direction_noise)",
                )
            }
            EstimatorKind::Eqf => refuse(
                &complementary_keys,
                "a gain of kind = \"complementary\" (the EqF's gains come from its noise \
                 model: gyro_noise, bias_walk, direction_noise)",
            ),
        }
    }

    /// The sensors a filter of `kind` reads: `[sensors]` given, on se3 the accelerometer and
    /// position fixes, and at least two directions; returns them and the count of direction
    /// sources (the accelerometer counting as one on se3).
    fn filter_sensors<'s>(
        &self,
        sensors: Option<&'s SensorsSpec>,
        kind: EstimatorKind,
        group: GroupKind,
    ) -> Result<(&'s SensorsSpec, usize), ScenarioError> {
        let sensors = sensors.ok_or_else(|| {
            self.err(
                "estimator.kind",
                format!(
                    "kind = \"{}\": a filter needs a [sensors] table to read",
                    kind.name()
                ),
            )
        })?;
        let accel = usize::from(group == GroupKind::Se3);
        if group == GroupKind::Se3 {
            if sensors.accelerometer.is_none() {
                return Err(self.err(
                    "sensors.accelerometer",
                    "missing: on se3 the filter's position and velocity are driven by the \
                     accelerometer",
                ));
            }
            if sensors.position.is_none() {
                return Err(self.err(
                    "sensors.position",
                    "missing: on se3 the filter's position is corrected by position fixes",
                ));
            }
        }
        let sources = sensors.directions.len() + accel;
        if sources < 2 {
            return Err(self.err(
                "sensors.directions",
                format!(
                    "the filter needs two directions to know the attitude (the accelerometer \
                     counts as one on se3), got {sources}"
                ),
            ));
        }
        Ok((sensors, sources))
    }

    /// `estimator.weights`: one per direction source, each > 0; all 1 when absent.
    fn weights(
        &self,
        given: Option<&[f64]>,
        sources: usize,
        group: GroupKind,
    ) -> Result<Vec<f64>, ScenarioError> {
        let Some(w) = given else {
            return Ok(vec![1.0; sources]);
        };
        let why = if group == GroupKind::Se3 {
            "one per direction, then one for the accelerometer"
        } else {
            "one per direction"
        };
        let w = self.vector("estimator.weights", w, sources, why)?;
        if let Some(x) = w.iter().find(|x| **x <= 0.0) {
            return Err(self.err("estimator.weights", format!("must be > 0, got {x}")));
        }
        Ok(w)
    }

    /// `estimator.accel_gate`: se3 only, and > 0.
    fn accel_gate(
        &self,
        gate: Option<f64>,
        group: GroupKind,
    ) -> Result<Option<f64>, ScenarioError> {
        match (gate, group) {
            (None, _) => Ok(None),
            (Some(_), GroupKind::So3 | GroupKind::Se2) => Err(self.err(
                "estimator.accel_gate",
                "only se3 scenarios have an accelerometer",
            )),
            (Some(x), GroupKind::Se3) => Ok(Some(self.positive("estimator.accel_gate", x)?)),
        }
    }
}

impl Validator<'_> {
    /// `estimator.direction_noise`: each direction source's noise (one per direction, then
    /// the accelerometer's as a direction), each > 0; default the sensors' (the
    /// accelerometer's `noise / 9.81`). `who` needs them: the EqF, or the gate.
    pub(crate) fn direction_noise(
        &self,
        raw: &RawEstimator,
        sensors: &SensorsSpec,
        sources: usize,
        who: &str,
    ) -> Result<Vec<f64>, ScenarioError> {
        let accel = sensors.accelerometer.map(|a| a / GRAVITY);
        Ok(match &raw.direction_noise {
            Some(given) => {
                let why = if accel.is_some() {
                    "one per direction, then one for the accelerometer"
                } else {
                    "one per direction"
                };
                let v = self.vector("estimator.direction_noise", given, sources, why)?;
                if let Some(x) = v.iter().find(|x| **x <= 0.0) {
                    return Err(self.err(
                        "estimator.direction_noise",
                        format!("each must be > 0 ({who} divides by it), got {x}"),
                    ));
                }
                v
            }
            None => {
                let from: Vec<f64> = sensors
                    .directions
                    .iter()
                    .map(|d| d.noise)
                    .chain(accel)
                    .collect();
                if let Some(i) = from.iter().position(|x| *x <= 0.0) {
                    let what = if i < sensors.directions.len() {
                        format!("sensors.directions[{i}].noise")
                    } else {
                        "sensors.accelerometer.noise".to_owned()
                    };
                    return Err(self.err(
                        "estimator.direction_noise",
                        format!(
                            "missing, and its default {what} is 0: {who} needs each \
                             direction's noise > 0 (give direction_noise = [...])"
                        ),
                    ));
                }
                from
            }
        })
    }

    /// The EqF's noise model and start, each key defaulting to the `[sensors]` value.
    fn eqf(
        &self,
        raw: &RawEstimator,
        sensors: &SensorsSpec,
        sources: usize,
    ) -> Result<EqfSpec, ScenarioError> {
        let gyro_noise = self.non_negative(
            "estimator.gyro_noise",
            raw.gyro_noise.unwrap_or(sensors.gyro.noise),
        )?;
        let bias_walk = self.non_negative(
            "estimator.bias_walk",
            raw.bias_walk.unwrap_or(sensors.gyro.bias_walk),
        )?;
        let direction_noise = self.direction_noise(raw, sensors, sources, "the EqF")?;
        let largest_bias = sensors.gyro.bias.iter().fold(0.0f64, |m, b| m.max(b.abs()));
        let initial_attitude_std = self.positive(
            "estimator.initial_attitude_std",
            raw.initial_attitude_std.unwrap_or(0.1),
        )?;
        let initial_bias_std = self.positive(
            "estimator.initial_bias_std",
            raw.initial_bias_std.unwrap_or(if largest_bias > 0.0 {
                largest_bias
            } else {
                0.05
            }),
        )?;
        Ok(EqfSpec {
            gyro_noise,
            bias_walk,
            direction_noise,
            initial_attitude_std,
            initial_bias_std,
        })
    }
}

impl crate::Scenario {
    /// The scenario's `[estimator]` and sensors as the estimator's settings (`None`:
    /// `truth`). The plant side builds its filter from them; the processor-in-the-loop
    /// firmware's configuration casts the same numbers to `f32`.
    pub fn filter_settings(&self) -> Result<Option<Settings<f64>>, ScenarioError> {
        let s = self;
        let (Some(spec), e) = (&s.sensors, &s.estimator) else {
            return Ok(None);
        };
        let five = |xs: &[f64]| {
            let mut out = [0.0; SLOTS + 1];
            for (o, x) in out.iter_mut().zip(xs) {
                *o = *x;
            }
            (out, xs.len())
        };
        let kind = match e.kind {
            EstimatorKind::Truth => return Ok(None),
            EstimatorKind::Complementary => {
                let (weights, count) = five(&e.weights);
                FilterKind::Complementary {
                    kp: e.kp,
                    ki: e.ki,
                    weights,
                    count,
                }
            }
            EstimatorKind::Eqf => {
                let q: &EqfSpec = e.eqf.as_ref().ok_or_else(|| ScenarioError::Invalid {
                    origin: format!("scenario `{}`", s.name),
                    key: "estimator.kind".to_owned(),
                    message: "\"eqf\" without its noise model".to_owned(),
                })?;
                let (direction_noise, count) = five(&q.direction_noise);
                FilterKind::Eqf {
                    gyro_noise: q.gyro_noise,
                    bias_walk: q.bias_walk,
                    direction_noise,
                    count,
                    initial_attitude_std: q.initial_attitude_std,
                    initial_bias_std: q.initial_bias_std,
                }
            }
        };
        let mut world = [Vector3::zeros(); SLOTS];
        for (w, d) in world.iter_mut().zip(&spec.directions) {
            *w = Vector3::from(d.world);
        }
        Ok(Some(Settings {
            kind,
            world,
            directions: spec.directions.len(),
            initial_attitude: e.initial_attitude.map(|r| exp_so3(&Vector3::from(r))),
            bias_limit: e.bias_limit,
            accel_gate: e.accel_gate,
            accel_noise: spec.accelerometer.unwrap_or(0.0),
            position_noise: spec.position.map_or(0.0, |p| p.noise),
        }))
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod eqf_tests;
