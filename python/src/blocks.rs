//! The building blocks from Python, each stepping on numpy arrays: the law
//! (docs/maths.md, "The EqT law" and the comparison laws), the complementary filter and the
//! equivariant filter (docs/maths.md, "Estimators"), and a vehicle's allocator
//! (docs/maths.md, "Control allocation").

use crate::arrays::{matrix, out1, out2, read_into, rows, rows3, vector};
use crate::source;
use eqtrack_controller::group::{Se2, Se3, So3};
use eqtrack_controller::law::Desired;
use eqtrack_controller::{Controller as Law, GroupKind};
use eqtrack_estimator::{
    AttitudeEstimate, ComplementaryConfig, ComplementaryFilter as Cf, EqfConfig,
    EquivariantFilter as Eqf,
};
use nalgebra::{SVector, Vector3};
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

enum Either {
    So3(Box<Law<f64, So3, 3, 3>>),
    Se3(Box<Law<f64, Se3, 4, 6>>),
    Se2(Box<Law<f64, Se2, 3, 3>>),
}

/// The scenario's controller (its law, gains, model inertia and torque limit).
#[pyclass(module = "eqtrack._native", name = "Controller", frozen)]
struct Controller {
    law: Either,
    group: GroupKind,
}

fn compute<G, const N: usize, const M: usize>(
    py: Python<'_>,
    law: &Law<f64, G, N, M>,
    args: [&Bound<'_, PyAny>; 4],
    tau_d: Option<&Bound<'_, PyAny>>,
) -> PyResult<(Py<PyArray1<f64>>, f64)>
where
    G: eqtrack_controller::BuiltinGroup<N, M>,
{
    let q = matrix::<N, N>(args[0], "q")?;
    let v = vector::<M>(args[1], "v")?;
    let q_d = matrix::<N, N>(args[2], "q_d")?;
    let v_d = vector::<M>(args[3], "v_d")?;
    let tau = match tau_d {
        Some(t) => vector::<M>(t, "tau_d")?,
        None => SVector::zeros(),
    };
    let desired = Desired {
        q: q_d,
        p: law.config().inertia * v_d,
        v: v_d,
        tau,
    };
    let out = law.compute(&q, &v, &desired).map_err(value_err)?;
    Ok((out1(py, out.torque.as_slice()).unbind(), out.lyapunov.total))
}

#[pymethods]
impl Controller {
    /// The controller of `scenario` (a path or TOML text), with `overrides` merged in.
    #[new]
    #[pyo3(signature = (scenario, overrides=None))]
    fn new(scenario: &Bound<'_, PyAny>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let s = source::load(scenario, overrides)?;
        let law = match s.group {
            GroupKind::So3 => {
                Either::So3(Box::new(s.controller::<So3, 3, 3>().map_err(value_err)?))
            }
            GroupKind::Se3 => {
                Either::Se3(Box::new(s.controller::<Se3, 4, 6>().map_err(value_err)?))
            }
            GroupKind::Se2 => {
                Either::Se2(Box::new(s.controller::<Se2, 3, 3>().map_err(value_err)?))
            }
        };
        Ok(Controller {
            law,
            group: s.group,
        })
    }

    /// The group: `"so3"`, `"se3"` or `"se2"`.
    #[getter]
    fn group(&self) -> &'static str {
        self.group.name()
    }

    /// The law's torque (after its limit) and the Lyapunov function at the state `(q, v)`
    /// against the desired `(q_d, v_d)` with feedforward `tau_d` (default 0); `p_d = I v_d`
    /// with the model inertia.
    #[pyo3(signature = (q, v, q_d, v_d, tau_d=None))]
    fn compute(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        v: &Bound<'_, PyAny>,
        q_d: &Bound<'_, PyAny>,
        v_d: &Bound<'_, PyAny>,
        tau_d: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(Py<PyArray1<f64>>, f64)> {
        match &self.law {
            Either::So3(l) => compute(py, l, [q, v, q_d, v_d], tau_d),
            Either::Se3(l) => compute(py, l, [q, v, q_d, v_d], tau_d),
            Either::Se2(l) => compute(py, l, [q, v, q_d, v_d], tau_d),
        }
    }
}

fn step_args(
    h: f64,
    gyro: &Bound<'_, PyAny>,
    directions: &Bound<'_, PyAny>,
    count: usize,
) -> PyResult<(Vector3<f64>, Vec<Vector3<f64>>)> {
    if !(h.is_finite() && h > 0.0) {
        return Err(PyValueError::new_err(format!(
            "h: {h} is not a finite positive period"
        )));
    }
    Ok((
        vector::<3>(gyro, "gyro")?,
        rows3(directions, "directions", count)?,
    ))
}

type Estimate<'py> = (
    Bound<'py, numpy::PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    bool,
);

fn estimate<'py>(py: Python<'py>, e: &AttitudeEstimate<f64>) -> PyResult<Estimate<'py>> {
    Ok((
        out2(py, &e.r)?,
        out1(py, e.rate.as_slice()),
        out1(py, e.bias.as_slice()),
        e.started,
    ))
}

fn world(obj: &Bound<'_, PyAny>) -> PyResult<Vec<Vector3<f64>>> {
    rows3(obj, "world", rows(obj, "world")?)
}

fn per_direction(obj: &Bound<'_, PyAny>, name: &str, k: usize) -> PyResult<Vec<f64>> {
    let mut v = vec![0.0; k];
    read_into(obj, name, &[k], &mut v)?;
    Ok(v)
}

/// The complementary filter on SO(3) with gyro bias.
#[pyclass(module = "eqtrack._native", name = "ComplementaryFilter")]
struct ComplementaryFilter {
    filter: Cf<f64>,
    count: usize,
}

#[pymethods]
impl ComplementaryFilter {
    /// Gains `kp`, `ki`, the world directions (k × 3, 2 ≤ k ≤ 4) and their weights (k).
    #[new]
    fn new(
        kp: f64,
        ki: f64,
        world: &Bound<'_, PyAny>,
        weights: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let w = self::world(world)?;
        let weights = per_direction(weights, "weights", w.len())?;
        let cfg = ComplementaryConfig::new(kp, ki, &w, &weights).map_err(value_err)?;
        Ok(ComplementaryFilter {
            filter: Cf::new(cfg),
            count: w.len(),
        })
    }

    /// One step over `h` seconds with the gyro (3) and the body directions (k × 3); returns
    /// `(R̂, ω̂, b̂, started)`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        h: f64,
        gyro: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
    ) -> PyResult<Estimate<'py>> {
        let (g, d) = step_args(h, gyro, directions, self.count)?;
        estimate(py, &self.filter.step(h, &g, &d))
    }
}

/// The equivariant filter on SO(3) with gyro bias.
#[pyclass(module = "eqtrack._native", name = "EquivariantFilter")]
struct EquivariantFilter {
    filter: Eqf<f64>,
    count: usize,
}

#[pymethods]
impl EquivariantFilter {
    /// The gyro's noise density and bias walk, the world directions (k × 3) and each
    /// direction's noise (k).
    #[new]
    fn new(
        gyro_noise: f64,
        bias_walk: f64,
        world: &Bound<'_, PyAny>,
        direction_noise: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let w = self::world(world)?;
        let noise = per_direction(direction_noise, "direction_noise", w.len())?;
        let cfg = EqfConfig::new(gyro_noise, bias_walk, &w, &noise).map_err(value_err)?;
        Ok(EquivariantFilter {
            filter: Eqf::new(cfg),
            count: w.len(),
        })
    }

    /// One step, as [`ComplementaryFilter::step`].
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        h: f64,
        gyro: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
    ) -> PyResult<Estimate<'py>> {
        let (g, d) = step_args(h, gyro, directions, self.count)?;
        estimate(py, &self.filter.step(h, &g, &d))
    }

    /// The covariance `Σ` (6 × 6: attitude, then bias).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        out2(py, self.filter.covariance())
    }
}

enum Alloc {
    Three(Box<eqtrack_allocation::Allocator<f64, 3>>),
    Six(Box<eqtrack_allocation::Allocator<f64, 6>>),
}

/// `(u_cmd, B u_cmd, status)`.
type Allocated<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>, u8);

/// A vehicle's allocator, from its scenario's `[vehicle]`.
#[pyclass(module = "eqtrack._native", name = "Allocator", frozen)]
struct Allocator {
    alloc: Alloc,
}

fn allocate<'py, const K: usize>(
    py: Python<'py>,
    a: &eqtrack_allocation::Allocator<f64, K>,
    demand: &Bound<'py, PyAny>,
) -> PyResult<Allocated<'py>> {
    let d = vector::<K>(demand, "demand")?;
    let r = a.allocate(&d);
    let count = a.geometry().count();
    Ok((
        out1(py, &r.u.as_slice()[..count]),
        out1(py, r.achieved.as_slice()),
        r.status.code(),
    ))
}

#[pymethods]
impl Allocator {
    /// The allocator of `scenario`'s `[vehicle]`.
    #[new]
    #[pyo3(signature = (scenario, overrides=None))]
    fn new(scenario: &Bound<'_, PyAny>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let s = source::load(scenario, overrides)?;
        let v = s.vehicle.as_ref().ok_or_else(|| {
            PyValueError::new_err(format!("scenario `{}` has no [vehicle]", s.name))
        })?;
        let alloc = match s.group {
            // a planar (se2) vehicle's allocator has the columns (τ, f_x, f_y)
            GroupKind::So3 | GroupKind::Se2 => {
                Alloc::Three(Box::new(v.allocator::<3>().map_err(value_err)?))
            }
            GroupKind::Se3 => Alloc::Six(Box::new(v.allocator::<6>().map_err(value_err)?)),
        };
        Ok(Allocator { alloc })
    }

    /// The number of actuators.
    #[getter]
    fn count(&self) -> usize {
        match &self.alloc {
            Alloc::Three(a) => a.geometry().count(),
            Alloc::Six(a) => a.geometry().count(),
        }
    }

    /// Allocates the wrench `demand` (3 on SO(3) and SE(2), 6 on SE(3)): returns `(u_cmd, B u_cmd,
    /// status)`, the status code of `trajectory.csv`'s `alloc_status`.
    fn allocate<'py>(
        &self,
        py: Python<'py>,
        demand: &Bound<'py, PyAny>,
    ) -> PyResult<Allocated<'py>> {
        match &self.alloc {
            Alloc::Three(a) => allocate(py, a, demand),
            Alloc::Six(a) => allocate(py, a, demand),
        }
    }
}

/// Adds the classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Controller>()?;
    m.add_class::<ComplementaryFilter>()?;
    m.add_class::<EquivariantFilter>()?;
    m.add_class::<Allocator>()?;
    Ok(())
}
