//! The Monte Carlo study (docs/simulations.md): whole in this process, or one seed-indexed
//! shard at a time (the bytes of `plant_sim montecarlo --shard`'s `shard.bin`) and the shards
//! merged, so that every engine gives the command line's `runs.csv`, bit for bit.

use crate::{sim_err, source};
use eqtrack_controller::Law;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use scenario::Scenario;
use studies::montecarlo as mc;
use studies::montecarlo::{RunResult, Sample};
use studies::shard::{Shard, Study};

/// What a study needs: the base scenario, the drawn samples and the laws.
struct Plan {
    base: Scenario,
    samples: Vec<Sample>,
    laws: Vec<Law>,
}

impl Plan {
    fn new(scenario: Option<&str>, runs: usize, seed: u64, laws: Vec<String>) -> PyResult<Plan> {
        let base = match scenario {
            Some(text) => Scenario::from_toml(text, "the scenario text", "scenario"),
            None => Scenario::builtin("montecarlo"),
        }
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
        if runs == 0 {
            return Err(PyValueError::new_err("runs: must be at least 1"));
        }
        if laws.is_empty() {
            return Err(PyValueError::new_err("laws: give at least one law"));
        }
        let laws = laws
            .iter()
            .map(|l| {
                Law::from_name(l).ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "laws: `{l}` is not a law (possible values: {})",
                        Law::ALL.map(Law::name).join(", ")
                    ))
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        Ok(Plan {
            base,
            samples: mc::draw_samples(runs, seed),
            laws,
        })
    }

    fn study(&self) -> Study {
        Study::new(self.base.fingerprint(), &self.samples, &self.laws)
    }

    fn fly(
        &self,
        share: &[(usize, Sample)],
        threads: Option<usize>,
    ) -> Result<Vec<RunResult>, plant::SimError> {
        let stop = link::StopFlag::never();
        mc::run_indexed(&self.base, share, &self.laws, threads, &|| {}, &stop)
    }
}

/// `runs.csv`'s columns: `run`, `law` (a list of names), the sample, the final attitude
/// error, the two efforts and the settling time (NaN where the run did not settle).
fn columns<'py>(py: Python<'py>, results: &[RunResult]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let f = |g: &dyn Fn(&RunResult) -> f64| -> Vec<f64> { results.iter().map(g).collect() };
    d.set_item(
        "run",
        PyArray1::from_vec(py, results.iter().map(|r| r.run as i64).collect()),
    )?;
    d.set_item(
        "law",
        PyList::new(py, results.iter().map(|r| r.law.name()))?,
    )?;
    for (i, name) in ["rx", "ry", "rz"].iter().enumerate() {
        d.set_item(*name, PyArray1::from_vec(py, f(&|r| r.sample.r[i])))?;
    }
    for (i, name) in ["wx", "wy", "wz"].iter().enumerate() {
        d.set_item(*name, PyArray1::from_vec(py, f(&|r| r.sample.w[i])))?;
    }
    d.set_item(
        "final_attitude_error",
        PyArray1::from_vec(py, f(&|r| r.final_attitude_error)),
    )?;
    d.set_item("effort_0_5", PyArray1::from_vec(py, f(&|r| r.effort_0_5)))?;
    d.set_item("effort_0_20", PyArray1::from_vec(py, f(&|r| r.effort_0_20)))?;
    d.set_item(
        "settling_time",
        PyArray1::from_vec(py, f(&|r| r.settling_time.unwrap_or(f64::NAN))),
    )?;
    Ok(d)
}

/// The whole study in this process on `threads` threads (default: one per core).
#[pyfunction]
#[pyo3(signature = (scenario, runs, seed, laws, threads=None))]
fn montecarlo<'py>(
    py: Python<'py>,
    scenario: Option<&str>,
    runs: usize,
    seed: u64,
    laws: Vec<String>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads: must be at least 1"));
    }
    let plan = Plan::new(scenario, runs, seed, laws)?;
    let all: Vec<(usize, Sample)> = plan.samples.iter().copied().enumerate().collect();
    let results = py.detach(|| plan.fly(&all, threads)).map_err(sim_err)?;
    columns(py, &results)
}

/// Shard `index` of `count` of the study, on one thread: the bytes of its `shard.bin`.
#[pyfunction]
fn montecarlo_shard<'py>(
    py: Python<'py>,
    scenario: Option<&str>,
    runs: usize,
    seed: u64,
    laws: Vec<String>,
    index: usize,
    count: usize,
) -> PyResult<Bound<'py, PyBytes>> {
    let shard: Shard = format!("{index}/{count}")
        .parse()
        .map_err(|e: String| PyValueError::new_err(format!("shard: {e}")))?;
    let plan = Plan::new(scenario, runs, seed, laws)?;
    let bytes = py
        .detach(|| -> Result<Vec<u8>, plant::SimError> {
            let results = plan.fly(&shard.select(&plan.samples), Some(1))?;
            Ok(studies::shard::encode_shard(shard, &plan.study(), &results))
        })
        .map_err(sim_err)?;
    Ok(PyBytes::new(py, &bytes))
}

/// The shards' bytes (every shard once, in any order) merged into the study's columns; a
/// shard of another study, a duplicate or a missing shard is refused, naming it.
#[pyfunction]
fn montecarlo_merge<'py>(
    py: Python<'py>,
    scenario: Option<&str>,
    runs: usize,
    seed: u64,
    laws: Vec<String>,
    shards: Vec<Vec<u8>>,
) -> PyResult<Bound<'py, PyDict>> {
    let plan = Plan::new(scenario, runs, seed, laws)?;
    let named: Vec<(String, Vec<u8>)> = shards
        .into_iter()
        .enumerate()
        .map(|(i, b)| (format!("result {i}"), b))
        .collect();
    let results = studies::shard::merge_encoded(&named, &plan.study()).map_err(sim_err)?;
    columns(py, &results)
}

/// A scenario source (path or TOML text) with overrides, as the TOML text a study's workers
/// load (`None` stays the built-in `montecarlo`).
#[pyfunction]
#[pyo3(signature = (scenario, overrides=None))]
fn scenario_text(
    scenario: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<Option<String>> {
    match scenario {
        None if overrides.is_some_and(|o| !o.is_empty()) => {
            let text = crate::builtin_scenario("montecarlo")?;
            let text = pyo3::types::PyString::new(overrides.unwrap().py(), &text);
            source::text(text.as_any(), overrides).map(Some)
        }
        None => Ok(None),
        Some(s) => source::text(s, overrides).map(Some),
    }
}

/// Adds the functions to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(montecarlo, m)?)?;
    m.add_function(wrap_pyfunction!(montecarlo_shard, m)?)?;
    m.add_function(wrap_pyfunction!(montecarlo_merge, m)?)?;
    m.add_function(wrap_pyfunction!(scenario_text, m)?)?;
    Ok(())
}
