//! The failure detector as a building block (docs/maths.md, "Failure detection"): a
//! vehicle's allocation with its detector, stepped from Python one control period at a time
//! exactly as the controller steps it (`control_cycle::ControllerVehicle`, the code the
//! pair's controller runs): the detector's cycle over the period that ended, what it found
//! told to the allocator, then the wrench allocated.

use crate::arrays::{matrix, out1, vector};
use crate::source;
use control_cycle::ControllerVehicle;
use eqtrack_controller::GroupKind;
use eqtrack_controller::group::{BuiltinGroup, Se3, So3};
use ipc_types::{CommandMsg, StateMsg, WireGroup};
use nalgebra::SVector;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

enum Vehicle {
    So3(Box<ControllerVehicle<3>>),
    Se3(Box<ControllerVehicle<6>>),
}

/// A vehicle's allocation with its failure detector, from a scenario with `[vehicle]` and
/// `[fault_detection]`.
#[pyclass(module = "eqtrack._native", name = "Detector")]
struct Detector {
    vehicle: Vehicle,
    period: f64,
    seq: u64,
    /// The wrench the last step accounted for (what the vehicle applies when it flies the
    /// commands as given).
    accounted: [f64; 6],
}

/// The arguments of one step, checked.
struct Step<'a, 'py> {
    t: f64,
    q: &'a Bound<'py, PyAny>,
    v: &'a Bound<'py, PyAny>,
    wrench: &'a Bound<'py, PyAny>,
    applied: Option<&'a Bound<'py, PyAny>>,
    follows: bool,
}

fn step<'py, G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    py: Python<'py>,
    vehicle: &mut ControllerVehicle<M>,
    state: &mut StateMsg,
    accounted: &mut [f64; 6],
    a: &Step<'_, 'py>,
) -> PyResult<Bound<'py, PyDict>> {
    let q = matrix::<N, N>(a.q, "q")?;
    let v = vector::<M>(a.v, "v")?;
    let wrench = vector::<M>(a.wrench, "wrench")?;
    let applied = match a.applied {
        Some(x) => vector::<M>(x, "applied")?,
        None => SVector::<f64, M>::from_fn(|i, _| accounted[i]),
    };
    state.set_state(&q, &v);
    state.set_applied(&applied);
    let mut cmd = CommandMsg::new(link::wire::wire_group(G::KIND));
    vehicle.answer::<G, N>(state, &wrench, a.follows, &mut cmd);
    accounted[..M].copy_from_slice(&cmd.accounted[..M]);
    let count = vehicle.count();
    let out = PyDict::new(py);
    out.set_item("u_cmd", out1(py, &cmd.u_cmd[..count]))?;
    out.set_item("demand", out1(py, &cmd.demand[..M]))?;
    out.set_item("achieved", out1(py, &cmd.achieved[..M]))?;
    out.set_item("accounted", out1(py, &cmd.accounted[..M]))?;
    out.set_item("status", cmd.alloc_status)?;
    out.set_item("alarms", cmd.alarms)?;
    let testing = cmd.suspect > 0;
    out.set_item("suspect", testing.then(|| cmd.suspect - 1))?;
    out.set_item("statistic", testing.then_some(cmd.statistic))?;
    let found = match (cmd.detected.checked_sub(1), detection_kind(&cmd)) {
        (Some(j), Some(kind)) => {
            let d = PyDict::new(py);
            d.set_item("actuator", j)?;
            d.set_item("kind", kind.name())?;
            d.set_item("value", kind.value())?;
            d.set_item("refined", cmd.detected_refined == 1)?;
            Some(d)
        }
        _ => None,
    };
    out.set_item("detection", found)?;
    Ok(out)
}

fn detection_kind(cmd: &CommandMsg) -> Option<detection::Kind<f64>> {
    detection::Kind::from_code(cmd.detected_kind, cmd.detected_value)
}

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

#[pymethods]
impl Detector {
    /// The vehicle of `scenario` (a path or TOML text, with `overrides` merged in) with its
    /// failure detector; the scenario needs `[vehicle]` and `[fault_detection]`.
    #[new]
    #[pyo3(signature = (scenario, overrides=None))]
    fn new(scenario: &Bound<'_, PyAny>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let s = source::load(scenario, overrides)?;
        if s.vehicle.is_none() {
            return Err(value_err(format!("scenario `{}` has no [vehicle]", s.name)));
        }
        if s.fault_detection.is_none() {
            return Err(value_err(format!(
                "scenario `{}` has no [fault_detection]",
                s.name
            )));
        }
        if s.vehicle.as_ref().is_some_and(|v| !v.wheels.is_empty()) {
            // `step` takes no wheel speeds: the gyroscopic term and the wheels' momentum in
            // the residual would be missing
            return Err(value_err(format!(
                "scenario `{}`: vehicle.wheel: the Detector does not take reaction wheels' speeds yet (fly them with simulate or the process pair)",
                s.name
            )));
        }
        let vehicle = match s.group {
            GroupKind::So3 => Vehicle::So3(Box::new(ControllerVehicle::of(&s).map_err(value_err)?)),
            GroupKind::Se3 => Vehicle::Se3(Box::new(ControllerVehicle::of(&s).map_err(value_err)?)),
            // the scenario refuses [fault_detection] on se2 before
            GroupKind::Se2 => {
                return Err(value_err(format!(
                    "scenario `{}`: the Detector does not run on se2",
                    s.name
                )));
            }
        };
        Ok(Detector {
            vehicle,
            period: s.control_period,
            seq: 0,
            accounted: [0.0; 6],
        })
    }

    /// The number of actuators.
    #[getter]
    fn count(&self) -> usize {
        match &self.vehicle {
            Vehicle::So3(v) => v.count(),
            Vehicle::Se3(v) => v.count(),
        }
    }

    /// The actuators found failed so far (0-based).
    #[getter]
    fn failed(&self) -> Vec<usize> {
        let failed = match &self.vehicle {
            Vehicle::So3(v) => v.detector().map(|d| *d.failed()),
            Vehicle::Se3(v) => v.detector().map(|d| *d.failed()),
        };
        failed
            .map(|f| (0..self.count()).filter(|j| f[*j]).collect())
            .unwrap_or_default()
    }

    /// One control period at time `t` (s) with the state `(q, v)` the controller sees and
    /// the law's `wrench`: the detector's cycle over the period that ended (it counts only
    /// when `follows`, the step before was the period before, and the vehicle applied the
    /// last step's wrench: `applied`, by default the last step's `accounted`), then the
    /// wrench allocated. Returns a dict: `u_cmd`, `demand`, `achieved`, `accounted`,
    /// `status` (`trajectory.csv`'s `alloc_status`), `alarms`, `suspect` and `statistic`
    /// (the last test's best actuator and its χ²₁ statistic; `None` before it tests), and
    /// `detection`: `None`, or what it found in this period (`actuator`, `kind`, `value`,
    /// `refined`), already told to the allocator.
    #[pyo3(signature = (t, q, v, wrench, applied=None, follows=true))]
    #[expect(
        clippy::too_many_arguments,
        reason = "Python's keyword signature: each argument is one the caller names"
    )]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        q: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        wrench: &Bound<'py, PyAny>,
        applied: Option<&Bound<'py, PyAny>>,
        follows: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        if !t.is_finite() {
            return Err(value_err(format!("t: {t} is not a finite time")));
        }
        let args = Step {
            t,
            q,
            v,
            wrench,
            applied,
            follows,
        };
        let group = match &self.vehicle {
            Vehicle::So3(_) => WireGroup::So3,
            Vehicle::Se3(_) => WireGroup::Se3,
        };
        let mut state = StateMsg::new(group);
        state.seq = self.seq;
        state.t = args.t;
        state.control_period = self.period;
        let out = match &mut self.vehicle {
            Vehicle::So3(veh) => {
                step::<So3, 3, 3>(py, veh, &mut state, &mut self.accounted, &args)?
            }
            Vehicle::Se3(veh) => {
                step::<Se3, 4, 6>(py, veh, &mut state, &mut self.accounted, &args)?
            }
        };
        self.seq += 1;
        Ok(out)
    }
}

/// Adds the class to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Detector>()
}
