//! `params.log`: the run-time parameter changes of a run started with `plant_sim run
//! --tunable` (docs/live.md, "Tuning a running pair"), one JSON object per line after a
//! header line, appended and synced by the plant's parameter thread as each change takes
//! effect. Replay applies each change at its cycle; the MCAP export makes a channel of them.

use crate::RecorderError;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The file's name in a run's output directory.
pub const PARAMS_FILE: &str = "params.log";
/// Its format version (the header line's `version`).
pub const PARAMS_VERSION: u32 = 1;
/// The header line's `format`.
const PARAMS_FORMAT: &str = "eqtrack-params";

/// One change, as it took effect.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamChange {
    /// The first cycle it answered: the state of this cycle was the first published with it.
    pub cycle: u64,
    /// That cycle's time `t_k` (s).
    pub t: f64,
    /// The scenario key (`controller.kd`).
    pub key: String,
    /// The new value, as TOML text (what replay applies).
    pub value: String,
    /// The value before, as TOML text.
    pub previous: String,
    /// The numbers the new value resolves to (a matrix row-major, a number per axis).
    pub numbers: Vec<f64>,
    /// The numbers before.
    pub previous_numbers: Vec<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct HeaderLine {
    format: String,
    version: u32,
}

/// Starts `dir/params.log` with its header line (an existing file is replaced).
pub fn create_params(dir: &Path) -> Result<(), RecorderError> {
    let path = dir.join(PARAMS_FILE);
    let header = serde_json::to_string(&HeaderLine {
        format: PARAMS_FORMAT.to_owned(),
        version: PARAMS_VERSION,
    })
    .map_err(|e| RecorderError::Io(e.to_string()))?;
    std::fs::write(&path, format!("{header}\n"))
        .map_err(|e| RecorderError::Io(format!("{}: {e}", path.display())))
}

/// Appends `change` to `dir/params.log` and syncs it.
pub fn append_param(dir: &Path, change: &ParamChange) -> Result<(), RecorderError> {
    let path = dir.join(PARAMS_FILE);
    let io = |e: std::io::Error| RecorderError::Io(format!("{}: {e}", path.display()));
    let line = serde_json::to_string(change).map_err(|e| RecorderError::Io(e.to_string()))?;
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .map_err(io)?;
    f.write_all(format!("{line}\n").as_bytes()).map_err(io)?;
    f.sync_data().map_err(io)
}

/// Reads `text`, a `params.log`: the changes in order. Refused (naming the line): another
/// format or version, a line that is not a change, cycles that do not increase.
pub fn parse_params(text: &str) -> Result<Vec<ParamChange>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, first)) = lines.next() else {
        return Ok(Vec::new());
    };
    let header: HeaderLine =
        serde_json::from_str(first).map_err(|e| format!("line 1: not a params.log header: {e}"))?;
    if header.format != PARAMS_FORMAT || header.version != PARAMS_VERSION {
        return Err(format!(
            "line 1: format `{}` version {}, this build reads `{PARAMS_FORMAT}` version {PARAMS_VERSION}",
            header.format, header.version
        ));
    }
    let mut out: Vec<ParamChange> = Vec::new();
    for (i, line) in lines {
        let c: ParamChange =
            serde_json::from_str(line).map_err(|e| format!("line {}: {e}", i + 1))?;
        if let Some(last) = out.last()
            && c.cycle <= last.cycle
        {
            return Err(format!(
                "line {}: cycle {} after cycle {}: changes take effect at increasing cycles",
                i + 1,
                c.cycle,
                last.cycle
            ));
        }
        out.push(c);
    }
    Ok(out)
}

/// A run's changes (`dir/params.log`); empty when the file does not exist.
pub fn read_params(dir: &Path) -> Result<Vec<ParamChange>, RecorderError> {
    let path = dir.join(PARAMS_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) => parse_params(&text)
            .map_err(|e| RecorderError::Input(format!("{}: {e}", path.display()))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(e) => Err(RecorderError::Input(format!(
            "{}: cannot read: {e}",
            path.display()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn change(cycle: u64, value: &str) -> ParamChange {
        ParamChange {
            cycle,
            t: cycle as f64 * 0.01,
            key: "controller.kd".into(),
            value: value.into(),
            previous: "0.5".into(),
            numbers: vec![0.8, 0.0, 0.1 + 0.2],
            previous_numbers: vec![0.5],
        }
    }

    #[test]
    fn changes_round_trip_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        create_params(dir.path()).unwrap();
        let a = change(3, "0.8");
        let b = change(9, "[[1.0, 0.0], [0.0, 2.0]]");
        append_param(dir.path(), &a).unwrap();
        append_param(dir.path(), &b).unwrap();
        let back = read_params(dir.path()).unwrap();
        assert_eq!(back, vec![a, b]);
        assert_eq!(back[0].numbers[2].to_bits(), (0.1f64 + 0.2).to_bits());
        let none = tempfile::tempdir().unwrap();
        assert_eq!(read_params(none.path()).unwrap(), vec![]);
    }

    #[test]
    fn bad_files_are_refused_naming_the_line() {
        let header = "{\"format\":\"eqtrack-params\",\"version\":1}\n";
        let line = |c: &ParamChange| serde_json::to_string(c).unwrap();
        assert!(parse_params("garbage\n").unwrap_err().starts_with("line 1"));
        assert!(
            parse_params("{\"format\":\"eqtrack-params\",\"version\":2}\n")
                .unwrap_err()
                .contains("version 2")
        );
        let back = format!(
            "{header}{}\n{}\n",
            line(&change(5, "1.0")),
            line(&change(5, "2.0"))
        );
        assert!(
            parse_params(&back)
                .unwrap_err()
                .contains("line 3: cycle 5 after cycle 5")
        );
        let extra = format!("{header}{{\"cycle\":1}}\n");
        assert!(parse_params(&extra).unwrap_err().starts_with("line 2"));
        assert_eq!(parse_params("").unwrap(), vec![]);
    }
}
