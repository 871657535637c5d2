//! Where a scenario comes from in Python: a path (`str` or `os.PathLike`) or TOML text, with
//! keyword overrides merged into its tables before it is validated, so a bad override is
//! refused with the same message as the same mistake in a file.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};
use scenario::Scenario;
use std::path::PathBuf;

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Is `text` a scenario's TOML rather than a path? TOML has a `=` or a line break; a path
/// has neither.
fn is_toml(text: &str) -> bool {
    text.contains('=') || text.contains('\n')
}

/// The scenario `source` names (a path or TOML text), with `overrides` merged in.
pub(crate) fn load(
    source: &Bound<'_, PyAny>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<Scenario> {
    let overrides = match overrides {
        Some(d) if !d.is_empty() => Some(table(d, "")?),
        _ => None,
    };
    if let Ok(text) = source.cast::<PyString>() {
        let text: String = text.extract()?;
        if is_toml(&text) {
            return parse(&text, "the scenario text", "scenario", None, overrides);
        }
    }
    let path: PathBuf = source.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "scenario: expected a path or TOML text, got {}",
            source
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    match overrides {
        None => Scenario::from_file(&path).map_err(value_err),
        Some(o) => {
            let (text, stem) = Scenario::read_file(&path).map_err(value_err)?;
            let origin = path.display().to_string();
            parse(&text, &origin, &stem, path.parent(), Some(o))
        }
    }
}

/// The scenario's TOML text (with `overrides` merged), for a study's workers.
pub(crate) fn text(
    source: &Bound<'_, PyAny>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<String> {
    // validate it here, where the error is the caller's
    load(source, overrides)?;
    let raw = match source.cast::<PyString>() {
        Ok(t) if is_toml(&t.extract::<String>()?) => t.extract::<String>()?,
        _ => {
            let path: PathBuf = source.extract()?;
            std::fs::read_to_string(&path).map_err(value_err)?
        }
    };
    match overrides {
        Some(d) if !d.is_empty() => {
            let mut doc: toml::Table = raw.parse().map_err(value_err)?;
            merge(&mut doc, table(d, "")?);
            Ok(doc.to_string())
        }
        _ => Ok(raw),
    }
}

fn parse(
    text: &str,
    origin: &str,
    name: &str,
    base: Option<&std::path::Path>,
    overrides: Option<toml::Table>,
) -> PyResult<Scenario> {
    let Some(o) = overrides else {
        return Scenario::from_toml_in(text, origin, name, base).map_err(value_err);
    };
    // a file that is not TOML is refused as the file would be, before anything is merged
    let mut doc: toml::Table = match text.parse() {
        Ok(d) => d,
        Err(_) => return Scenario::from_toml_in(text, origin, name, base).map_err(value_err),
    };
    merge(&mut doc, o);
    Scenario::from_toml_in(&doc.to_string(), origin, name, base).map_err(value_err)
}

/// Merges `over` into `doc`: a table into a table key by key, anything else replaces.
fn merge(doc: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (doc.get_mut(&k), v) {
            (Some(toml::Value::Table(d)), toml::Value::Table(o)) => merge(d, o),
            (_, v) => {
                doc.insert(k, v);
            }
        }
    }
}

fn table(d: &Bound<'_, PyDict>, at: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let key: String = k
            .extract()
            .map_err(|_| value_err(format!("override{at}: keys must be strings")))?;
        let path = format!("{at}.{key}");
        t.insert(key, value(&v, &path)?);
    }
    Ok(t)
}

/// A Python value as TOML: bool, int, float, str, a dict (a table) or a sequence (an array).
fn value(v: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        let i: i64 = v
            .extract()
            .map_err(|_| value_err(format!("override `{}`: integer out of range", &path[1..])))?;
        return Ok(toml::Value::Integer(i));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(table(d, path)?));
    }
    if let Ok(x) = v.extract::<f64>() {
        // numpy scalars and other numbers
        return Ok(toml::Value::Float(x));
    }
    if let Ok(items) = v.try_iter() {
        let mut a = Vec::new();
        for item in items {
            a.push(value(&item?, path)?);
        }
        return Ok(toml::Value::Array(a));
    }
    Err(value_err(format!(
        "override `{}`: cannot be written as TOML (a bool, number, string, dict or sequence)",
        &path[1..]
    )))
}
