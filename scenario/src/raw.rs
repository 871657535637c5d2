//! The TOML schema as serde reads it: every table with `deny_unknown_fields`, so an unknown key is refused naming the keys the table takes (docs/scenario.md is the reference).

use crate::{failsafe, fault_detection, rejection, sensing, vehicle};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScenario {
    pub(crate) name: Option<String>,
    pub(crate) group: String,
    pub(crate) law: String,
    pub(crate) duration: f64,
    pub(crate) control_period: f64,
    pub(crate) plant_substeps: Option<i64>,
    pub(crate) reference_substeps: Option<i64>,
    pub(crate) plant: RawPlant,
    pub(crate) controller: RawController,
    pub(crate) initial: RawState,
    pub(crate) reference: RawReference,
    pub(crate) sensors: Option<sensing::RawSensors>,
    pub(crate) estimator: Option<sensing::RawEstimator>,
    pub(crate) vehicle: Option<vehicle::RawVehicle>,
    pub(crate) allocation: Option<vehicle::RawAllocation>,
    pub(crate) fault_detection: Option<fault_detection::RawFaultDetection>,
    pub(crate) failsafe: Option<failsafe::RawFailsafe>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawPlant {
    pub(crate) inertia: Vec<Vec<f64>>,
    pub(crate) torque_limit: Option<NumberOrList>,
    pub(crate) disturbance: Option<Vec<f64>>,
    pub(crate) disturbance_world: Option<Vec<f64>>,
    pub(crate) disturbance_steps: Option<Vec<rejection::RawStep>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawController {
    /// Read as any value, so that a number or a list is refused naming the accepted strings.
    pub(crate) error_frame: Option<toml::Value>,
    pub(crate) inertia: Option<Vec<Vec<f64>>>,
    pub(crate) kp: NumberOrMatrix,
    pub(crate) kd: NumberOrMatrix,
    pub(crate) disturbance_observer: Option<rejection::RawObserver>,
    pub(crate) integral: Option<rejection::RawIntegral>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawState {
    pub(crate) rotation: Vec<f64>,
    pub(crate) position: Option<Vec<f64>>,
    pub(crate) velocity: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawReference {
    pub(crate) rotation: Option<Vec<f64>>,
    pub(crate) position: Option<Vec<f64>>,
    pub(crate) velocity: Option<Vec<f64>>,
    pub(crate) torque: Option<Vec<RawAxis>>,
    pub(crate) waypoints: Option<String>,
    pub(crate) path: Option<String>,
    pub(crate) setpoint: Option<RawPose>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawPose {
    pub(crate) rotation: Vec<f64>,
    pub(crate) position: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAxis {
    #[serde(default)]
    pub(crate) offset: f64,
    #[serde(default)]
    pub(crate) terms: Vec<RawTerm>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTerm {
    pub(crate) amplitude: f64,
    pub(crate) frequency: f64,
    #[serde(default)]
    pub(crate) phase: f64,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum NumberOrMatrix {
    Number(f64),
    Matrix(Vec<Vec<f64>>),
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub(crate) enum NumberOrList {
    Number(f64),
    List(Vec<f64>),
}
