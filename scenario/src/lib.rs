//! Scenario files: the TOML schema, its validation, the built-in scenarios, and the builders
//! that turn a validated [`Scenario`] into the controller crate's objects. Both processes
//! (plant and controller) read configuration only through this crate.
//!
//! The schema, key by key (type, unit, default and meaning of every key this crate accepts,
//! and the waypoint file's columns), is docs/scenario.md.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod cli;
pub mod failsafe;
pub mod fault_detection;
mod firmware;
pub mod moving;
pub mod rejection;
pub mod sensing;
pub mod vehicle;
pub mod waypoints;
pub mod wheels;

mod build;
mod raw;
mod spec;
pub mod tuning;
mod validate;

use raw::*;
pub use spec::build_path;
pub use spec::{Axis, PathKind, PathSpec, Pose, StateSpec, Term};
use validate::{Validator, parse_law};

pub use rejection::{IntegralSpec, ObserverSpec, RejectionSpec, StepSpec};
pub use sensing::{
    DirectionSpec, EqfSpec, EstimatorKind, EstimatorSpec, GyroSpec, PositionSpec, SensorsSpec,
};

use eqtrack_controller::{ErrorFrame, GroupKind, Law};

/// The built-in scenarios, shipped as TOML files in `scenarios/`.
pub const BUILTINS: [(&str, &str); 4] = [
    ("seed", include_str!("../../scenarios/seed.toml")),
    (
        "montecarlo",
        include_str!("../../scenarios/montecarlo.toml"),
    ),
    (
        "se3_circle",
        include_str!("../../scenarios/se3_circle.toml"),
    ),
    (
        "se2_circle",
        include_str!("../../scenarios/se2_circle.toml"),
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
    #[error(
        "unknown built-in scenario `{0}` (available: seed, montecarlo, se3_circle, se2_circle)"
    )]
    UnknownBuiltin(String),
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
    /// `controller.error_frame`: where EqT forms its error (default
    /// [`ErrorFrame::Reference`]).
    pub error_frame: ErrorFrame,
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
    /// `[vehicle]` and `[allocation]`: actuators, gravity, buoyancy, added mass, drag, and
    /// the allocation of the law's wrench (`None`: the wrench acts on the body directly).
    pub vehicle: Option<vehicle::VehicleSpec>,
    /// `[fault_detection]`: the detector of actuator failures nobody announces (`None`:
    /// off, the default).
    pub fault_detection: Option<fault_detection::FaultDetectionSpec>,
    /// `[failsafe]`: the failsafe manager's actions and limits (`None`: off, the default).
    pub failsafe: Option<failsafe::FailsafeSpec>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

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
