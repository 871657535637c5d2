//! `[[sensors.fault]]`: sensor faults a scenario scripts
//! (docs/scenario.md, "Sensor faults"). Each names one sensor, when it starts and for how
//! long, and what goes wrong:
//! a constant bias, no samples at all, or the last good sample repeated. The plant applies
//! them to the samples it has drawn, so the sensors' random stream, and with it every sample
//! outside a fault, is the same as without them.

use crate::{ScenarioError, Validator};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSensorFault {
    sensor: String,
    t: f64,
    duration: Option<f64>,
    kind: String,
    value: Option<Vec<f64>>,
    rotation: Option<Vec<f64>>,
}

/// Which sensor a fault strikes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// `"gyro"`.
    Gyro,
    /// `"direction0"`, `"direction1"` …: the direction sensor of that index in
    /// `[sensors] directions`.
    Direction(usize),
    /// `"accelerometer"` (se3).
    Accelerometer,
    /// `"position"`: the position fixes (se3).
    Position,
}

impl Sensor {
    /// The scenario's name of the sensor.
    pub fn name(&self) -> String {
        match self {
            Sensor::Gyro => "gyro".to_owned(),
            Sensor::Direction(i) => format!("direction{i}"),
            Sensor::Accelerometer => "accelerometer".to_owned(),
            Sensor::Position => "position".to_owned(),
        }
    }
}

/// What goes wrong.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorFaultKind {
    /// `"bias"`: a constant added to each sample: for the gyro (rad/s) and the accelerometer
    /// (m/s²) in body axes, for position fixes (m) in world axes (`value`); for a direction,
    /// the sample turned by the rotation vector `rotation` (rad, body axes).
    Bias([f64; 3]),
    /// `"dropout"`: no samples. The gyro, a direction and the accelerometer give a sample of
    /// NaNs, which every filter skips (and counts) as it skips a bad sample; the position
    /// fixes give none.
    Dropout,
    /// `"stuck"`: the sensor's last sample before the fault, repeated (position fixes: on the
    /// ticks that take a fix). With no sample before, it gives none, as a dropout.
    Stuck,
}

impl SensorFaultKind {
    /// The scenario's name of the kind.
    pub fn name(&self) -> &'static str {
        match self {
            SensorFaultKind::Bias(_) => "bias",
            SensorFaultKind::Dropout => "dropout",
            SensorFaultKind::Stuck => "stuck",
        }
    }
}

/// `[[sensors.fault]]`: one sensor's fault over `[t, t + duration)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorFault {
    /// The sensor.
    pub sensor: Sensor,
    /// When it starts (s): from the first tick `t_k ≥ t − h/2`.
    pub t: f64,
    /// How long it lasts (s); `None`: to the end of the run.
    pub duration: Option<f64>,
    /// What goes wrong.
    pub kind: SensorFaultKind,
}

impl SensorFault {
    /// Whether the fault is on at tick `t_k` of period `h`: from the first `t_k ≥ t − h/2`
    /// to the last `t_k < t + duration − h/2`.
    pub fn active(&self, t_k: f64, h: f64) -> bool {
        t_k >= self.t - h / 2.0 && self.duration.is_none_or(|d| t_k < self.t + d - h / 2.0)
    }

    /// When it ends (s); infinite when it lasts to the end.
    fn end(&self) -> f64 {
        self.t + self.duration.unwrap_or(f64::INFINITY)
    }
}

/// The sensors a scenario has, to check a fault's `sensor` against.
pub(crate) struct Present {
    pub(crate) directions: usize,
    pub(crate) accelerometer: bool,
    pub(crate) position: bool,
}

impl Validator<'_> {
    /// `[[sensors.fault]]`: each names a sensor the scenario has, a finite `t ≥ 0`, a
    /// `duration > 0` when given, and a kind with its own keys
    /// (docs/scenario.md, "Sensor faults"); two faults of one sensor must not overlap. In the
    /// table's order.
    pub(crate) fn sensor_faults(
        &self,
        raw: &[RawSensorFault],
        present: &Present,
    ) -> Result<Vec<SensorFault>, ScenarioError> {
        let mut out: Vec<SensorFault> = Vec::with_capacity(raw.len());
        for (i, f) in raw.iter().enumerate() {
            let key = |field: &str| format!("sensors.fault[{i}].{field}");
            let sensor = self.fault_sensor(&f.sensor, present, &key("sensor"))?;
            if !f.t.is_finite() || f.t < 0.0 {
                return Err(self.err(&key("t"), format!("must be finite and ≥ 0, got {}", f.t)));
            }
            if let Some(d) = f.duration
                && !(d.is_finite() && d > 0.0)
            {
                return Err(self.err(
                    &key("duration"),
                    format!(
                        "must be finite and > 0 (leave it out for a fault to the end), got {d}"
                    ),
                ));
            }
            let kind = self.fault_kind(f, sensor, &key)?;
            let fault = SensorFault {
                sensor,
                t: f.t,
                duration: f.duration,
                kind,
            };
            if let Some(j) = out
                .iter()
                .position(|g| g.sensor == sensor && g.t < fault.end() && fault.t < g.end())
            {
                return Err(self.err(
                    &key("t"),
                    format!(
                        "overlaps sensors.fault[{j}] on the same sensor ({}): one fault per \
                         sensor at a time",
                        sensor.name()
                    ),
                ));
            }
            out.push(fault);
        }
        Ok(out)
    }

    /// A fault's `sensor`: `"gyro"`, `"directionN"` for a listed direction, and on a scenario
    /// that has them `"accelerometer"` and `"position"`.
    fn fault_sensor(
        &self,
        name: &str,
        present: &Present,
        key: &str,
    ) -> Result<Sensor, ScenarioError> {
        let known = || {
            let mut names = vec!["\"gyro\"".to_owned()];
            names.extend((0..present.directions).map(|i| format!("\"direction{i}\"")));
            if present.accelerometer {
                names.push("\"accelerometer\"".to_owned());
            }
            if present.position {
                names.push("\"position\"".to_owned());
            }
            names.join(", ")
        };
        let sensor = match name {
            "gyro" => Some(Sensor::Gyro),
            "accelerometer" if present.accelerometer => Some(Sensor::Accelerometer),
            "position" if present.position => Some(Sensor::Position),
            // the index as the list counts it, without leading zeros or a sign
            other => other
                .strip_prefix("direction")
                .and_then(|n| n.parse::<usize>().ok().filter(|i| i.to_string() == n))
                .filter(|i| *i < present.directions)
                .map(Sensor::Direction),
        };
        sensor.ok_or_else(|| {
            self.err(
                key,
                format!("the scenario has no sensor \"{name}\" (it has {})", known()),
            )
        })
    }

    /// A fault's `kind` and the keys it takes: `"bias"` with `value` (three numbers) on the
    /// gyro, the accelerometer and position fixes, `rotation` (a rotation vector) on a
    /// direction; `"dropout"` and `"stuck"` with neither.
    fn fault_kind(
        &self,
        f: &RawSensorFault,
        sensor: Sensor,
        key: &dyn Fn(&str) -> String,
    ) -> Result<SensorFaultKind, ScenarioError> {
        let direction = matches!(sensor, Sensor::Direction(_));
        let (wanted, other) = if direction {
            ("rotation", "value")
        } else {
            ("value", "rotation")
        };
        let (given, stray) = if direction {
            (&f.rotation, &f.value)
        } else {
            (&f.value, &f.rotation)
        };
        let refuse = |field: &str, why: String| Err(self.err(&key(field), why));
        match f.kind.as_str() {
            "bias" => {
                if stray.is_some() {
                    return refuse(
                        other,
                        format!(
                            "a bias on {} is given as `{wanted}`{}",
                            sensor.name(),
                            if direction {
                                " (a rotation vector, rad)"
                            } else {
                                " (three numbers in the sensor's units)"
                            }
                        ),
                    );
                }
                let Some(xs) = given else {
                    return refuse(
                        wanted,
                        format!("a \"bias\" fault on {} needs `{wanted}`", sensor.name()),
                    );
                };
                let why = if direction {
                    "a rotation vector in body axes, rad"
                } else {
                    "the bias per axis"
                };
                let v = self.vector(&key(wanted), xs, 3, why)?;
                let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                let most = if direction {
                    core::f64::consts::PI
                } else {
                    1e6
                };
                if norm > most {
                    return refuse(
                        wanted,
                        format!(
                            "{} at most {most} in length, got one of length {norm}",
                            if direction { "a turn of" } else { "a bias of" }
                        ),
                    );
                }
                Ok(SensorFaultKind::Bias([v[0], v[1], v[2]]))
            }
            kind @ ("dropout" | "stuck") => {
                for (field, x) in [("value", &f.value), ("rotation", &f.rotation)] {
                    if x.is_some() {
                        return refuse(field, format!("a \"{kind}\" fault takes no `{field}`"));
                    }
                }
                Ok(if kind == "dropout" {
                    SensorFaultKind::Dropout
                } else {
                    SensorFaultKind::Stuck
                })
            }
            other => refuse(
                "kind",
                format!(
                    "unknown sensor fault kind \"{other}\" (known: \"bias\", \"dropout\", \
                     \"stuck\")"
                ),
            ),
        }
    }
}
