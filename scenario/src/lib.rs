//! Scenario files: the TOML schema, its validation, the built-in scenarios, and the builders
//! that turn a validated [`Scenario`] into the controller crate's objects. Both processes
//! (plant and controller) read configuration only through this crate.
//!
//! The schema, key by key (type, unit, default and meaning of every key this crate accepts,
//! and the waypoint file's columns), is docs/scenario.md.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod cli;
pub mod rejection;
pub mod sensing;
pub mod waypoints;

pub use rejection::{IntegralSpec, ObserverSpec, RejectionSpec, StepSpec};
pub use sensing::{
    DirectionSpec, EqfSpec, EstimatorKind, EstimatorSpec, GyroSpec, PositionSpec, SensorsSpec,
};

use controller::group::MatrixLieGroup;
use controller::group::so3::exp_so3;
use controller::integrator::RigidBody;
use controller::reference::{AxisTorque, CosTerm, Feedforward, MAX_TERMS};
use controller::validate::spd_inverse;
use controller::{
    Controller, ControllerConfig, GroupKind, Law, Path as GroupPath, PathReference, Quantity,
    Reference, Source,
};
use nalgebra::{SMatrix, SVector, Vector3};
use serde::Deserialize;
use std::path::Path;

/// The built-in scenarios, shipped as TOML files in `scenarios/`.
pub const BUILTINS: [(&str, &str); 3] = [
    ("seed", include_str!("../../scenarios/seed.toml")),
    (
        "montecarlo",
        include_str!("../../scenarios/montecarlo.toml"),
    ),
    (
        "se3_circle",
        include_str!("../../scenarios/se3_circle.toml"),
    ),
];

/// What can be wrong with a scenario. Every variant names where, and what.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The path given.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML is malformed, has an unknown key, or a value of the wrong type.
    #[error("{origin}: {message}")]
    Parse {
        /// The file or built-in name.
        origin: String,
        /// The parser's message (it names the key and the line).
        message: String,
    },
    /// A value is present and well-typed but not acceptable.
    #[error("{origin}: key `{key}`: {message}")]
    Invalid {
        /// The file or built-in name.
        origin: String,
        /// The dotted key, e.g. `plant.inertia`.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// A waypoint file is malformed.
    #[error("{file}: line {line}, column {column} (`{name}`): {message}")]
    Waypoints {
        /// The file.
        file: String,
        /// The line (1: the header).
        line: u64,
        /// The column (1-based).
        column: usize,
        /// The column's name in the header.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// No built-in scenario has that name.
    #[error("unknown built-in scenario `{0}` (available: seed, montecarlo, se3_circle)")]
    UnknownBuiltin(String),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    group: String,
    law: String,
    duration: f64,
    control_period: f64,
    plant_substeps: Option<i64>,
    reference_substeps: Option<i64>,
    plant: RawPlant,
    controller: RawController,
    initial: RawState,
    reference: RawReference,
    sensors: Option<sensing::RawSensors>,
    estimator: Option<sensing::RawEstimator>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlant {
    inertia: Vec<Vec<f64>>,
    torque_limit: Option<NumberOrList>,
    disturbance: Option<Vec<f64>>,
    disturbance_world: Option<Vec<f64>>,
    disturbance_steps: Option<Vec<rejection::RawStep>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawController {
    inertia: Option<Vec<Vec<f64>>>,
    kp: NumberOrMatrix,
    kd: NumberOrMatrix,
    disturbance_observer: Option<rejection::RawObserver>,
    integral: Option<rejection::RawIntegral>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawState {
    rotation: Vec<f64>,
    position: Option<Vec<f64>>,
    velocity: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReference {
    rotation: Option<Vec<f64>>,
    position: Option<Vec<f64>>,
    velocity: Option<Vec<f64>>,
    torque: Option<Vec<RawAxis>>,
    waypoints: Option<String>,
    path: Option<String>,
    setpoint: Option<RawPose>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPose {
    rotation: Vec<f64>,
    position: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    #[serde(default)]
    offset: f64,
    #[serde(default)]
    terms: Vec<RawTerm>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTerm {
    amplitude: f64,
    frequency: f64,
    #[serde(default)]
    phase: f64,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum NumberOrMatrix {
    Number(f64),
    Matrix(Vec<Vec<f64>>),
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum NumberOrList {
    Number(f64),
    List(Vec<f64>),
}

/// One cosine term of a feedforward axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    pub frequency: f64,
    /// Phase (rad).
    pub phase: f64,
}

/// One feedforward axis: `offset + Σ amplitude·cos(frequency·t + phase)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Constant part.
    pub offset: f64,
    /// Cosine terms.
    pub terms: Vec<Term>,
}

/// A configuration and velocity: `Q = [[exp(hat(rotation)), position], [0, 1]]` (SO(3): the
/// rotation alone) and the body velocity.
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpec {
    /// Rotation vector (rad).
    pub rotation: [f64; 3],
    /// Position (SE(3) only; zero on SO(3)).
    pub position: [f64; 3],
    /// Body velocity, m entries.
    pub velocity: Vec<f64>,
}

/// A pose: `Q = [[exp(hat(rotation)), position], [0, 1]]` (SO(3): the rotation alone).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation vector (rad).
    pub rotation: [f64; 3],
    /// Position (SE(3) only; zero on SO(3)).
    pub position: [f64; 3],
}

/// How a path treats its interior waypoints (`[reference] path`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PathKind {
    /// `"stop"` (the default): rest-to-rest geodesic legs, at rest at every waypoint.
    #[default]
    Stop,
    /// `"through"`: C² quintic Hermite legs that fly through the interior waypoints.
    Through,
}

impl PathKind {
    /// The scenario's name of the kind.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Stop => "stop",
            PathKind::Through => "through",
        }
    }
}

/// A reference given as poses at times: a set-point (one pose) or a path through waypoints.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Where it came from: the waypoint file, or `setpoint`.
    pub file: String,
    /// Stop at every waypoint, or fly through them.
    pub kind: PathKind,
    /// Waypoint times, strictly increasing.
    pub times: Vec<f64>,
    /// Waypoint poses.
    pub poses: Vec<Pose>,
    /// The body velocity given at each waypoint (m entries), `None`: chosen.
    pub velocities: Vec<Option<Vec<f64>>>,
    /// The file line of each waypoint (0 for a set-point).
    pub lines: Vec<u64>,
}

/// The path of a [`PathSpec`] on its group: the stop path (`Path::through`) or the
/// through-path (`Path::flying`, with the velocities given).
pub fn build_path<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
    spec: &PathSpec,
) -> Result<GroupPath<f64, G, N, M>, controller::Error> {
    let poses: Vec<SMatrix<f64, N, N>> = spec
        .poses
        .iter()
        .map(|p| Scenario::pose::<N>(p.rotation, p.position))
        .collect();
    match spec.kind {
        PathKind::Stop => GroupPath::through(&spec.times, &poses),
        PathKind::Through => {
            let given: Vec<Option<SVector<f64, M>>> = spec
                .velocities
                .iter()
                .map(|v| {
                    v.as_ref()
                        .map(|v| SVector::from_fn(|i, _| v.get(i).copied().unwrap_or(f64::NAN)))
                })
                .collect();
            GroupPath::flying(&spec.times, &poses, &given)
        }
    }
}

/// A validated scenario. Matrices are row-major; dimensions match the group.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Name (from the file, else the built-in name or the file stem).
    pub name: String,
    /// The group.
    pub group: GroupKind,
    /// The law.
    pub law: Law,
    /// Duration (s).
    pub duration: f64,
    /// Control period (s).
    pub control_period: f64,
    /// RKMK4 steps of the plant per control period.
    pub plant_substeps: usize,
    /// RKMK4 steps of the reference per control period.
    pub reference_substeps: usize,
    /// The plant's true inertia (m×m).
    pub plant_inertia: Vec<f64>,
    /// Per-axis torque limit (m entries), if any.
    pub torque_limit: Option<Vec<f64>>,
    /// Constant body-frame disturbance (m entries).
    pub disturbance: Vec<f64>,
    /// A wrench constant in world axes at the body's origin (m entries), if any.
    pub disturbance_world: Option<Vec<f64>>,
    /// Steps of the body disturbance, in time order.
    pub disturbance_steps: Vec<StepSpec>,
    /// The controller's model inertia (m×m).
    pub model_inertia: Vec<f64>,
    /// The potential weight K (n×n).
    pub kp: Vec<f64>,
    /// The damping K_d (m×m).
    pub kd: Vec<f64>,
    /// The controller's disturbance-rejection terms.
    pub rejection: RejectionSpec,
    /// The plant at t = 0.
    pub initial: StateSpec,
    /// The reference at t = 0.
    pub reference: StateSpec,
    /// Feedforward torque, one axis per algebra dimension (zero for a path).
    pub feedforward: Vec<Axis>,
    /// The reference as poses at times (`[reference] waypoints` or `setpoint`); `None`: the
    /// feedforward series. With a path, `reference` is its first pose at rest.
    pub path: Option<PathSpec>,
    /// `[sensors]`: the simulated sensors (`None`: none are simulated).
    pub sensors: Option<SensorsSpec>,
    /// `[estimator]`: what the plant side hands the law (default: the exact state).
    pub estimator: EstimatorSpec,
}

impl Scenario {
    /// Loads a built-in scenario by name.
    pub fn builtin(name: &str) -> Result<Scenario, ScenarioError> {
        let (_, text) = BUILTINS
            .iter()
            .find(|(n, _)| *n == name)
            .ok_or_else(|| ScenarioError::UnknownBuiltin(name.to_owned()))?;
        Scenario::from_toml(text, &format!("built-in scenario `{name}`"), name)
    }

    /// Loads and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Scenario, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scenario".to_owned());
        Validator {
            origin: &path.display().to_string(),
            base: path.parent(),
        }
        .parse(&text, &stem)
    }

    /// Parses and validates TOML text; `origin` names it in errors, `default_name` is used
    /// when the file has no `name`.
    pub fn from_toml(
        text: &str,
        origin: &str,
        default_name: &str,
    ) -> Result<Scenario, ScenarioError> {
        Validator { origin, base: None }.parse(text, default_name)
    }

    /// Overrides the law (checked against the group).
    pub fn with_law(mut self, law: Law) -> Result<Scenario, ScenarioError> {
        self.law = parse_law(law.name(), self.group, "--law", "the command line")?;
        Ok(self)
    }

    /// The number of control steps N = duration / control_period.
    pub fn steps(&self) -> u64 {
        (self.duration / self.control_period).round() as u64
    }

    /// n×n configuration from a [`StateSpec`].
    pub fn configuration<const N: usize>(spec: &StateSpec) -> SMatrix<f64, N, N> {
        let r = exp_so3(&Vector3::from(spec.rotation));
        let mut q = SMatrix::<f64, N, N>::identity();
        for i in 0..3.min(N) {
            for j in 0..3.min(N) {
                q[(i, j)] = r[(i, j)];
            }
            if N > 3 {
                q[(i, N - 1)] = spec.position[i];
            }
        }
        q
    }

    /// The controller configuration (validated again by [`Controller::new`]).
    pub fn controller_config<const N: usize, const M: usize>(&self) -> ControllerConfig<f64, N, M> {
        ControllerConfig {
            law: self.law,
            inertia: SMatrix::from_row_slice(&self.model_inertia),
            k: SMatrix::from_row_slice(&self.kp),
            kd: SMatrix::from_row_slice(&self.kd),
            torque_limit: self
                .torque_limit
                .as_ref()
                .map(|l| SVector::from_row_slice(l)),
        }
    }

    /// The controller.
    pub fn controller<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Controller<f64, G, N, M>, controller::Error> {
        Controller::new(self.controller_config())
    }

    /// The feedforward torque.
    pub fn feedforward<const M: usize>(&self) -> Result<Feedforward<f64, M>, controller::Error> {
        let mut ff = Feedforward::<f64, M>::zero();
        for (i, axis) in self.feedforward.iter().enumerate().take(M) {
            let terms: Vec<CosTerm<f64>> = axis
                .terms
                .iter()
                .map(|t| CosTerm {
                    amplitude: t.amplitude,
                    frequency: t.frequency,
                    phase: t.phase,
                })
                .collect();
            ff.axes[i] = AxisTorque::new(i, axis.offset, &terms)?;
        }
        Ok(ff)
    }

    /// The reference generator (model inertia, control period, reference substeps).
    pub fn reference_generator<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Reference<f64, G, N, M>, controller::Error> {
        Reference::new(
            Self::configuration::<N>(&self.reference),
            SVector::from_row_slice(&self.reference.velocity),
            SMatrix::from_row_slice(&self.model_inertia),
            self.feedforward()?,
            self.control_period,
            self.reference_substeps,
        )
    }

    /// The path of a waypoint or set-point scenario (`None` for a feedforward series).
    pub fn path<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Option<Result<GroupPath<f64, G, N, M>, controller::Error>> {
        self.path.as_ref().map(build_path::<G, N, M>)
    }

    /// The desired trajectory, whichever its kind: the feedforward series integrated, or the
    /// path through waypoints (a set-point) stepped at the control period.
    pub fn reference_source<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<Source<f64, G, N, M>, controller::Error> {
        Ok(match self.path::<G, N, M>() {
            None => Source::Series(self.reference_generator()?),
            Some(path) => Source::Path(PathReference::new(
                path?,
                SMatrix::from_row_slice(&self.model_inertia),
                self.control_period,
            )?),
        })
    }

    /// n×n configuration from a rotation vector and a position (ignored on SO(3)).
    pub fn pose<const N: usize>(rotation: [f64; 3], position: [f64; 3]) -> SMatrix<f64, N, N> {
        Self::configuration::<N>(&StateSpec {
            rotation,
            position,
            velocity: Vec::new(),
        })
    }

    /// The plant body at its initial state (true inertia).
    pub fn plant_body<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(
        &self,
    ) -> Result<RigidBody<f64, G, N, M>, controller::Error> {
        RigidBody::new(
            SMatrix::from_row_slice(&self.plant_inertia),
            Self::configuration::<N>(&self.initial),
            SVector::from_row_slice(&self.initial.velocity),
        )
    }

    /// A 64-bit fingerprint (FNV-1a, never 0) of what the controller takes from the scenario:
    /// the group, the control period and reference substeps, the model inertia, `K`, `K_d`,
    /// the torque limit, the reference's initial state and its feedforward. Not the law (a
    /// controller may override it), the duration, the name, nor the plant's own initial state,
    /// inertia or disturbances. The disturbance-rejection terms when there are any. Two processes of a pair compare it on their first message
    /// (docs/architecture.md, "Configuration identity").
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fnv(0xcbf2_9ce4_8422_2325);
        h.bytes(self.group.name().as_bytes());
        h.f64s(&[self.control_period, self.reference_substeps as f64]);
        for part in [&self.model_inertia, &self.kp, &self.kd] {
            h.f64s(&[part.len() as f64]);
            h.f64s(part);
        }
        match &self.torque_limit {
            Some(l) => h.f64s(l),
            None => h.bytes(b"no limit"),
        }
        h.f64s(&self.reference.rotation);
        h.f64s(&self.reference.position);
        h.f64s(&self.reference.velocity);
        for axis in &self.feedforward {
            h.f64s(&[axis.offset, axis.terms.len() as f64]);
            for t in &axis.terms {
                h.f64s(&[t.amplitude, t.frequency, t.phase]);
            }
        }
        if let Some(p) = &self.path {
            h.f64s(&[p.times.len() as f64]);
            h.f64s(&p.times);
            for pose in &p.poses {
                h.f64s(&pose.rotation);
                h.f64s(&pose.position);
            }
            // only for a through-path, so stop paths keep their fingerprints
            if p.kind == PathKind::Through {
                h.bytes(b"through");
                for v in &p.velocities {
                    match v {
                        Some(v) => h.f64s(v),
                        None => h.bytes(b"chosen"),
                    }
                }
            }
        }
        // only when present, so scenarios without them keep their fingerprints
        if let Some(o) = &self.rejection.observer {
            h.bytes(b"observer");
            h.bytes(o.frame.name().as_bytes());
            h.f64s(&o.gain);
            if let Some(l) = &o.limit {
                h.f64s(l);
            }
        }
        if let Some(i) = &self.rejection.integral {
            h.bytes(if i.anti_windup {
                b"integral"
            } else {
                b"wound-up"
            });
            for part in [&i.ki, &i.c] {
                h.f64s(part);
            }
            if let Some(l) = &i.limit {
                h.f64s(l);
            }
        }
        h.0.max(1)
    }

    /// The disturbance as a vector.
    pub fn disturbance_vector<const M: usize>(&self) -> SVector<f64, M> {
        SVector::from_row_slice(&self.disturbance)
    }
}

/// FNV-1a, 64 bits.
struct Fnv(u64);

impl Fnv {
    fn bytes(&mut self, b: &[u8]) {
        for x in b {
            self.0 = (self.0 ^ u64::from(*x)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f64s(&mut self, xs: &[f64]) {
        for x in xs {
            self.bytes(&x.to_bits().to_le_bytes());
        }
    }
}

fn parse_law(text: &str, group: GroupKind, key: &str, origin: &str) -> Result<Law, ScenarioError> {
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

struct Validator<'a> {
    origin: &'a str,
    /// The scenario file's folder (waypoint files are relative to it); `None`: the current
    /// directory.
    base: Option<&'a Path>,
}

impl Validator<'_> {
    fn parse(&self, text: &str, default_name: &str) -> Result<Scenario, ScenarioError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            origin: self.origin.to_owned(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        self.validate(raw, default_name)
    }

    fn err(&self, key: &str, message: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            origin: self.origin.to_owned(),
            key: key.to_owned(),
            message: message.into(),
        }
    }

    fn finite(&self, key: &str, xs: &[f64]) -> Result<(), ScenarioError> {
        match xs.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(self.err(key, format!("entry {i} is not a finite number ({})", xs[i]))),
            None => Ok(()),
        }
    }

    fn vector(
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

    fn matrix(
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

    fn spd(&self, key: &str, flat: &[f64], d: usize) -> Result<(), ScenarioError> {
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

    fn gain(
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

    fn state(
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

    fn state_parts(
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

    fn validate(&self, raw: RawScenario, default_name: &str) -> Result<Scenario, ScenarioError> {
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
    fn reference(
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

    fn feedforward(&self, axes: &[RawAxis], m: usize) -> Result<Vec<Axis>, ScenarioError> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_load() {
        for (name, _) in BUILTINS {
            let s = Scenario::builtin(name).unwrap();
            assert_eq!(s.name, name);
        }
        let seed = Scenario::builtin("seed").unwrap();
        assert_eq!(seed.steps(), 2000);
        assert_eq!(seed.kp, vec![0.5, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5]);
        let se3 = Scenario::builtin("se3_circle").unwrap();
        assert_eq!(se3.group, GroupKind::Se3);
        assert_eq!(se3.kd.len(), 36);
    }

    #[test]
    fn a_set_point_or_waypoints_replace_the_series_and_only_one_kind_is_given() {
        let seed = BUILTINS[0].1;
        let at = seed.find("[reference]").unwrap();
        let head = &seed[..at];
        let sp = format!("{head}[reference]\nsetpoint = {{ rotation = [0.0, 0.0, 1.0] }}\n");
        let s = Scenario::from_toml(&sp, "sp", "sp").unwrap();
        let p = s.path.as_ref().unwrap();
        assert_eq!((p.times.len(), p.poses[0].rotation), (1, [0.0, 0.0, 1.0]));
        assert_eq!(s.reference.rotation, [0.0, 0.0, 1.0]);
        assert_ne!(
            s.fingerprint(),
            Scenario::builtin("seed").unwrap().fingerprint()
        );
        let both =
            format!("{head}[reference]\nrotation = [0.0, 0.0, 0.0]\nwaypoints = \"w.csv\"\n");
        let e = Scenario::from_toml(&both, "both", "both")
            .unwrap_err()
            .to_string();
        assert!(e.contains("key `reference`: give exactly one of"), "{e}");
        let pos = format!(
            "{head}[reference]\nsetpoint = {{ rotation = [0.0, 0.0, 1.0], position = [1.0, 0.0, 0.0] }}\n"
        );
        let e = Scenario::from_toml(&pos, "pos", "pos")
            .unwrap_err()
            .to_string();
        assert!(e.contains("reference.setpoint.position"), "{e}");
        let file = Scenario::from_file(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenarios/slew_se3.toml"
        )))
        .unwrap();
        assert_eq!(
            file.path.as_ref().unwrap().poses[1].position,
            [2.0, 0.0, 0.0]
        );
    }

    #[test]
    fn law_override_is_checked_against_the_group() {
        let e = Scenario::builtin("se3_circle")
            .unwrap()
            .with_law(Law::Gt)
            .unwrap_err();
        assert!(e.to_string().contains("not defined for group se3"), "{e}");
        let s = Scenario::builtin("seed")
            .unwrap()
            .with_law(Law::Asym)
            .unwrap();
        assert_eq!(s.law, Law::Asym);
    }

    #[test]
    fn the_fingerprint_covers_what_the_controller_uses_and_nothing_else() {
        let seed = Scenario::builtin("seed").unwrap();
        let fp = seed.fingerprint();
        assert_ne!(fp, 0);
        assert_ne!(fp, Scenario::builtin("montecarlo").unwrap().fingerprint());
        assert_ne!(fp, Scenario::builtin("se3_circle").unwrap().fingerprint());
        // not covered: law, duration, name, the plant's own state
        let mut same = seed.clone().with_law(Law::Gt).unwrap();
        same.duration = 3.0;
        same.name = "other".to_owned();
        same.initial.velocity[0] += 1.0;
        same.disturbance[1] = 0.5;
        assert_eq!(same.fingerprint(), fp);
        // covered: gains, model inertia, period, limit, reference
        let changes: [fn(&mut Scenario); 6] = [
            |s| s.kd[0] += 1e-9,
            |s| s.model_inertia[4] *= 1.01,
            |s| s.control_period = 0.001,
            |s| s.torque_limit = Some(vec![5.0; 3]),
            |s| s.reference.rotation[2] = 0.1,
            |s| s.feedforward[0].terms[0].frequency = 2.0,
        ];
        for change in changes {
            let mut s = seed.clone();
            change(&mut s);
            assert_ne!(s.fingerprint(), fp);
        }
    }
}
