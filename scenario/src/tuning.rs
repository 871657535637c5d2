//! Run-time parameters (docs/live.md, "Tuning a running pair"): the scenario keys a running
//! pair may change, and the one check of a new value, which is the scenario's own: the value
//! is written into the run's scenario text and the whole scenario is validated again, so a
//! bad value is refused with the message the scenario file would get.
//!
//! Only gains change. A change that would alter anything else (another key, a term the run
//! did not start with) is refused, so everything the fingerprint handshake checked at the
//! start stays as it was.

use crate::{Scenario, ScenarioError};
use std::path::PathBuf;

/// The keys that may change while a pair runs, and their short names.
pub const TUNABLE: [(&str, Option<&str>); 7] = [
    ("controller.kp", Some("kp")),
    ("controller.kd", Some("kd")),
    ("controller.disturbance_observer.gain", None),
    ("controller.integral.ki", None),
    ("controller.integral.c", None),
    ("estimator.kp", None),
    ("estimator.ki", None),
];

/// The list of tunable keys, for messages.
pub fn tunable_list() -> String {
    TUNABLE
        .iter()
        .map(|(k, short)| match short {
            Some(s) => format!("{k} ({s})"),
            None => (*k).to_owned(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Where a tunable key acts: on the controller's gains, or on the plant's estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Acts {
    /// `K`, `K_d` or a disturbance-rejection gain: the controller (and the plant's
    /// safe-mode damping for `K_d`).
    Controller,
    /// The complementary filter's `k_P` or `k_I`: the plant's estimator.
    Estimator,
}

/// A checked change, not yet in force.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    /// The full key (`controller.kd`).
    pub key: &'static str,
    /// The new value as TOML text, exactly as the scenario now holds it.
    pub value: String,
    /// The value before, as TOML text.
    pub previous: String,
    /// The scenario with the change.
    pub scenario: Scenario,
    /// The value as the scenario holds it (what [`Tuner::commit`] puts in force: the text
    /// read again could differ in type, `1_000` an integer, `1000` a float).
    parsed: toml::Value,
}

impl Change {
    /// Where the change acts.
    pub fn acts(&self) -> Acts {
        acts(self.key)
    }
}

/// Where `key` (a full tunable key) acts.
pub fn acts(key: &str) -> Acts {
    if key.starts_with("estimator.") {
        Acts::Estimator
    } else {
        Acts::Controller
    }
}

/// The numbers a tunable key resolves to in `s` (a matrix row-major, a number per axis);
/// empty when the scenario has no such term.
pub fn numbers(s: &Scenario, key: &str) -> Vec<f64> {
    let r = &s.rejection;
    match key {
        "controller.kp" => s.kp.clone(),
        "controller.kd" => s.kd.clone(),
        "controller.disturbance_observer.gain" => r
            .observer
            .as_ref()
            .map(|o| o.gain.clone())
            .unwrap_or_default(),
        "controller.integral.ki" => r
            .integral
            .as_ref()
            .map(|i| i.ki.clone())
            .unwrap_or_default(),
        "controller.integral.c" => r.integral.as_ref().map(|i| i.c.clone()).unwrap_or_default(),
        "estimator.kp" => vec![s.estimator.kp],
        "estimator.ki" => vec![s.estimator.ki],
        _ => Vec::new(),
    }
}

/// The run's scenario as text, and every change checked against it.
#[derive(Debug, Clone)]
pub struct Tuner {
    table: toml::Table,
    origin: String,
    base: Option<PathBuf>,
    scenario: Scenario,
}

/// Reads a value as the command line gives it: a number as Rust reads one (`0.8`, `-1`,
/// `NaN`, `inf`), else a TOML value (`[[1.0, 0.0], [0.0, 1.0]]`, `[1.0, 2.0, 3.0]`).
pub fn parse_value(text: &str) -> Result<toml::Value, String> {
    let t = text.trim();
    if t.contains(['\n', '\r']) {
        return Err(format!(
            "value `{}`: one line, please (a number or a TOML value)",
            t.escape_debug()
        ));
    }
    if let Ok(x) = t.parse::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    toml::from_str::<toml::Table>(&format!("v = {t}"))
        .ok()
        .filter(|table| table.len() == 1)
        .and_then(|mut table| table.remove("v"))
        .ok_or_else(|| {
            format!(
                "value `{text}`: neither a number nor a TOML value (e.g. 0.8, or [1.0, 2.0, 3.0])"
            )
        })
}

/// The full key for `name` (a full key or a short name); `None` if it is not tunable.
pub fn resolve(name: &str) -> Option<&'static str> {
    TUNABLE
        .iter()
        .find(|(k, short)| *k == name || *short == Some(name))
        .map(|(k, _)| *k)
}

fn get<'t>(table: &'t toml::Table, path: &[&str]) -> Option<&'t toml::Value> {
    let (last, parents) = path.split_last()?;
    let mut t = table;
    for p in parents {
        t = t.get(*p)?.as_table()?;
    }
    t.get(*last)
}

/// Sets `path` in `table`, creating tables on the way (a key that does not exist then
/// meets the scenario's own check for unknown keys).
fn set(table: &mut toml::Table, path: &[&str], value: toml::Value) -> Result<(), String> {
    let Some((last, parents)) = path.split_last() else {
        return Err("an empty key".to_owned());
    };
    let mut t = table;
    for (i, p) in parents.iter().enumerate() {
        let entry = t
            .entry((*p).to_owned())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = entry.as_table_mut().ok_or_else(|| {
            format!(
                "key `{}`: `{}` is not a table",
                path.join("."),
                parents[..=i].join(".")
            )
        })?;
    }
    t.insert((*last).to_owned(), value);
    Ok(())
}

/// The message of a scenario error without its origin (the text after `origin: `).
fn message(e: &ScenarioError, origin: &str) -> String {
    let text = e.to_string();
    text.strip_prefix(&format!("{origin}: "))
        .map_or(text.clone(), str::to_owned)
}

impl Tuner {
    /// The tuner of a run whose scenario is `table` (its text parsed; with a `name`), from
    /// `origin`, with waypoint files relative to `base`.
    pub fn new(
        table: toml::Table,
        origin: &str,
        base: Option<PathBuf>,
    ) -> Result<Tuner, ScenarioError> {
        let scenario = parse(&table, origin, base.as_deref())?;
        Ok(Tuner {
            table,
            origin: origin.to_owned(),
            base,
            scenario,
        })
    }

    /// The tuner of the scenario `source` loads (`default`: the built-in it falls back to).
    pub fn from_source(
        source: &crate::cli::ScenarioSource,
        default: &str,
    ) -> Result<Tuner, ScenarioError> {
        let (table, origin, base) = source.table(default)?;
        Tuner::new(table, &origin, base)
    }

    /// The scenario with every change so far.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The value of `name` in force, as TOML text.
    pub fn get(&self, name: &str) -> Result<(&'static str, String), String> {
        let key = resolve(name).ok_or_else(|| not_tunable(name))?;
        self.value_of(key).map(|v| (key, v))
    }

    /// The value of a tunable key in force as TOML text: as the scenario file gives it, or,
    /// for a key its table leaves to a default (`estimator.kp`), the default.
    fn value_of(&self, key: &'static str) -> Result<String, String> {
        let path: Vec<&str> = key.split('.').collect();
        if let Some(v) = get(&self.table, &path) {
            return Ok(v.to_string());
        }
        let parent_exists = path.split_last().is_some_and(|(_, parents)| {
            get(&self.table, parents).is_some_and(toml::Value::is_table)
        });
        match numbers(&self.scenario, key).as_slice() {
            [x] if parent_exists => Ok(toml::Value::Float(*x).to_string()),
            _ => Err(absent(key)),
        }
    }

    /// Checks setting `name` to `value` (command-line text): the scenario's own validation
    /// of the scenario with the new value. Refused: a key that is not tunable (a key the
    /// scenario does not know gets the scenario's message for an unknown key), a value the
    /// scenario refuses (its message), a term the run did not start with.
    pub fn check(&self, name: &str, value: &str) -> Result<Change, String> {
        let parsed = parse_value(value)?;
        let path: Vec<&str> = name.split('.').collect();
        let Some(key) = resolve(name) else {
            // the scenario's message for a key it does not know; else: not tunable
            let mut table = self.table.clone();
            set(&mut table, &path, parsed)?;
            return Err(match parse(&table, &self.origin, self.base.as_deref()) {
                Err(e) => message(&e, &self.origin),
                Ok(_) => not_tunable(name),
            });
        };
        let path: Vec<&str> = key.split('.').collect();
        let previous = self.value_of(key)?;
        let mut table = self.table.clone();
        set(&mut table, &path, parsed.clone())?;
        let scenario = parse(&table, &self.origin, self.base.as_deref()).map_err(|e| {
            let m = message(&e, &self.origin);
            // a value of the wrong shape fails in the TOML reader, whose message names a line
            // of the rewritten text: say which key it was
            if m.contains(&format!("`{key}`")) {
                m
            } else {
                format!("key `{key}` = {value}: {m}")
            }
        })?;
        // only the gains may differ
        let mut same = scenario.clone();
        same.kp.clone_from(&self.scenario.kp);
        same.kd.clone_from(&self.scenario.kd);
        same.rejection.clone_from(&self.scenario.rejection);
        same.estimator.clone_from(&self.scenario.estimator);
        let mut gains = self.scenario.rejection.clone();
        if let (Some(a), Some(b)) = (&mut gains.observer, &scenario.rejection.observer) {
            a.gain.clone_from(&b.gain);
        }
        if let (Some(a), Some(b)) = (&mut gains.integral, &scenario.rejection.integral) {
            a.ki.clone_from(&b.ki);
            a.c.clone_from(&b.c);
        }
        if same != self.scenario || gains != scenario.rejection {
            return Err(format!(
                "key `{key}`: this value changes more than a gain, which a running pair cannot take"
            ));
        }
        let value = get(&table, &path)
            .map(|v| v.to_string())
            .unwrap_or_default();
        Ok(Change {
            key,
            value,
            previous,
            scenario,
            parsed,
        })
    }

    /// Puts a checked change in force (for the checks of the next one).
    pub fn commit(&mut self, change: &Change) -> Result<(), String> {
        let path: Vec<&str> = change.key.split('.').collect();
        set(&mut self.table, &path, change.parsed.clone())?;
        self.scenario = change.scenario.clone();
        Ok(())
    }

    /// Checks and commits `name = value` (replay applies a recorded change this way).
    pub fn apply(&mut self, name: &str, value: &str) -> Result<Change, String> {
        let change = self.check(name, value)?;
        self.commit(&change)?;
        Ok(change)
    }
}

fn parse(
    table: &toml::Table,
    origin: &str,
    base: Option<&std::path::Path>,
) -> Result<Scenario, ScenarioError> {
    let text = toml::to_string(table).map_err(|e| ScenarioError::Parse {
        origin: origin.to_owned(),
        message: e.to_string(),
    })?;
    Scenario::from_toml_in(&text, origin, "scenario", base)
}

fn not_tunable(name: &str) -> String {
    format!(
        "key `{name}` cannot change while the pair runs; the keys that can: {}",
        tunable_list()
    )
}

fn absent(key: &str) -> String {
    let parent = key.rsplit_once('.').map_or(key, |(p, _)| p);
    format!(
        "key `{key}`: the run's scenario has no `{parent}`; a running pair can retune a term it started with, not add one"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tuner(name: &str) -> Tuner {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../scenarios/{name}.toml"));
        let text = std::fs::read_to_string(path).unwrap();
        let mut table: toml::Table = toml::from_str(&text).unwrap();
        table.insert("name".into(), toml::Value::String(name.into()));
        Tuner::new(table, "param set", None).unwrap()
    }

    /// The message the scenario file itself gets for `key = value` (after its origin).
    fn file_message(t: &Tuner, edit: impl FnOnce(&mut toml::Table)) -> String {
        let mut table = t.table.clone();
        edit(&mut table);
        let e = Scenario::from_toml(&toml::to_string(&table).unwrap(), "file", "x").unwrap_err();
        message(&e, "file")
    }

    #[test]
    fn a_gain_changes_and_nothing_else() {
        let mut t = tuner("seed");
        let before = t.scenario().clone();
        let c = t.apply("kd", "0.8").unwrap();
        assert_eq!(c.key, "controller.kd");
        assert_eq!((c.previous.as_str(), c.value.as_str()), ("0.5", "0.8"));
        assert_eq!(
            c.scenario.kd,
            vec![0.8, 0.0, 0.0, 0.0, 0.8, 0.0, 0.0, 0.0, 0.8]
        );
        assert_eq!(numbers(&c.scenario, c.key), c.scenario.kd);
        assert_eq!(c.acts(), Acts::Controller);
        let mut same = c.scenario.clone();
        same.kd = before.kd.clone();
        assert_eq!(same, before);
        // the fingerprint covers the gains: a tuned scenario has another one
        assert_ne!(c.scenario.fingerprint(), before.fingerprint());
        assert_eq!(t.get("controller.kd").unwrap().1, "0.8");
        // a value the TOML reader takes as an integer stays one once in force
        let i = t.check("kd", "1_000").unwrap();
        assert_eq!(i.value, "1000");
        t.commit(&i).unwrap();
        assert_eq!(t.get("kd").unwrap().1, "1000");
        // a matrix
        let m = t
            .check("kp", "[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]")
            .unwrap();
        assert_eq!(m.scenario.kp[4], 2.0);
    }

    #[test]
    fn bad_values_get_the_scenarios_own_messages() {
        let t = tuner("seed");
        for (value, toml_value) in [
            ("-1", toml::Value::Float(-1.0)),
            ("NaN", toml::Value::Float(f64::NAN)),
            ("0", toml::Value::Float(0.0)),
            (
                "[1.0, 2.0]",
                toml::Value::Array(vec![1.0.into(), 2.0.into()]),
            ),
        ] {
            let got = t.check("kp", value).unwrap_err();
            let want = file_message(&t, |table| {
                table["controller"]
                    .as_table_mut()
                    .unwrap()
                    .insert("kp".into(), toml_value.clone());
            });
            assert!(got.ends_with(&want), "kp = {value}: {got} / {want}");
            assert!(got.contains("controller.kp"), "{got}");
        }
        let got = t.check("nosuchkey", "1").unwrap_err();
        let want = file_message(&t, |table| {
            table.insert("nosuchkey".into(), toml::Value::Float(1.0));
        });
        assert_eq!(got, want);
        assert!(got.contains("nosuchkey"), "{got}");
        // a key the scenario knows but a running pair cannot change
        let e = t.check("duration", "3.0").unwrap_err();
        assert!(e.contains("cannot change while the pair runs"), "{e}");
        // a term the run did not start with
        let e = t.check("controller.integral.ki", "1.0").unwrap_err();
        assert!(e.contains("has no `controller.integral`"), "{e}");
        // not a value at all
        let e = t.check("kd", "0.8 0.9").unwrap_err();
        assert!(e.contains("neither a number"), "{e}");
    }

    #[test]
    fn rejection_and_estimator_gains_are_tunable_where_the_run_has_them() {
        let mut t = tuner("reject_so3");
        let keys: Vec<_> = TUNABLE.iter().map(|(k, _)| *k).collect();
        let mut tuned = 0;
        for key in keys.iter().filter(|k| k.starts_with("controller.")) {
            if t.get(key).is_err() {
                continue;
            }
            let c = t.apply(key, "2.5").unwrap();
            // a number: every axis (a matrix: 2.5 I)
            let xs = numbers(&c.scenario, key);
            assert!(xs.contains(&2.5), "{key}: {xs:?}");
            assert!(xs.iter().all(|x| *x == 2.5 || *x == 0.0), "{key}: {xs:?}");
            tuned += 1;
        }
        // kp, kd and the observer's gain (the scenario's integral is checked too, if any)
        assert!(tuned >= 3, "{tuned}");
        // a gain the file leaves to its default is tunable too, from the default
        let mut table = tuner("sensors_so3").table.clone();
        table["estimator"].as_table_mut().unwrap().remove("ki");
        let d = Tuner::new(table, "param set", None).unwrap();
        assert_eq!(d.get("estimator.ki").unwrap().1, "0.3");
        assert_eq!(d.check("estimator.ki", "0.5").unwrap().previous, "0.3");
        assert!(parse_value("0.8\n[x]").is_err());
        assert!(parse_value("[1.0, 2.0] # fine").is_ok());
        let mut e = tuner("sensors_so3");
        let c = e.apply("estimator.kp", "3.0").unwrap();
        assert_eq!(c.acts(), Acts::Estimator);
        assert_eq!(c.scenario.estimator.kp, 3.0);
        assert!(
            e.check("estimator.ki", "-1")
                .unwrap_err()
                .contains("estimator.ki")
        );
    }
}
