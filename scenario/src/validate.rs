//! Validation: raw TOML to a [`Scenario`], every bad value refused with its key and what is wrong.

use crate::{
    Axis, EstimatorSpec, NumberOrList, NumberOrMatrix, PathKind, PathSpec, Pose, RawAxis,
    RawController, RawPlant, RawPose, RawReference, RawScenario, RawState, RejectionSpec, Scenario,
    ScenarioError, StateSpec, StepSpec, Term, waypoints,
};
use eqtrack_controller::reference::MAX_TERMS;
use eqtrack_controller::validate::spd_inverse;
use eqtrack_controller::{ErrorFrame, GroupKind, Law, Quantity};
use nalgebra::SMatrix;
use std::path::Path;

pub(crate) fn parse_law(
    text: &str,
    group: GroupKind,
    key: &str,
    origin: &str,
) -> Result<Law, ScenarioError> {
    let law = Law::from_name(text).ok_or_else(|| ScenarioError::Invalid {
        origin: origin.to_owned(),
        key: key.to_owned(),
        message: format!("unknown law `{text}` (expected eqt, gt, nog or asym)"),
    })?;
    if !law.defined_for(group) {
        return Err(ScenarioError::Invalid {
            origin: origin.to_owned(),
            key: key.to_owned(),
            message: format!(
                "law `{text}` is not defined for group {} (only eqt is)",
                group.name()
            ),
        });
    }
    Ok(law)
}

pub(crate) struct Validator<'a> {
    pub(crate) origin: &'a str,
    /// The scenario file's folder (waypoint files are relative to it); `None`: the current
    /// directory.
    pub(crate) base: Option<&'a Path>,
}

impl Validator<'_> {
    pub(crate) fn parse(&self, text: &str, default_name: &str) -> Result<Scenario, ScenarioError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            origin: self.origin.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        self.validate(raw, default_name)
    }

    pub(crate) fn err(&self, key: &str, message: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            origin: self.origin.to_owned(),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    pub(crate) fn finite(&self, key: &str, xs: &[f64]) -> Result<(), ScenarioError> {
        match xs.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(self.err(key, format!("entry {i} is not a finite number ({})", xs[i]))),
            None => Ok(()),
        }
    }

    pub(crate) fn vector(
        &self,
        key: &str,
        xs: &[f64],
        len: usize,
        why: &str,
    ) -> Result<Vec<f64>, ScenarioError> {
        if xs.len() != len {
            return Err(self.err(
                key,
                format!("expected {len} numbers ({why}), got {}", xs.len()),
            ));
        }
        self.finite(key, xs)?;
        Ok(xs.to_vec())
    }

    pub(crate) fn matrix(
        &self,
        key: &str,
        rows: &[Vec<f64>],
        d: usize,
        why: &str,
    ) -> Result<Vec<f64>, ScenarioError> {
        if rows.len() != d || rows.iter().any(|r| r.len() != d) {
            let shape = rows
                .iter()
                .map(|r| r.len().to_string())
                .collect::<Vec<_>>()
                .join(", ");
            return Err(self.err(
                key,
                format!(
                    "expected a {d}×{d} matrix ({why}), got {} rows of lengths [{shape}]",
                    rows.len()
                ),
            ));
        }
        let flat: Vec<f64> = rows.iter().flatten().copied().collect();
        self.finite(key, &flat)?;
        Ok(flat)
    }

    pub(crate) fn spd(&self, key: &str, flat: &[f64], d: usize) -> Result<(), ScenarioError> {
        let check = match d {
            3 => spd_inverse(
                Quantity::Inertia,
                &SMatrix::<f64, 3, 3>::from_row_slice(flat),
            )
            .map(|_| ()),
            4 => spd_inverse(
                Quantity::Inertia,
                &SMatrix::<f64, 4, 4>::from_row_slice(flat),
            )
            .map(|_| ()),
            6 => spd_inverse(
                Quantity::Inertia,
                &SMatrix::<f64, 6, 6>::from_row_slice(flat),
            )
            .map(|_| ()),
            _ => Ok(()),
        };
        check.map_err(|e| {
            let what = match e {
                eqtrack_controller::Error::NotSymmetric(_) => "the matrix is not symmetric",
                _ => "the matrix is not positive definite",
            };
            self.err(key, what)
        })
    }

    pub(crate) fn gain(
        &self,
        key: &str,
        g: &NumberOrMatrix,
        d: usize,
        why: &str,
    ) -> Result<Vec<f64>, ScenarioError> {
        let flat = match g {
            NumberOrMatrix::Number(x) => {
                self.finite(key, &[*x])?;
                if *x <= 0.0 {
                    return Err(self.err(key, format!("must be positive, got {x}")));
                }
                let mut m = vec![0.0; d * d];
                for i in 0..d {
                    m[i * d + i] = *x;
                }
                m
            }
            NumberOrMatrix::Matrix(rows) => self.matrix(key, rows, d, why)?,
        };
        self.spd(key, &flat, d)?;
        Ok(flat)
    }

    pub(crate) fn state(
        &self,
        section: &str,
        raw: &RawState,
        group: GroupKind,
        m: usize,
    ) -> Result<StateSpec, ScenarioError> {
        self.state_parts(
            section,
            &raw.rotation,
            raw.position.as_deref(),
            &raw.velocity,
            group,
            m,
        )
    }

    pub(crate) fn state_parts(
        &self,
        section: &str,
        rotation: &[f64],
        position: Option<&[f64]>,
        velocity: &[f64],
        group: GroupKind,
        m: usize,
    ) -> Result<StateSpec, ScenarioError> {
        let rot = if group == GroupKind::Se2 {
            // the heading θ, stored as the rotation vector (0, 0, θ) about z
            let theta = self.vector(
                &format!("{section}.rotation"),
                rotation,
                1,
                "a heading, rad",
            )?;
            vec![0.0, 0.0, theta[0]]
        } else {
            self.vector(
                &format!("{section}.rotation"),
                rotation,
                3,
                "a rotation vector",
            )?
        };
        let pos = match (group, position) {
            (GroupKind::So3, Some(_)) => {
                return Err(self.err(
                    &format!("{section}.position"),
                    "only se3 and se2 scenarios have a position",
                ));
            }
            (_, None) => vec![0.0; 3],
            (GroupKind::Se3, Some(p)) => {
                self.vector(&format!("{section}.position"), p, 3, "x, y, z")?
            }
            (GroupKind::Se2, Some(p)) => {
                let xy = self.vector(&format!("{section}.position"), p, 2, "x, y")?;
                vec![xy[0], xy[1], 0.0]
            }
        };
        let why = match group {
            GroupKind::Se3 => "ω then v",
            GroupKind::Se2 => "ω, v_x, v_y",
            GroupKind::So3 => "body angular velocity",
        };
        let vel = self.vector(&format!("{section}.velocity"), velocity, m, why)?;
        Ok(StateSpec {
            rotation: [rot[0], rot[1], rot[2]],
            position: [pos[0], pos[1], pos[2]],
            velocity: vel,
        })
    }

    /// The whole scenario, checked table by table in the file's order; the first error found
    /// is the one reported.
    pub(crate) fn validate(
        &self,
        raw: RawScenario,
        default_name: &str,
    ) -> Result<Scenario, ScenarioError> {
        let group = self.group(&raw.group)?;
        if group == GroupKind::Se2 {
            self.refused_on_se2(&raw)?;
        }
        let (n, m) = group.dims();
        let law = parse_law(&raw.law, group, "law", self.origin)?;
        self.timing(raw.duration, raw.control_period)?;
        let plant_substeps = self.substeps("plant_substeps", raw.plant_substeps, 10)?;
        let reference_substeps = self.substeps("reference_substeps", raw.reference_substeps, 1)?;
        let plant = self.plant(&raw.plant, m)?;
        let vehicle = self.vehicle(
            raw.vehicle.as_ref(),
            raw.allocation.as_ref(),
            group,
            &plant.inertia,
            raw.control_period,
        )?;
        let total = default_model(vehicle.as_ref(), &plant.inertia, m);
        let controller = self.controller(&raw.controller, &total, n, m)?;
        let initial = self.state("initial", &raw.initial, group, m)?;
        let (reference, feedforward, path) =
            self.reference(&raw.reference, group, m, raw.control_period)?;
        let sensors = raw
            .sensors
            .as_ref()
            .map(|r| self.sensors(r, group))
            .transpose()?;
        let estimator = match &raw.estimator {
            None => EstimatorSpec::default(),
            Some(r) => self.estimator(r, sensors.as_ref(), group, raw.control_period)?,
        };
        if let Some(v) = vehicle.as_ref().filter(|v| !v.wheels.is_empty()) {
            self.refused_with_wheels(&raw)?;
            self.stiff_friction(&v.wheels, raw.control_period / plant_substeps as f64)?;
        }
        let fault_detection = self.fault_detection(
            raw.fault_detection.as_ref(),
            vehicle.as_ref().map(|v| v.actuators.len()),
            raw.control_period,
        )?;
        let failsafe = self.failsafe(
            raw.failsafe.as_ref(),
            &crate::failsafe::Fit {
                group,
                vehicle: vehicle.as_ref().map(|v| (v.gravity, v.buoyancy)),
                gated: estimator.gate.is_some(),
                control_period: raw.control_period,
            },
        )?;
        Ok(Scenario {
            name: raw.name.unwrap_or_else(|| default_name.to_owned()),
            group,
            law,
            duration: raw.duration,
            control_period: raw.control_period,
            plant_substeps,
            reference_substeps,
            plant_inertia: plant.inertia,
            torque_limit: plant.torque_limit,
            disturbance: plant.disturbance,
            disturbance_world: plant.disturbance_world,
            disturbance_steps: plant.disturbance_steps,
            error_frame: controller.error_frame,
            model_inertia: controller.model_inertia,
            kp: controller.kp,
            kd: controller.kd,
            rejection: controller.rejection,
            initial,
            reference,
            feedforward,
            path,
            sensors,
            estimator,
            vehicle,
            fault_detection,
            failsafe,
        })
    }

    /// `group`: `so3`, `se3` or `se2`.
    fn group(&self, name: &str) -> Result<GroupKind, ScenarioError> {
        GroupKind::from_name(name).ok_or_else(|| {
            self.err(
                "group",
                format!(
                    "unknown group `{other}` (expected so3, se3 or se2)",
                    other = name
                ),
            )
        })
    }

    /// `duration` and `control_period`: each finite and positive, the duration a whole number
    /// of periods, and at most 1e9 steps.
    fn timing(&self, duration: f64, control_period: f64) -> Result<(), ScenarioError> {
        for (key, x) in [("duration", duration), ("control_period", control_period)] {
            if !x.is_finite() {
                return Err(self.err(key, format!("not a finite number ({x})")));
            }
            if x <= 0.0 {
                return Err(self.err(key, format!("must be positive, got {x}")));
            }
        }
        let steps = duration / control_period;
        if (steps - steps.round()).abs() > 1e-9 * steps.max(1.0) {
            return Err(self.err(
                "duration",
                format!(
                    "must be a whole number of control periods ({duration} / {control_period} = {steps})"
                ),
            ));
        }
        if steps.round() > 1e9 {
            return Err(self.err(
                "duration",
                format!("{steps} control steps is more than 1e9"),
            ));
        }
        Ok(())
    }

    /// `plant_substeps` or `reference_substeps`: a whole number from 1 to 100000, `default`
    /// when absent.
    fn substeps(&self, key: &str, v: Option<i64>, default: usize) -> Result<usize, ScenarioError> {
        match v {
            None => Ok(default),
            Some(x) if (1..=100_000).contains(&x) => Ok(x as usize),
            Some(x) => Err(self.err(
                key,
                format!("must be a whole number from 1 to 100000, got {x}"),
            )),
        }
    }

    /// `[plant]`: inertia, torque limit, disturbances, in that order.
    fn plant(&self, raw: &RawPlant, m: usize) -> Result<Plant, ScenarioError> {
        let inertia = self.matrix("plant.inertia", &raw.inertia, m, "m×m for the group")?;
        self.spd("plant.inertia", &inertia, m)?;
        let torque_limit = match &raw.torque_limit {
            None => None,
            Some(NumberOrList::Number(x)) => Some(vec![*x; m]),
            Some(NumberOrList::List(xs)) => Some(xs.clone()),
        };
        if let Some(l) = &torque_limit {
            let l = self.vector("plant.torque_limit", l, m, "one limit per axis")?;
            if let Some(x) = l.iter().find(|x| **x <= 0.0) {
                return Err(self.err("plant.torque_limit", format!("must be positive, got {x}")));
            }
        }
        let disturbance = match &raw.disturbance {
            None => vec![0.0; m],
            Some(d) => self.vector("plant.disturbance", d, m, "one entry per axis")?,
        };
        let disturbance_world = raw
            .disturbance_world
            .as_ref()
            .map(|d| {
                let why = if m == 6 {
                    "world axes: torque then force"
                } else {
                    "world axes"
                };
                self.vector("plant.disturbance_world", d, m, why)
            })
            .transpose()?;
        let disturbance_steps = self.steps(raw.disturbance_steps.as_deref(), m)?;
        Ok(Plant {
            inertia,
            torque_limit,
            disturbance,
            disturbance_world,
            disturbance_steps,
        })
    }

    /// `[controller]`: model inertia (default the plant's), gains, rejection terms.
    fn controller(
        &self,
        raw: &RawController,
        plant_inertia: &[f64],
        n: usize,
        m: usize,
    ) -> Result<Controller, ScenarioError> {
        let model_inertia = match &raw.inertia {
            None => plant_inertia.to_vec(),
            Some(rows) => {
                let i = self.matrix("controller.inertia", rows, m, "m×m for the group")?;
                self.spd("controller.inertia", &i, m)?;
                i
            }
        };
        let error_frame = self.error_frame(raw.error_frame.as_ref())?;
        let kp = self.gain("controller.kp", &raw.kp, n, "n×n for the group")?;
        let kd = self.gain("controller.kd", &raw.kd, m, "m×m for the group")?;
        let rejection =
            self.rejection(raw.disturbance_observer.as_ref(), raw.integral.as_ref(), m)?;
        Ok(Controller {
            error_frame,
            model_inertia,
            kp,
            kd,
            rejection,
        })
    }

    /// `controller.error_frame`: `reference` (the default), `world` or `recentred`.
    fn error_frame(&self, value: Option<&toml::Value>) -> Result<ErrorFrame, ScenarioError> {
        let expected = ErrorFrame::ALL.map(ErrorFrame::name).join(", ");
        let text = match value {
            None => return Ok(ErrorFrame::default()),
            Some(toml::Value::String(text)) => text,
            Some(other) => {
                return Err(self.err(
                    "controller.error_frame",
                    format!(
                        "must be a string, one of {expected} (got the {} `{other}`)",
                        other.type_str()
                    ),
                ));
            }
        };
        ErrorFrame::from_name(text).ok_or_else(|| {
            self.err(
                "controller.error_frame",
                format!("unknown error frame `{text}` (expected {expected})"),
            )
        })
    }

    /// `[reference]`: exactly one of the feedforward series (`rotation`, `velocity`, optional
    /// `position` and `torque`), `waypoints = "FILE"` or `setpoint = { ... }`.
    pub(crate) fn reference(
        &self,
        raw: &RawReference,
        group: GroupKind,
        m: usize,
        period: f64,
    ) -> Result<(StateSpec, Vec<Axis>, Option<PathSpec>), ScenarioError> {
        let series = raw.rotation.is_some()
            || raw.velocity.is_some()
            || raw.position.is_some()
            || raw.torque.is_some();
        let kinds = [series, raw.waypoints.is_some(), raw.setpoint.is_some()];
        if kinds.iter().filter(|k| **k).count() != 1 {
            return Err(self.err(
                "reference",
                "give exactly one of: rotation + velocity (+ torque) for a feedforward series, \
                 waypoints = \"FILE.csv\", or setpoint = { rotation = [...] }",
            ));
        }
        let kind = self.path_kind(raw)?;
        let path = if let Some(file) = &raw.waypoints {
            self.waypoint_path(file, kind, group, period)?
        } else if let Some(sp) = &raw.setpoint {
            self.setpoint_path(sp, group, m)?
        } else {
            let (reference, feedforward) = self.series(raw, group, m)?;
            return Ok((reference, feedforward, None));
        };
        let first = path.poses[0];
        let reference = StateSpec {
            rotation: first.rotation,
            position: first.position,
            velocity: vec![0.0; m],
        };
        Ok((reference, zero_feedforward(m), Some(path)))
    }

    /// `reference.path`: `stop` (the default) or `through`, and only with `waypoints`.
    fn path_kind(&self, raw: &RawReference) -> Result<PathKind, ScenarioError> {
        let kind = match raw.path.as_deref() {
            None | Some("stop") => PathKind::Stop,
            Some("through") => PathKind::Through,
            Some(other) => {
                return Err(self.err(
                    "reference.path",
                    format!("unknown path kind `{other}` (expected \"stop\" or \"through\")"),
                ));
            }
        };
        if raw.path.is_some() && raw.waypoints.is_none() {
            return Err(self.err(
                "reference.path",
                "applies to `waypoints = \"FILE.csv\"` only (a set-point or a feedforward series has no waypoints to pass)",
            ));
        }
        Ok(kind)
    }

    /// `reference.waypoints`: the file (relative to the scenario's folder), read and its legs
    /// checked.
    fn waypoint_path(
        &self,
        file: &str,
        kind: PathKind,
        group: GroupKind,
        period: f64,
    ) -> Result<PathSpec, ScenarioError> {
        let full = self
            .base
            .map_or_else(|| Path::new(file).to_path_buf(), |b| b.join(file));
        let mut spec = waypoints::read(&full, group)?;
        spec.kind = kind;
        waypoints::check_legs(&spec, group, period)?;
        Ok(spec)
    }

    /// `reference.setpoint`: one pose, held at rest from t = 0.
    fn setpoint_path(
        &self,
        sp: &RawPose,
        group: GroupKind,
        m: usize,
    ) -> Result<PathSpec, ScenarioError> {
        let st = self.state_parts(
            "reference.setpoint",
            &sp.rotation,
            sp.position.as_deref(),
            &vec![0.0; m],
            group,
            m,
        )?;
        Ok(PathSpec {
            file: "setpoint".to_owned(),
            kind: PathKind::Stop,
            times: vec![0.0],
            poses: vec![Pose {
                rotation: st.rotation,
                position: st.position,
            }],
            velocities: vec![None],
            lines: vec![0],
        })
    }

    /// The feedforward series: the reference's start (`rotation`, `velocity`, optional
    /// `position`) and its torque (zero when absent).
    fn series(
        &self,
        raw: &RawReference,
        group: GroupKind,
        m: usize,
    ) -> Result<(StateSpec, Vec<Axis>), ScenarioError> {
        let missing = |k: &str| self.err(&format!("reference.{k}"), "missing");
        let reference = self.state_parts(
            "reference",
            raw.rotation.as_deref().ok_or_else(|| missing("rotation"))?,
            raw.position.as_deref(),
            raw.velocity.as_deref().ok_or_else(|| missing("velocity"))?,
            group,
            m,
        )?;
        let feedforward = match &raw.torque {
            None => zero_feedforward(m),
            Some(axes) => self.feedforward(axes, m)?,
        };
        Ok((reference, feedforward))
    }

    pub(crate) fn feedforward(
        &self,
        axes: &[RawAxis],
        m: usize,
    ) -> Result<Vec<Axis>, ScenarioError> {
        if axes.len() != m {
            return Err(self.err(
                "reference.torque",
                format!(
                    "expected {m} axes (one per algebra dimension), got {}",
                    axes.len()
                ),
            ));
        }
        let mut out = Vec::with_capacity(m);
        for (i, a) in axes.iter().enumerate() {
            let key = format!("reference.torque[{i}]");
            if a.terms.len() > MAX_TERMS {
                return Err(self.err(
                    &key,
                    format!("at most {MAX_TERMS} terms, got {}", a.terms.len()),
                ));
            }
            self.finite(&format!("{key}.offset"), &[a.offset])?;
            let mut terms = Vec::new();
            for (j, t) in a.terms.iter().enumerate() {
                self.finite(
                    &format!("{key}.terms[{j}]"),
                    &[t.amplitude, t.frequency, t.phase],
                )?;
                terms.push(Term {
                    amplitude: t.amplitude,
                    frequency: t.frequency,
                    phase: t.phase,
                });
            }
            out.push(Axis {
                offset: a.offset,
                terms,
            });
        }
        Ok(out)
    }
}

/// `[plant]`, checked.
struct Plant {
    /// `plant.inertia` (m×m, row-major).
    inertia: Vec<f64>,
    /// `plant.torque_limit`, one per axis.
    torque_limit: Option<Vec<f64>>,
    /// `plant.disturbance` (zero when absent).
    disturbance: Vec<f64>,
    /// `plant.disturbance_world`.
    disturbance_world: Option<Vec<f64>>,
    /// `plant.disturbance_steps`.
    disturbance_steps: Vec<StepSpec>,
}

/// `[controller]`, checked.
struct Controller {
    /// `controller.error_frame`.
    error_frame: ErrorFrame,
    /// `controller.inertia` (the plant's when absent).
    model_inertia: Vec<f64>,
    /// `controller.kp` (n×n).
    kp: Vec<f64>,
    /// `controller.kd` (m×m).
    kd: Vec<f64>,
    /// `controller.disturbance_observer` and `controller.integral`.
    rejection: RejectionSpec,
}

/// A zero feedforward torque on each of the `m` axes.
fn zero_feedforward(m: usize) -> Vec<Axis> {
    vec![
        Axis {
            offset: 0.0,
            terms: vec![]
        };
        m
    ]
}

/// The plant's inertia plus any added mass (row-major).
pub(crate) fn plus(plant: &[f64], added: Option<&[f64]>) -> Vec<f64> {
    match added {
        None => plant.to_vec(),
        Some(a) => plant.iter().zip(a).map(|(p, x)| p + x).collect(),
    }
}

/// The controller's model inertia when `[controller]` gives none: the plant's total (added
/// mass included), the body with its reaction wheels free (docs/maths.md, "Reaction wheels").
fn default_model(
    vehicle: Option<&crate::vehicle::VehicleSpec>,
    plant: &[f64],
    m: usize,
) -> Vec<f64> {
    let mut total = plus(plant, vehicle.and_then(|v| v.added_mass.as_deref()));
    if let Some(v) = vehicle {
        let spin = crate::wheels::spin_inertia(&v.wheels, m);
        for (t, s) in total.iter_mut().zip(spin) {
            *t -= s;
        }
    }
    total
}

impl Validator<'_> {
    /// The keys a planar (SE(2)) scenario cannot take, refused by name: the sensors and the
    /// estimators (three-dimensional models), failure detection and the failsafe manager (not
    /// yet planar), and the vehicle keys that need a third dimension
    /// ([`crate::vehicle::planar_refusal`]).
    fn refused_on_se2(&self, raw: &RawScenario) -> Result<(), ScenarioError> {
        let tables = [
            ("sensors", raw.sensors.is_some()),
            ("estimator", raw.estimator.is_some()),
            ("fault_detection", raw.fault_detection.is_some()),
            ("failsafe", raw.failsafe.is_some()),
        ];
        let key = tables
            .iter()
            .find(|(_, given)| *given)
            .map(|(key, _)| (*key).to_owned())
            .or_else(|| {
                crate::vehicle::planar_refusal(raw.vehicle.as_ref(), raw.allocation.as_ref())
            });
        match key {
            Some(key) => Err(self.err(&key, "is not available on se2 (a planar scenario)")),
            None => Ok(()),
        }
    }

    /// What a vehicle with reaction wheels does not have yet, refused naming the table: the
    /// failsafe's laws know thrusters only.
    fn refused_with_wheels(&self, raw: &RawScenario) -> Result<(), ScenarioError> {
        let tables = [("failsafe", raw.failsafe.is_some())];
        match tables.iter().find(|(_, given)| *given) {
            Some((key, _)) => Err(self.err(
                key,
                "is not yet available on a vehicle with reaction wheels ([[vehicle.wheel]])",
            )),
            None => Ok(()),
        }
    }
}
