//! The Python package `eqtrack`'s native module (`eqtrack._native`; docs/python.md): thin
//! bindings over the libraries the command line uses, so that Python gets the same numbers.
//!
//! - `simulate`: `plant_sim sim`'s closed loop, its `trajectory.csv` columns (from the one
//!   table the CSV is written from) and its `summary.json`.
//! - `montecarlo`, `montecarlo_shard`, `montecarlo_merge`: the Monte Carlo study, whole or in
//!   the seed-indexed shards of `plant_sim montecarlo --shard` (the Ray engine's tasks).
//! - `Controller`, `ComplementaryFilter`, `EquivariantFilter`, `Allocator`: the building
//!   blocks, stepping on numpy arrays.
//!
//! Every input is checked: a bad value raises `ValueError` naming it, with the message the
//! command line gives for the same mistake; nothing here panics on user input. Long work runs
//! with the GIL released (`Python::detach`).
#![forbid(unsafe_code)]
#![deny(missing_docs)]

mod arrays;
mod blocks;
mod detector;
mod source;
mod study;

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A simulation error as a Python exception: bad input is a `ValueError`, a run that failed
/// a `RuntimeError`, an interrupted one `KeyboardInterrupt`.
pub(crate) fn sim_err(e: plant::SimError) -> PyErr {
    match e {
        plant::SimError::Input(_) => PyValueError::new_err(e.to_string()),
        plant::SimError::Interrupted(_) => {
            pyo3::exceptions::PyKeyboardInterrupt::new_err(e.to_string())
        }
        _ => PyRuntimeError::new_err(e.to_string()),
    }
}

/// Runs the scenario's closed loop in this process, as `plant_sim sim` does. Returns
/// `(header, columns, summary_json)`: the `trajectory.csv` column names, one list of floats
/// per column (an empty cell is NaN) and `summary.json`'s text.
#[pyfunction]
#[pyo3(signature = (scenario, overrides=None))]
fn simulate<'py>(
    py: Python<'py>,
    scenario: &Bound<'py, PyAny>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyList>, String)> {
    let s = source::load(scenario, overrides)?;
    let (header, columns, summary) = py
        .detach(|| -> Result<_, plant::SimError> {
            let traj = plant::trajectory::simulate(&s, &|_| Ok(()))?;
            let mut columns: Vec<Vec<f64>> = Vec::new();
            let header = plant::output::trajectory_table(&traj, |cells| {
                columns.resize_with(cells.len(), || Vec::with_capacity(traj.rows.len()));
                for (c, cell) in columns.iter_mut().zip(cells) {
                    c.push(cell.value());
                }
                Ok(())
            })?;
            let summary =
                plant::output::Summary::of(&traj, &s.name, s.law.name()).with_error_frame(&s);
            let json = serde_json::to_string(&summary)
                .map_err(|e| plant::SimError::Run(format!("cannot encode the summary: {e}")))?;
            Ok((header, columns, json))
        })
        .map_err(sim_err)?;
    let arrays = columns
        .into_iter()
        .map(|c| numpy::PyArray1::from_vec(py, c))
        .collect::<Vec<_>>();
    Ok((PyList::new(py, header)?, PyList::new(py, arrays)?, summary))
}

/// The text of a built-in scenario (`seed`, `montecarlo`, `se3_circle`, …), for `simulate`.
#[pyfunction]
fn builtin_scenario(name: &str) -> PyResult<String> {
    scenario::BUILTINS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| (*text).to_owned())
        .ok_or_else(|| {
            PyValueError::new_err(
                scenario::ScenarioError::UnknownBuiltin(name.to_owned()).to_string(),
            )
        })
}

/// The package's native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_scenario, m)?)?;
    study::register(m)?;
    blocks::register(m)?;
    detector::register(m)?;
    Ok(())
}
