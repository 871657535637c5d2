//! Validation: raw TOML to a [`Scenario`], every bad value refused with its key and what is wrong.

use crate::{
    Axis, EstimatorSpec, NumberOrList, NumberOrMatrix, PathKind, PathSpec, Pose, RawAxis,
    RawReference, RawScenario, RawState, Scenario, ScenarioError, StateSpec, Term, waypoints,
};
use controller::reference::MAX_TERMS;
use controller::validate::spd_inverse;
use controller::{GroupKind, Law, Quantity};
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
                controller::Error::NotSymmetric(_) => "the matrix is not symmetric",
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
        let rot = self.vector(
            &format!("{section}.rotation"),
            rotation,
            3,
            "a rotation vector",
        )?;
        let pos = match (group, position) {
            (GroupKind::So3, Some(_)) => {
                return Err(self.err(
                    &format!("{section}.position"),
                    "only se3 scenarios have a position",
                ));
            }
            (GroupKind::So3, None) | (GroupKind::Se3, None) => vec![0.0; 3],
            (GroupKind::Se3, Some(p)) => {
                self.vector(&format!("{section}.position"), p, 3, "x, y, z")?
            }
        };
        let why = if m == 6 {
            "ω then v"
        } else {
            "body angular velocity"
        };
        let vel = self.vector(&format!("{section}.velocity"), velocity, m, why)?;
        Ok(StateSpec {
            rotation: [rot[0], rot[1], rot[2]],
            position: [pos[0], pos[1], pos[2]],
            velocity: vel,
        })
    }

    pub(crate) fn validate(
        &self,
        raw: RawScenario,
        default_name: &str,
    ) -> Result<Scenario, ScenarioError> {
        let group = match raw.group.as_str() {
            "so3" => GroupKind::So3,
            "se3" => GroupKind::Se3,
            other => {
                return Err(self.err(
                    "group",
                    format!("unknown group `{other}` (expected so3 or se3)"),
                ));
            }
        };
        let (n, m) = group.dims();
        let law = parse_law(&raw.law, group, "law", self.origin)?;
        for (key, x) in [
            ("duration", raw.duration),
            ("control_period", raw.control_period),
        ] {
            if !x.is_finite() {
                return Err(self.err(key, format!("not a finite number ({x})")));
            }
            if x <= 0.0 {
                return Err(self.err(key, format!("must be positive, got {x}")));
            }
        }
        let steps = raw.duration / raw.control_period;
        if (steps - steps.round()).abs() > 1e-9 * steps.max(1.0) {
            return Err(self.err(
                "duration",
                format!(
                    "must be a whole number of control periods ({} / {} = {steps})",
                    raw.duration, raw.control_period
                ),
            ));
        }
        if steps.round() > 1e9 {
            return Err(self.err(
                "duration",
                format!("{steps} control steps is more than 1e9"),
            ));
        }
        let substeps =
            |key: &str, v: Option<i64>, default: usize| -> Result<usize, ScenarioError> {
                match v {
                    None => Ok(default),
                    Some(x) if (1..=100_000).contains(&x) => Ok(x as usize),
                    Some(x) => Err(self.err(
                        key,
                        format!("must be a whole number from 1 to 100000, got {x}"),
                    )),
                }
            };
        let plant_substeps = substeps("plant_substeps", raw.plant_substeps, 10)?;
        let reference_substeps = substeps("reference_substeps", raw.reference_substeps, 1)?;

        let plant_inertia =
            self.matrix("plant.inertia", &raw.plant.inertia, m, "m×m for the group")?;
        self.spd("plant.inertia", &plant_inertia, m)?;
        let torque_limit = match &raw.plant.torque_limit {
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
        let disturbance = match &raw.plant.disturbance {
            None => vec![0.0; m],
            Some(d) => self.vector("plant.disturbance", d, m, "one entry per axis")?,
        };
        let disturbance_world = raw
            .plant
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
        let disturbance_steps = self.steps(raw.plant.disturbance_steps.as_deref(), m)?;
        let model_inertia = match &raw.controller.inertia {
            None => plant_inertia.clone(),
            Some(rows) => {
                let i = self.matrix("controller.inertia", rows, m, "m×m for the group")?;
                self.spd("controller.inertia", &i, m)?;
                i
            }
        };
        let kp = self.gain("controller.kp", &raw.controller.kp, n, "n×n for the group")?;
        let kd = self.gain("controller.kd", &raw.controller.kd, m, "m×m for the group")?;
        let rejection = self.rejection(
            raw.controller.disturbance_observer.as_ref(),
            raw.controller.integral.as_ref(),
            m,
        )?;
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
            Some(r) => self.estimator(r, sensors.as_ref(), group)?,
        };
        Ok(Scenario {
            name: raw.name.unwrap_or_else(|| default_name.to_owned()),
            group,
            law,
            duration: raw.duration,
            control_period: raw.control_period,
            plant_substeps,
            reference_substeps,
            plant_inertia,
            torque_limit,
            disturbance,
            disturbance_world,
            disturbance_steps,
            model_inertia,
            kp,
            kd,
            rejection,
            initial,
            reference,
            feedforward,
            path,
            sensors,
            estimator,
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
        let zero = vec![
            Axis {
                offset: 0.0,
                terms: vec![]
            };
            m
        ];
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
        let path = if let Some(file) = &raw.waypoints {
            let full = self
                .base
                .map_or_else(|| Path::new(file).to_path_buf(), |b| b.join(file));
            let mut spec = waypoints::read(&full, group)?;
            spec.kind = kind;
            waypoints::check_legs(&spec, group, period)?;
            spec
        } else if let Some(sp) = &raw.setpoint {
            let st = self.state_parts(
                "reference.setpoint",
                &sp.rotation,
                sp.position.as_deref(),
                &vec![0.0; m],
                group,
                m,
            )?;
            PathSpec {
                file: "setpoint".to_owned(),
                kind: PathKind::Stop,
                times: vec![0.0],
                poses: vec![Pose {
                    rotation: st.rotation,
                    position: st.position,
                }],
                velocities: vec![None],
                lines: vec![0],
            }
        } else {
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
                None => zero,
                Some(axes) => self.feedforward(axes, m)?,
            };
            return Ok((reference, feedforward, None));
        };
        let first = path.poses[0];
        let reference = StateSpec {
            rotation: first.rotation,
            position: first.position,
            velocity: vec![0.0; m],
        };
        Ok((reference, zero, Some(path)))
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
