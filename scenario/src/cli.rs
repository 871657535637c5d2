//! The command-line pieces both binaries share: where the scenario comes from, the law and
//! group values, and the one positive-duration parser.

use crate::{Scenario, ScenarioError};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use eqtrack_controller::{GroupKind, Law};
use std::path::PathBuf;
use std::time::Duration;

/// `--scenario FILE | --builtin NAME`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ScenarioSource {
    /// Scenario file (TOML).
    #[arg(long, value_name = "FILE", conflicts_with = "builtin")]
    pub scenario: Option<PathBuf>,
    /// Built-in scenario: seed, montecarlo, se3_circle, se2_circle.
    #[arg(long, value_name = "NAME")]
    pub builtin: Option<String>,
}

impl ScenarioSource {
    /// Loads the scenario (the built-in `default` when neither flag is given).
    pub fn load(&self, default: &str) -> Result<Scenario, ScenarioError> {
        match (&self.scenario, &self.builtin) {
            (Some(p), _) => Scenario::from_file(p),
            (None, Some(n)) => Scenario::builtin(n),
            (None, None) => Scenario::builtin(default),
        }
    }

    /// The arguments that make another process load the same scenario (a file path made
    /// absolute).
    pub fn args(&self, default: &str) -> Vec<String> {
        match (&self.scenario, &self.builtin) {
            (Some(p), _) => {
                let abs = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
                vec!["--scenario".to_owned(), abs.display().to_string()]
            }
            (None, Some(n)) => vec!["--builtin".to_owned(), n.clone()],
            (None, None) => vec!["--builtin".to_owned(), default.to_owned()],
        }
    }
}

impl ScenarioSource {
    /// The scenario this source loads as a TOML table, with the `name` it was loaded under,
    /// the origin errors name, and the directory its waypoint files are relative to (what
    /// [`ScenarioSource::save`] writes, and what run-time parameters are checked against).
    pub fn table(
        &self,
        default: &str,
    ) -> Result<(toml::Table, String, Option<PathBuf>), ScenarioError> {
        let io = |path: &std::path::Path| {
            let path = path.display().to_string();
            move |source| ScenarioError::Io { path, source }
        };
        let (text, origin, name, base) = match (&self.scenario, &self.builtin) {
            (Some(p), _) => {
                let text = std::fs::read_to_string(p).map_err(io(p))?;
                let stem = p
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "scenario".to_owned());
                (
                    text,
                    p.display().to_string(),
                    stem,
                    p.parent().map(std::path::Path::to_path_buf),
                )
            }
            (None, b) => {
                let name = b.as_deref().unwrap_or(default);
                let text = crate::BUILTINS
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map(|(_, t)| (*t).to_owned())
                    .ok_or_else(|| ScenarioError::UnknownBuiltin(name.to_owned()))?;
                (
                    text,
                    format!("built-in scenario `{name}`"),
                    name.to_owned(),
                    None,
                )
            }
        };
        let mut table: toml::Table = toml::from_str(&text).map_err(|e| ScenarioError::Parse {
            origin: origin.clone(),
            message: e.to_string().trim_end().to_owned(),
        })?;
        table
            .entry("name")
            .or_insert_with(|| toml::Value::String(name));
        Ok((table, origin, base))
    }

    /// Writes the scenario this source loads, as text, to `dir/scenario.toml`, so that the
    /// directory alone reproduces the controller's configuration (a run's flight recording
    /// is replayed with it). A waypoint file is copied beside it and the copy's reference
    /// points at it; a scenario without a `name` gets the one it was loaded under. Returns
    /// the path written.
    pub fn save(&self, default: &str, dir: &std::path::Path) -> Result<PathBuf, ScenarioError> {
        let io = |path: &std::path::Path| {
            let path = path.display().to_string();
            move |source| ScenarioError::Io { path, source }
        };
        let (mut table, origin, base) = self.table(default)?;
        if let Some(toml::Value::Table(reference)) = table.get_mut("reference")
            && let Some(toml::Value::String(file)) = reference.get_mut("waypoints")
        {
            let from = base
                .as_deref()
                .unwrap_or(std::path::Path::new("."))
                .join(&*file);
            let copy = "waypoints.csv";
            std::fs::copy(&from, dir.join(copy)).map_err(io(&from))?;
            *file = copy.to_owned();
        }
        let out = dir.join("scenario.toml");
        let text = toml::to_string(&table).map_err(|e| ScenarioError::Parse {
            origin,
            message: e.to_string(),
        })?;
        std::fs::write(&out, text).map_err(io(&out))?;
        Ok(out)
    }
}

/// clap's parser for a [`Law`] (`eqt`, `gt`, `nog`, `asym`; listed in `--help`). The law
/// enum lives in the `no_std` controller crate, which stays free of clap, so this maps
/// clap's possible values onto it instead of deriving `ValueEnum` there.
pub fn law_parser() -> impl TypedValueParser<Value = Law> {
    PossibleValuesParser::new(Law::ALL.map(Law::name))
        .map(|name| Law::from_name(&name).unwrap_or(Law::Eqt))
}

/// clap's parser for a [`GroupKind`] (`so3`, `se3`), as [`law_parser`].
pub fn group_parser() -> impl TypedValueParser<Value = GroupKind> {
    PossibleValuesParser::new(GroupKind::ALL.map(GroupKind::name))
        .map(|name| GroupKind::from_name(&name).unwrap_or(GroupKind::So3))
}

/// A positive, finite number of seconds (the one duration parser of both binaries).
pub fn positive_seconds(text: &str) -> Result<Duration, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if v.is_finite() && v > 0.0 && v < 1e9 {
        Ok(Duration::from_secs_f64(v))
    } else {
        Err(format!("must be a positive number of seconds, got {text}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[arg(long, value_parser = law_parser())]
        law: Option<Law>,
        #[arg(long, value_parser = law_parser(), value_delimiter = ',')]
        laws: Vec<Law>,
        #[arg(long, value_parser = group_parser())]
        group: Option<GroupKind>,
        #[arg(long, value_parser = positive_seconds)]
        wait: Option<Duration>,
    }

    #[test]
    fn typed_values_parse_and_bad_ones_are_named() {
        let c = Cli::try_parse_from(["x", "--law", "gt", "--laws", "eqt,asym", "--group", "se3"])
            .unwrap();
        assert_eq!(c.law, Some(Law::Gt));
        assert_eq!(c.laws, vec![Law::Eqt, Law::Asym]);
        assert_eq!(c.group, Some(GroupKind::Se3));
        let e = Cli::try_parse_from(["x", "--law", "pid"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("pid") && e.contains("eqt"), "{e}");
        let e = Cli::try_parse_from(["x", "--laws", "eqt,nope"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("nope"), "{e}");
    }

    #[test]
    fn a_saved_scenario_loads_back_to_the_same_one() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let slew = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/slew_so3.toml");
        let sources = [
            ScenarioSource {
                scenario: None,
                builtin: Some("se3_circle".to_owned()),
            },
            ScenarioSource {
                scenario: Some(PathBuf::from(slew)),
                builtin: None,
            },
        ];
        for src in sources {
            let original = src.load("seed").unwrap();
            let saved = src.save("seed", &dir).unwrap();
            let mut back = Scenario::from_file(&saved).unwrap();
            // only where the waypoints were read from differs
            if let (Some(b), Some(o)) = (&mut back.path, &original.path) {
                assert!(b.file.ends_with("waypoints.csv"), "{}", b.file);
                b.file.clone_from(&o.file);
            }
            assert_eq!(back, original, "{src:?}");
            assert_eq!(back.fingerprint(), original.fingerprint());
        }
        assert!(dir.join("waypoints.csv").exists());
        let missing = ScenarioSource {
            scenario: None,
            builtin: Some("nope".to_owned()),
        };
        assert!(missing.save("seed", &dir).is_err());
    }

    #[test]
    fn durations_must_be_positive_and_finite() {
        assert_eq!(positive_seconds("1.5"), Ok(Duration::from_millis(1500)));
        for bad in ["0", "-1", "nan", "inf", "x", ""] {
            assert!(positive_seconds(bad).is_err(), "{bad}");
        }
        let e = Cli::try_parse_from(["x", "--wait=-2"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("--wait") && e.contains("positive"), "{e}");
    }
}
