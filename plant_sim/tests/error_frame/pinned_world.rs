//! The papers' law stays byte for byte: every scenario in `scenarios/`, flown with
//! `[controller] error_frame = "world"`, and the extended paper's Monte Carlo write exactly the
//! `trajectory.csv` and `summary.json` (and the study's CSVs and summary) they wrote before the
//! key existed.
//!
//! `plant_sim/tests/data/world_outputs.txt` holds the FNV-1a digests of what commit a8344c4 (the last
//! before `error_frame`) wrote for them. It was written by this test itself, run against that
//! commit's build with the scenarios as they were then (no `error_frame` line):
//!
//! ```text
//! PINNED_WORLD_BASE=/path/to/a8344c4/plant_sim cargo test -p plant_sim --test error_frame pinned_world
//! ```
//!
//! (`scripts/compare-outputs.sh --world BASE NEW` compares every file, figures included, when
//! both builds are at hand.)
//!
//! Eight lines were pinned again when the allocation's active set was rewritten (issue
//! "Bounded time on the microcontroller"): `trajectory.csv` and `summary.json` of the four
//! vehicle scenarios whose allocation leaves the closed form (`hexarotor_eqf`, `pil_hexarotor`,
//! `rov_failure`, `spacecraft`). The same optima, reached by other arithmetic: against the
//! build before the rewrite their columns differ by at most 9e-12 relative, and DAQP agrees
//! with every row (scripts/daqp.sh). `hexarotor_eight`, whose allocation never leaves the
//! closed form, kept its bytes.
//!
//! Four were pinned again when the hexarotor's force stage became the dual method (the same
//! issue; docs/maths.md, "Control allocation"): `trajectory.csv` and `summary.json` of
//! `hexarotor_eqf` and `pil_hexarotor`. Against the build before, their columns differ by at
//! most 3e-13 relative (the NEES; the wrench's columns 2e-14), `alloc_status` not at all.
//!
//! The same four again when the hexarotor's torque stage became the dual method too. Against
//! the build before the force stage's change (7d1eec5), their columns differ by at most 2.7e-13
//! relative (the NEES), the positions 5e-15, `alloc_status` not at all (`pil_hexarotor_saturated`
//! the same, on its 907 rows off the closed form).
//!
//! Four again when geometries in blocks came to be allocated block by block (the same issue;
//! docs/maths.md, "Control allocation": geometries in blocks): `trajectory.csv` and
//! `summary.json` of `rov_failure` and `spacecraft`. Against the build before (438e2e9), each
//! column differs by at most 8.8e-12 of its largest value (`rov_failure`'s commands; the
//! spacecraft's 3.8e-15), `alloc_status` in no row.
//!
//! Two again when the ROV's blocks came to be solved by their reach (the same issue;
//! docs/maths.md, "Control allocation": a block of three rows by its reach): `trajectory.csv`
//! and `summary.json` of `rov_failure`. Against the build before (3b6d133), each column
//! differs by at most 4.4e-14 of its largest value (the wrench achieved), `alloc_status` in no
//! row.

use crate::common::ok;
use pair_tests::repo;
use std::path::{Path, PathBuf};
use std::process::Command;

const DIGESTS: &str = "tests/data/world_outputs.txt";

/// FNV-1a, 64 bits.
fn digest(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A copy of `scenarios/` in `dir`: every `[controller]` with `error_frame = "world"`, or
/// (for the base, which does not know the key) with no `error_frame` line at all.
fn scenarios(dir: &Path, world: bool) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    let mut files = Vec::new();
    for entry in std::fs::read_dir(repo("scenarios")).unwrap() {
        let path = entry.unwrap().path();
        let to = dir.join(path.file_name().unwrap());
        if path.extension().is_some_and(|e| e == "toml") {
            let text = std::fs::read_to_string(&path).unwrap();
            let kept: Vec<&str> = text
                .lines()
                .filter(|l| !l.starts_with("error_frame"))
                .collect();
            let mut text = kept.join("\n") + "\n";
            if world {
                text = text.replacen(
                    "[controller]\n",
                    "[controller]\nerror_frame = \"world\"\n",
                    1,
                );
                assert!(
                    text.contains("error_frame = \"world\""),
                    "{}",
                    path.display()
                );
            }
            std::fs::write(&to, text).unwrap();
            files.push(to);
        } else {
            std::fs::copy(&path, &to).unwrap();
        }
    }
    files.sort();
    files
}

/// What `plant_sim` (at `bin`) writes for each pinned run: `(name, digest)` lines.
fn outputs(bin: &Path, dir: &Path, world: bool) -> Vec<String> {
    let files = scenarios(&dir.join("scenarios"), world);
    let mut lines = Vec::new();
    let mut fly = |tag: String, args: Vec<String>, written: &[&str]| {
        let out = dir.join(&tag);
        let result = Command::new(bin)
            .args(&args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        ok(&result);
        for f in written {
            let bytes = std::fs::read(out.join(f)).unwrap();
            lines.push(format!("{tag}/{f} {:016x}", digest(&bytes)));
        }
    };
    for f in &files {
        let name = f.file_stem().unwrap().to_string_lossy().into_owned();
        fly(
            format!("sim-{name}"),
            vec!["sim".into(), "--scenario".into(), f.display().to_string()],
            &["trajectory.csv", "summary.json"],
        );
    }
    fly(
        "montecarlo".into(),
        ["montecarlo", "--runs", "6", "--threads", "2", "--scenario"]
            .iter()
            .map(|s| s.to_string())
            .chain([dir.join("scenarios/montecarlo.toml").display().to_string()])
            .collect(),
        &["runs.csv", "mean.csv", "summary.json"],
    );
    lines
}

#[test]
fn every_scenario_flown_with_error_frame_world_writes_what_it_wrote_before_the_key() {
    let dir = tempfile::tempdir().unwrap();
    if let Ok(base) = std::env::var("PINNED_WORLD_BASE") {
        let lines = outputs(Path::new(&base), dir.path(), false);
        std::fs::write(
            repo(&format!("plant_sim/{DIGESTS}")),
            lines.join("\n") + "\n",
        )
        .unwrap();
        return;
    }
    let expected = std::fs::read_to_string(repo(&format!("plant_sim/{DIGESTS}"))).unwrap();
    let expected: Vec<&str> = expected.lines().collect();
    let got = outputs(Path::new(env!("CARGO_BIN_EXE_plant_sim")), dir.path(), true);
    // every output pinned then is written the same now (scenarios added since are new, not
    // pinned)
    assert!(
        expected.len() >= 35,
        "{DIGESTS} has {} lines",
        expected.len()
    );
    let mut changed = Vec::new();
    for e in &expected {
        let name = e.split(' ').next().unwrap();
        let g = got
            .iter()
            .find(|g| g.split(' ').next() == Some(name))
            .unwrap_or_else(|| panic!("{name}: pinned, and no longer written"));
        if g != e {
            changed.push(format!("{e} is now {g}"));
        }
    }
    assert!(
        changed.is_empty(),
        "flown with error_frame = \"world\", these outputs changed:\n{}",
        changed.join("\n")
    );
}
