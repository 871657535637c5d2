//! `plant_sim` driven as a user drives it: through the binary.

mod common;

use common::{ok, run};
use pair_tests::{column, read_csv, repo};
use std::path::Path;
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_plant_sim"))
}

#[test]
fn sim_builtin_seed_matches_the_independent_reference() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&[
        "sim",
        "--builtin",
        "seed",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    ok(&out);
    let (h, rows) = read_csv(&dir.path().join("trajectory.csv"));
    assert_eq!(rows.len(), 2001);
    let (rh, rrows) = read_csv(&repo("controller/tests/data/seed_eqt.csv"));
    let mut compared = 0;
    for name in &rh {
        let ours = column(&h, &rows, name);
        let theirs = column(&rh, &rrows, name);
        for (j, b) in theirs.iter().enumerate() {
            let a = ours[j * 10];
            assert!(
                (a - b).abs() <= 1e-8 * (1.0 + b.abs()),
                "{name} at row {j}: {a} vs {b}"
            );
            compared += 1;
        }
    }
    assert_eq!(compared, rh.len() * 201);
    // the other outputs exist and say the same thing
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    let l_end = column(&h, &rows, "lyapunov")[2000];
    assert_eq!(summary["final"]["lyapunov"].as_f64().unwrap(), l_end);
    let effort: f64 = column(&h, &rows, "torque_norm")[..2000]
        .iter()
        .map(|x| x * 0.01)
        .sum();
    assert!((summary["effort"].as_f64().unwrap() - effort).abs() < 1e-9);
    for f in ["figure.png", "figure.svg"] {
        assert!(
            std::fs::metadata(dir.path().join(f)).unwrap().len() > 10_000,
            "{f}"
        );
    }
}

#[test]
fn no_arguments_runs_the_seed_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let out = bin().current_dir(dir.path()).output().unwrap();
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("scenario seed"));
    assert!(dir.path().join("out/seed/trajectory.csv").exists());
}

/// The montecarlo base scenario's text with a replacement applied.
fn base_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(repo("scenarios/montecarlo.toml")).unwrap();
    assert!(text.contains(from), "base scenario has no `{from}`");
    text.replacen(from, to, 1)
}

fn se3_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(repo("scenarios/se3_circle.toml")).unwrap();
    assert!(text.contains(from), "se3 scenario has no `{from}`");
    text.replacen(from, to, 1)
}

#[test]
fn every_validation_error_names_the_key_and_exits_2() {
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "unknown top-level key",
            base_with("name = ", "colour = \"red\"\nname = "),
            &["unknown field `colour`"],
        ),
        (
            "unknown nested key",
            base_with("kd = 0.5", "kd = 0.5\nki = 0.1"),
            &["unknown field `ki`"],
        ),
        (
            "wrong shape",
            base_with(
                "inertia = [[0.824, 0.0, 0.12], [0.0, 1.135, 0.0], [0.12, 0.0, 1.759]]",
                "inertia = [[1.0, 0.0], [0.0, 1.0]]",
            ),
            &["plant.inertia", "3×3"],
        ),
        (
            "non-SPD gain",
            base_with(
                "kp = 1.0",
                "kp = [[1.0, 0.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, 1.0]]",
            ),
            &["controller.kp", "not positive definite"],
        ),
        (
            "non-symmetric inertia",
            base_with("[0.12, 0.0, 1.759]]", "[0.5, 0.0, 1.759]]"),
            &["plant.inertia", "not symmetric"],
        ),
        (
            "non-finite number",
            base_with("velocity = [4.0, -3.0, 2.0]", "velocity = [4.0, nan, 2.0]"),
            &["initial.velocity", "not a finite number"],
        ),
        (
            "non-positive period",
            base_with("control_period = 0.01", "control_period = 0.0"),
            &["control_period", "must be positive"],
        ),
        (
            "negative duration",
            base_with("duration = 20.0", "duration = -1.0"),
            &["duration", "must be positive"],
        ),
        (
            "law not defined for the group",
            se3_with("law = \"eqt\"", "law = \"gt\""),
            &["law", "not defined for group se3"],
        ),
        (
            "unknown error frame",
            se3_with("kd = 1.5", "kd = 1.5\nerror_frame = \"up\""),
            &[
                "controller.error_frame",
                "unknown error frame `up`",
                "reference, world, recentred",
            ],
        ),
        (
            "empty error frame",
            se3_with("kd = 1.5", "kd = 1.5\nerror_frame = \"\""),
            &["controller.error_frame", "unknown error frame ``"],
        ),
        (
            "an error frame that is a number",
            se3_with("kd = 1.5", "kd = 1.5\nerror_frame = 3"),
            &[
                "controller.error_frame",
                "must be a string, one of reference, world, recentred",
                "integer",
            ],
        ),
        (
            "an error frame in capitals",
            base_with("error_frame = \"world\"", "error_frame = \"World\""),
            &["controller.error_frame", "unknown error frame `World`"],
        ),
        (
            "unknown law",
            base_with("law = \"eqt\"", "law = \"pid\""),
            &["law", "unknown law `pid`"],
        ),
        (
            "unknown group",
            base_with("group = \"so3\"", "group = \"se4\""),
            &["group", "unknown group `se4`"],
        ),
        (
            "position on so3",
            base_with(
                "velocity = [4.0, -3.0, 2.0]",
                "velocity = [4.0, -3.0, 2.0]\nposition = [1.0, 0.0, 0.0]",
            ),
            &["initial.position", "only se3"],
        ),
        (
            "feedforward axes",
            base_with("torque = [", "torque = [ { offset = 1.0 },"),
            &["reference.torque", "expected 3 axes"],
        ),
        (
            "zero substeps",
            base_with("plant_substeps = 10", "plant_substeps = 0"),
            &["plant_substeps", "from 1 to"],
        ),
        (
            "wrong type",
            base_with("duration = 20.0", "duration = \"long\""),
            &["duration"],
        ),
        (
            "fractional steps",
            base_with("duration = 20.0", "duration = 20.005"),
            &["duration", "whole number of control periods"],
        ),
        (
            "torque limit",
            base_with("[plant]", "[plant]\ntorque_limit = -1.0"),
            &["plant.torque_limit", "must be positive"],
        ),
        (
            "se3 velocity shape",
            se3_with(
                "velocity = [1.0, -0.5, 0.3, 0.0, 0.5, -1.0]",
                "velocity = [1.0, -0.5, 0.3]",
            ),
            &["initial.velocity", "expected 6"],
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (what, text, needles) in cases {
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, &text).unwrap();
        let out = run(&[
            "sim",
            "--scenario",
            path.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{what}: exit code, stderr: {err}"
        );
        assert!(!err.contains("panicked"), "{what}: {err}");
        assert!(err.starts_with("error: "), "{what}: {err}");
        for n in needles {
            assert!(err.contains(n), "{what}: message lacks `{n}`: {err}");
        }
    }
    // command-line mistakes
    for (args, needle) in [
        (
            vec!["sim", "--builtin", "nope"],
            "unknown built-in scenario `nope`",
        ),
        (
            vec!["sim", "--law", "pid"],
            "invalid value 'pid' for '--law",
        ),
        (
            vec!["sim", "--builtin", "se3_circle", "--law", "asym"],
            "not defined for group se3",
        ),
        (
            vec!["sim", "--scenario", "/nonexistent/x.toml"],
            "cannot read scenario file",
        ),
        (
            vec!["montecarlo", "--laws", "eqt,pid"],
            "invalid value 'pid' for '--laws",
        ),
        (vec!["sim", "--frobnicate"], "unexpected argument"),
    ] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

fn montecarlo(dir: &Path, extra: &[&str]) -> Output {
    let scen = dir.join("short.toml");
    std::fs::write(&scen, base_with("duration = 20.0", "duration = 3.0")).unwrap();
    let mut args = vec![
        "montecarlo",
        "--scenario",
        scen.to_str().unwrap(),
        "--laws",
        "eqt,gt,asym",
    ];
    args.extend_from_slice(extra);
    run(&args)
}

#[test]
fn montecarlo_is_the_same_for_any_thread_count_and_round_trips_samples() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one");
    let many = dir.path().join("many");
    ok(&montecarlo(
        dir.path(),
        &[
            "--runs",
            "6",
            "--seed",
            "7",
            "--threads",
            "1",
            "--out",
            one.to_str().unwrap(),
        ],
    ));
    let out = montecarlo(
        dir.path(),
        &[
            "--runs",
            "6",
            "--seed",
            "7",
            "--threads",
            "3",
            "--out",
            many.to_str().unwrap(),
        ],
    );
    ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("effort 0-5"));
    for f in ["runs.csv", "mean.csv", "summary.json"] {
        let a = std::fs::read(one.join(f)).unwrap();
        let b = std::fs::read(many.join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 3 threads");
    }
    let (h, rows) = read_csv(&one.join("runs.csv"));
    assert_eq!(rows.len(), 18);
    assert_eq!(&h[..8], ["run", "law", "rx", "ry", "rz", "wx", "wy", "wz"]);
    let (mh, mrows) = read_csv(&one.join("mean.csv"));
    assert_eq!(mh.len(), 1 + 3 * 4);
    assert_eq!(mrows.len(), 301);
    // a different seed draws different samples
    let other = dir.path().join("other");
    ok(&montecarlo(
        dir.path(),
        &[
            "--runs",
            "6",
            "--seed",
            "8",
            "--out",
            other.to_str().unwrap(),
        ],
    ));
    assert!(
        std::fs::read(other.join("runs.csv")).unwrap()
            != std::fs::read(one.join("runs.csv")).unwrap()
    );

    // --samples round trip: the samples of runs.csv fed back give the same runs.csv
    let mut samples = String::from("rx,ry,rz,wx,wy,wz\n");
    for r in rows.iter().filter(|r| r[1] == "eqt") {
        samples += &r[2..8].join(",");
        samples.push('\n');
    }
    let sfile = dir.path().join("samples.csv");
    std::fs::write(&sfile, samples).unwrap();
    let back = dir.path().join("back");
    ok(&montecarlo(
        dir.path(),
        &[
            "--samples",
            sfile.to_str().unwrap(),
            "--out",
            back.to_str().unwrap(),
        ],
    ));
    assert!(
        std::fs::read(back.join("runs.csv")).unwrap()
            == std::fs::read(one.join("runs.csv")).unwrap()
    );
}

#[test]
fn a_montecarlo_run_equals_a_single_sim_of_that_case() {
    let dir = tempfile::tempdir().unwrap();
    let sfile = dir.path().join("samples.csv");
    std::fs::write(&sfile, "rx,ry,rz,wx,wy,wz\n0.3,-2.1,1.4,0.5,-1.25,0.75\n").unwrap();
    let mc = dir.path().join("mc");
    ok(&montecarlo(
        dir.path(),
        &[
            "--samples",
            sfile.to_str().unwrap(),
            "--out",
            mc.to_str().unwrap(),
        ],
    ));
    let (h, rows) = read_csv(&mc.join("runs.csv"));
    // the same case as a scenario: R_d(0) = I and ω_d(0) = 0 in the base, so R(0) = exp(r), ω(0) = w
    let text = base_with("duration = 20.0", "duration = 3.0")
        .replacen(
            "rotation = [2.4332741228718345, 1.8249555921538759, 0.0]",
            "rotation = [0.3, -2.1, 1.4]",
            1,
        )
        .replacen(
            "velocity = [4.0, -3.0, 2.0]",
            "velocity = [0.5, -1.25, 0.75]",
            1,
        );
    let scen = dir.path().join("case.toml");
    for law in ["eqt", "gt", "asym"] {
        std::fs::write(&scen, &text).unwrap();
        let out_dir = dir.path().join(law);
        ok(&run(&[
            "sim",
            "--scenario",
            scen.to_str().unwrap(),
            "--law",
            law,
            "--out",
            out_dir.to_str().unwrap(),
        ]));
        let (th, trows) = read_csv(&out_dir.join("trajectory.csv"));
        let att = column(&th, &trows, "attitude_error");
        let tn = column(&th, &trows, "torque_norm");
        let row = rows.iter().find(|r| r[1] == law).unwrap();
        let get = |name: &str| -> f64 {
            row[h.iter().position(|x| x == name).unwrap()]
                .parse()
                .unwrap()
        };
        assert_eq!(get("final_attitude_error"), *att.last().unwrap(), "{law}");
        let effort5: f64 = tn[..300].iter().map(|x| x * 0.01).sum();
        assert_eq!(
            get("effort_0_5"),
            effort5,
            "{law}: the horizon is cut at T = 3 s"
        );
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap())
                .unwrap();
        let settle = row[h.iter().position(|x| x == "settling_time").unwrap()].clone();
        match summary["settling_time"].as_f64() {
            Some(t) => assert_eq!(settle.parse::<f64>().unwrap(), t),
            None => assert_eq!(settle, ""),
        }
    }
}

#[test]
fn se3_scenario_converges_and_its_lyapunov_function_never_rises() {
    let dir = tempfile::tempdir().unwrap();
    ok(&run(&[
        "sim",
        "--builtin",
        "se3_circle",
        "--out",
        dir.path().to_str().unwrap(),
    ]));
    let (h, rows) = read_csv(&dir.path().join("trajectory.csv"));
    assert_eq!(h.len(), 7 + 6 + 16 + 6);
    let cfg = column(&h, &rows, "config_error");
    assert!(
        *cfg.last().unwrap() < 1e-3,
        "config error at the end {}",
        cfg.last().unwrap()
    );
    // RKMK4 with 1 ms substeps integrates to ~1e-12 of L; zero-order hold at 10 ms makes L
    // deviate from the continuous-time decrease by O(h) relative to the dissipation, which
    // only shows as a rise where the dissipation vanishes. 1e-9·L(0) bounds both with margin.
    let l = column(&h, &rows, "lyapunov");
    let rise = l
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(rise <= 1e-9 * l[0], "L rose by {rise}");
    assert!(l.last().unwrap() < &(1e-6 * l[0]));
}

#[test]
fn torque_limit_disturbance_and_model_mismatch_reach_the_loop() {
    let dir = tempfile::tempdir().unwrap();
    let nominal = dir.path().join("nominal");
    let scen = dir.path().join("nominal.toml");
    std::fs::write(&scen, base_with("duration = 20.0", "duration = 5.0")).unwrap();
    ok(&run(&[
        "sim",
        "--scenario",
        scen.to_str().unwrap(),
        "--out",
        nominal.to_str().unwrap(),
    ]));
    let (h, rows) = read_csv(&nominal.join("trajectory.csv"));
    let peak = (0..3)
        .flat_map(|i| column(&h, &rows, &format!("tau_{i}")))
        .fold(0.0f64, |a, x| a.max(x.abs()));
    assert!(
        peak > 1.0,
        "the nominal run must exceed the limit below: {peak}"
    );

    let text = base_with("duration = 20.0", "duration = 5.0")
        .replacen(
            "[plant]",
            "[plant]\ntorque_limit = [1.0, 0.8, 1.2]\ndisturbance = [0.05, -0.02, 0.01]",
            1,
        )
        .replacen(
            "[controller]",
            "[controller]\ninertia = [[0.9, 0.0, 0.1], [0.0, 1.0, 0.0], [0.1, 0.0, 1.6]]",
            1,
        );
    let limited = dir.path().join("limited");
    let scen = dir.path().join("limited.toml");
    std::fs::write(&scen, text).unwrap();
    ok(&run(&[
        "sim",
        "--scenario",
        scen.to_str().unwrap(),
        "--out",
        limited.to_str().unwrap(),
    ]));
    let (h2, rows2) = read_csv(&limited.join("trajectory.csv"));
    for (i, lim) in [1.0, 0.8, 1.2].iter().enumerate() {
        let tau = column(&h2, &rows2, &format!("tau_{i}"));
        assert!(
            tau.iter().all(|x| x.abs() <= *lim),
            "axis {i} exceeds {lim}"
        );
        assert!(
            tau.iter().any(|x| x.abs() == *lim),
            "axis {i} never saturates"
        );
    }
    // the model inertia enters L: at t = 0 the state is the same, L differs
    let l0 = column(&h, &rows, "lyapunov")[0];
    let l0_model = column(&h2, &rows2, "lyapunov")[0];
    assert!((l0 - l0_model).abs() > 1e-3);
    // and the trajectories part ways after the first step
    assert_ne!(column(&h, &rows, "q_00")[1], column(&h2, &rows2, "q_00")[1]);
}

#[test]
fn a_vehicle_runs_in_sim_and_in_the_pair() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = repo("scenarios/rov_failure.toml");
    let out = run(&[
        "sim",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    ok(&out);
    let (h, rows) = read_csv(&dir.path().join("trajectory.csv"));
    assert!(
        h.iter().any(|c| c == "alloc_status") && h.iter().any(|c| c == "u_cmd_7"),
        "{h:?}"
    );
    assert_eq!(rows.len(), 4001);
    let summary = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    assert!(
        summary.contains("\"saturated_time_s\"") && summary.contains("\"reconfigure\": true"),
        "{summary}"
    );
    // the lockstep pair flies it too, and writes the same rows
    let out = run(&[
        "run",
        "--scenario",
        scenario.to_str().unwrap(),
        "--mode",
        "lockstep",
        "--name",
        "t-vehicle-cli",
        "--out",
        dir.path().join("pair").to_str().unwrap(),
    ]);
    ok(&out);
    assert_eq!(
        std::fs::read(dir.path().join("trajectory.csv")).unwrap(),
        std::fs::read(dir.path().join("pair/trajectory.csv")).unwrap()
    );
}

/// The Monte Carlo study with a vehicle: the spacecraft's thrusters carry every run's torque
/// (allocation in the loop: the runs that saturate them differ from the same study without
/// them, the others not by a bit), the result does not depend on the thread count, and no
/// value is NaN.
#[test]
fn the_monte_carlo_study_flies_a_vehicle_through_its_thrusters() {
    let dir = tempfile::tempdir().unwrap();
    let study = |scenario: &str, threads: &str, out: &str| {
        let out = dir.path().join(out);
        ok(&run(&[
            "montecarlo",
            "--scenario",
            repo(scenario).to_str().unwrap(),
            "--runs",
            "6",
            "--threads",
            threads,
            "--out",
            out.to_str().unwrap(),
        ]));
        std::fs::read_to_string(out.join("runs.csv")).unwrap()
    };
    let one = study("scenarios/spacecraft.toml", "1", "one");
    assert_eq!(one, study("scenarios/spacecraft.toml", "2", "two"));
    let plain = study("scenarios/montecarlo.toml", "2", "plain");
    assert_eq!(one.lines().count(), 1 + 6 * 4);
    let (h, rows) = read_csv(&dir.path().join("one/runs.csv"));
    let (_, plain_rows) = read_csv(&dir.path().join("plain/runs.csv"));
    let effort = column(&h, &rows, "effort_0_20");
    let plain_effort = column(&h, &plain_rows, "effort_0_20");
    assert!(effort.iter().all(|x| x.is_finite()), "{effort:?}");
    assert!(
        column(&h, &rows, "final_attitude_error")
            .iter()
            .all(|x| x.is_finite())
    );
    // the same samples, another plant: where the law asks for more than the thrusters give,
    // the effort changes; where it does not, the thrusters give the law's torque exactly (their
    // arms are 0.5 m, so B u_cmd reproduces the demand bit for bit) and the run is the same
    let differ = effort
        .iter()
        .zip(&plain_effort)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differ >= 6 && differ < effort.len(),
        "{differ} of {} runs differ: {effort:?} vs {plain_effort:?}",
        effort.len()
    );
    assert_ne!(one, plain);
}

/// Bad vehicle tables are refused at load with exit 2, naming the key and what is wrong: a
/// geometry that loses a torque direction, min > max, a zero axis, a NaN, thirteen
/// actuators, a failure of an actuator that is not there.
#[test]
fn bad_vehicle_tables_exit_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(repo("scenarios/spacecraft.toml")).unwrap();
    let first = good.find("[[vehicle.actuator]]").unwrap();
    let blocks: Vec<&str> = good[first..]
        .split("[[vehicle.actuator]]")
        .filter(|b| !b.trim().is_empty())
        .collect();
    assert_eq!(blocks.len(), 12);
    let with = |blocks: &[&str]| {
        let mut s = good[..first].to_owned();
        for b in blocks {
            s += "[[vehicle.actuator]]";
            s += b;
        }
        s
    };
    // the thrusters about ±x (0, 1, 6, 7) gone: no torque about x
    let no_x: Vec<&str> = blocks
        .iter()
        .enumerate()
        .filter(|(j, _)| ![0, 1, 6, 7].contains(j))
        .map(|(_, b)| *b)
        .collect();
    let thirteen: Vec<&str> = blocks.iter().chain(&blocks[..1]).copied().collect();
    let cases = [
        ("lost", with(&no_x), "vehicle.actuator", "miss τx"),
        (
            "min-max",
            good.replacen("min = 0.0", "min = 4.0", 1),
            "min",
            "max",
        ),
        (
            "zero-axis",
            good.replacen("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 0.0]", 1),
            "axis",
            "zero",
        ),
        (
            "nan",
            good.replacen("position = [0, 0.5, 0]", "position = [nan, 0.5, 0]", 1),
            "position",
            "finite",
        ),
        ("thirteen", with(&thirteen), "vehicle.actuator", "12"),
        (
            "failure",
            format!("{good}\n[[vehicle.failure]]\nactuator = 12\nt = 1.0\n"),
            "vehicle.failure",
            "12",
        ),
    ];
    for (name, text, key, what) in cases {
        assert_ne!(text, good, "{name}: the case changes the file");
        let path = dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, &text).unwrap();
        let out = run(&["sim", "--scenario", path.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(
            err.contains(key) && err.contains(what),
            "{name}: the message names neither `{key}` nor `{what}`: {err}"
        );
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

/// The Monte Carlo study in shards: three shards (each on its own thread count) merged give
/// every file of the unsharded study byte for byte; bad shard arguments and bad merges are
/// refused with exit 2, naming what is wrong.
#[test]
fn shards_merge_into_the_unsharded_study_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let study = [
        "montecarlo",
        "--runs",
        "7",
        "--seed",
        "3",
        "--laws",
        "eqt,gt",
    ];
    let with = |extra: &[&str]| {
        let mut a: Vec<&str> = study.to_vec();
        a.extend_from_slice(extra);
        run(&a)
    };
    ok(&with(&["--out", &d("whole")]));
    // N = 1, 3 and 7 (7 runs: one run a shard), each shard on its own thread count, merged
    // in reverse order
    for n in [1usize, 3, 7] {
        for i in 0..n {
            let threads = if i % 2 == 0 { "1" } else { "2" };
            ok(&with(&[
                "--shard",
                &format!("{i}/{n}"),
                "--threads",
                threads,
                "--out",
                &d(&format!("n{n}/s{i}")),
            ]));
        }
        let dirs: Vec<String> = (0..n).rev().map(|i| d(&format!("n{n}/s{i}"))).collect();
        let merged = d(&format!("merged{n}"));
        let mut args: Vec<&str> = vec!["--merge"];
        args.extend(dirs.iter().map(String::as_str));
        args.extend(["--out", &merged]);
        ok(&with(&args));
        for f in [
            "runs.csv",
            "mean.csv",
            "summary.json",
            "figure.svg",
            "figure.png",
        ] {
            let a = std::fs::read(dir.path().join("whole").join(f)).unwrap();
            let b = std::fs::read(dir.path().join(format!("merged{n}")).join(f)).unwrap();
            assert!(
                a == b,
                "{f}: the study merged from {n} shards differs from the unsharded one"
            );
        }
    }
    for i in 0..3 {
        std::fs::rename(
            dir.path().join(format!("n3/s{i}")),
            dir.path().join(format!("s{i}")),
        )
        .unwrap();
    }
    // a shard holds its share only: run indices 1 and 4 for shard 1 of 3 (7 runs)
    let (h, rows) = read_csv(&dir.path().join("s1/runs.csv"));
    assert_eq!(column(&h, &rows, "run"), vec![1.0, 1.0, 4.0, 4.0]);
    let refused = |args: &[&str], says: &str| {
        let out = with(args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: `{says}` not in {err}");
        assert!(!err.contains("panicked"), "{err}");
    };
    refused(&["--shard", "3/3"], "I must be less than N");
    refused(&["--shard", "0/0"], "N must be at least 1");
    refused(&["--shard", "0/2000000"], "N must be at most 1048576");
    refused(&["--shard", "a/2"], "I is not a whole number");
    refused(&["--shard", "1"], "no `/`");
    refused(&["--merge", &d("s0"), &d("s1")], "shard 2 of 3 is missing");
    refused(&["--merge", &d("s0"), &d("s0"), &d("s1")], "given twice");
    refused(&["--merge", &d("whole")], "cannot read it");
    let other = run(&[
        "montecarlo",
        "--runs",
        "7",
        "--seed",
        "4",
        "--laws",
        "eqt,gt",
        "--merge",
        &d("s0"),
        &d("s1"),
        &d("s2"),
        "--out",
        &d("other"),
    ]);
    assert_eq!(other.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&other.stderr).contains("another study"));
    // a shard file cut short or padded is refused, not misread
    let bin = dir.path().join("s1/shard.bin");
    let bytes = std::fs::read(&bin).unwrap();
    std::fs::write(&bin, &bytes[..bytes.len() - 5]).unwrap();
    refused(
        &["--merge", &d("s0"), &d("s1"), &d("s2")],
        "more than the file holds",
    );
    let mut padded = bytes.clone();
    padded.extend_from_slice(&[0; 3]);
    std::fs::write(&bin, &padded).unwrap();
    refused(&["--merge", &d("s0"), &d("s1"), &d("s2")], "bytes over");
    std::fs::write(&bin, b"EQTRKMCS").unwrap();
    refused(&["--merge", &d("s0"), &d("s1"), &d("s2")], "cut short");
}

/// The Slurm example, its tasks run by hand with the variables Slurm sets and a stand-in
/// `sbatch` that records the merge job: the merged study equals the unsharded one.
#[test]
fn the_slurm_example_shards_and_merges_the_study() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let recorded = dir.path().join("sbatch.args");
    let fake = bin.join("sbatch");
    std::fs::write(
        &fake,
        format!(
            "#!/bin/sh\nfor a in \"$@\"; do printf '%s\\n' \"$a\"; done > {}\n",
            recorded.display()
        ),
    )
    .unwrap();
    std::process::Command::new("chmod")
        .args(["+x", fake.to_str().unwrap()])
        .status()
        .unwrap();
    let script = repo("examples/slurm/montecarlo.sbatch");
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = dir.path().join("study");
    for task in 0..3 {
        let status = Command::new("bash")
            .arg(&script)
            .current_dir(dir.path())
            .env("PATH", &path)
            .env("PLANT_SIM", env!("CARGO_BIN_EXE_plant_sim"))
            .env("RUNS", "5")
            .env("OUT", &out)
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .env("SLURM_ARRAY_JOB_ID", "77")
            .status()
            .unwrap();
        assert!(status.success(), "task {task}");
    }
    // the last task asked for the merge job, after the whole array
    let args = std::fs::read_to_string(&recorded).unwrap();
    let lines: Vec<&str> = args.lines().collect();
    assert!(lines.contains(&"--dependency=afterok:77"), "{args}");
    let wrap = lines[lines.iter().position(|l| *l == "--wrap").unwrap() + 1];
    let status = Command::new("sh")
        .args(["-c", wrap])
        .current_dir(dir.path())
        .status()
        .unwrap();
    assert!(status.success(), "{wrap}");
    let whole = dir.path().join("whole");
    ok(&run(&[
        "montecarlo",
        "--runs",
        "5",
        "--out",
        whole.to_str().unwrap(),
    ]));
    for f in ["runs.csv", "mean.csv", "summary.json"] {
        assert!(
            std::fs::read(whole.join(f)).unwrap() == std::fs::read(out.join(f)).unwrap(),
            "{f} differs"
        );
    }
}

#[test]
fn failsafe_tables_are_checked_and_a_runaway_exits_1_naming_the_time() {
    let dir = tempfile::tempdir().unwrap();
    let eight = std::fs::read_to_string(repo("scenarios/hexarotor_eight.toml")).unwrap();
    // hovering 2 m above the world origin under the world-frame law: it leaves its set-point
    let away = eight
        .replace("duration = 22.0", "duration = 3.0")
        .replace(
            "waypoints = \"hexarotor_eight.csv\"\npath = \"through\"\n",
            "setpoint = { rotation = [0.0, 0.0, 0.0], position = [0.0, 0.0, 2.0] }\n",
        )
        .replace(
            "position = [0.0, 0.0, 0.0]\nvelocity",
            "position = [0.0, 0.0, 2.0]\nvelocity",
        )
        .replace("[controller]\n", "[controller]\nerror_frame = \"world\"\n");
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_owned()
    };
    let sim = |scenario: &str, out: &str| {
        bin()
            .args(["sim", "--scenario", scenario, "--out"])
            .arg(dir.path().join(out))
            .output()
            .unwrap()
    };
    // without a limit the run exits 0, however far it goes
    let free = sim(&write("free.toml", &away), "free");
    ok(&free);
    let limited =
        format!("{away}\n[failsafe]\ntracking = \"disarm\"\ntracking_limit_position = 1.0\n");
    let out = sim(&write("limited.toml", &limited), "limited");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("passed its [failsafe] limit at t = 1.502 s"),
        "{err}"
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("failsafe: t = 1.502 s: tracking → disarm")
    );
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("limited/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        summary["failsafe"],
        serde_json::json!([{ "t": 1.502, "cause": "tracking", "action": "disarm" }])
    );
    // trajectory.csv's failsafe column: 0 before, 6 (disarm) from that tick
    let (h, rows) = read_csv(&dir.path().join("limited/trajectory.csv"));
    let (t, code) = (column(&h, &rows, "t"), column(&h, &rows, "failsafe"));
    assert!(
        t.iter()
            .zip(&code)
            .all(|(t, c)| *c == if *t >= 1.502 - 1e-9 { 6.0 } else { 0.0 })
    );
    let (h, _) = read_csv(&dir.path().join("free/trajectory.csv"));
    assert!(!h.iter().any(|c| c == "failsafe"));
    // a bad table exits 2 naming the key: an unknown action, an unknown event, an action
    // that does not fit the vehicle (`surface` without buoyancy, `descend` without gravity),
    // a negative rate
    let circle = std::fs::read_to_string(repo("scenarios/se3_circle.toml")).unwrap();
    for (base, table, says) in [
        (
            &away,
            "[failsafe]\ntracking = \"land\"\ntracking_limit_position = 1.0",
            "key `failsafe.tracking`",
        ),
        (
            &away,
            "[failsafe]\nthruster = \"hold\"",
            "unknown field `thruster`",
        ),
        (
            &away,
            "[failsafe]\nlink = \"surface\"",
            "key `failsafe.link`",
        ),
        (
            &circle,
            "[failsafe]\nlink = \"descend\"",
            "key `failsafe.link`: `descend` comes down along gravity",
        ),
        (
            &away,
            "[failsafe]\nlink = \"descend\"\ndescend_rate = -1.0",
            "key `failsafe.descend_rate`",
        ),
    ] {
        let out = sim(&write("bad.toml", &format!("{base}\n{table}\n")), "bad");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{table}: {err}");
        assert!(err.contains(says), "{table}: {err}");
    }
    // the pair runs the manager on the controller's side: the same runaway, the same tick
    let pair = bin()
        .args(["run", "--scenario", &write("pair.toml", &limited)])
        .args(["--mode", "lockstep", "--name", "cli-failsafe", "--out"])
        .arg(dir.path().join("pair"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&pair.stderr);
    assert_eq!(pair.status.code(), Some(1), "{err}");
    assert!(err.contains("limit at t = 1.502 s"), "{err}");
    // the processor-in-the-loop firmware runs it too (on the seed, whose reference the
    // firmware flies; a lockstep line loses no state: nothing engages)
    let seed = std::fs::read_to_string(repo("scenarios/seed.toml")).unwrap();
    let seed = format!("{seed}\n[failsafe]\nlink = \"hold\"\n");
    let f32 = bin()
        .args(["sim", "--controller-scalar", "f32", "--scenario"])
        .arg(write("f32.toml", &seed))
        .arg("--out")
        .arg(dir.path().join("f32"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&f32.stderr);
    assert_eq!(f32.status.code(), Some(0), "{err}");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("f32/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["failsafe"], serde_json::json!([]));
    let (h, rows) = read_csv(&dir.path().join("f32/trajectory.csv"));
    assert!(column(&h, &rows, "failsafe").iter().all(|c| *c == 0.0));
}

/// `plant_sim sim --controller-scalar SCALAR` of `file` into `out`: its output and its
/// `summary.json`.
fn sim_with_scalar(file: &Path, scalar: &str, out: &Path) -> (Output, serde_json::Value) {
    let o = bin()
        .args(["sim", "--controller-scalar", scalar, "--scenario"])
        .arg(file)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap_or_default();
    (
        o,
        serde_json::from_str(&text).unwrap_or(serde_json::Value::Null),
    )
}

/// The processor-in-the-loop firmware's controller (`--controller-scalar f32`, the code the
/// board runs) flies the thrust-axis descent too: `pil_hexarotor` hovering, rotor 2 dead at
/// 6 s unannounced, `descend` on the found failure. It comes down level at the set rate,
/// as the f64 simulation does.
#[test]
fn the_firmware_flies_the_thrust_axis_descent() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo("scenarios/pil_hexarotor.toml"))
        .unwrap()
        .replace("duration = 4.0", "duration = 12.0")
        .replace(
            "velocity = [0.0, 0.0, 0.3, 0.5, 0.0, 0.0]",
            "velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
        )
        .replace("{ offset = 0.225 }", "{ offset = 0.0 }")
        + "\n[fault_detection]\n\n[[vehicle.failure]]\nactuator = 2\nt = 6.0\nkind = \"dead\"\n\
           reconfigure = false\n\n[failsafe]\nactuators = \"descend\"\n";
    let file = dir.path().join("down.toml");
    std::fs::write(&file, text).unwrap();
    let mut heights = Vec::new();
    for scalar in ["f32", "f64"] {
        let out = dir.path().join(scalar);
        let (o, summary) = sim_with_scalar(&file, scalar, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{scalar}: {err}");
        let tr = summary["failsafe"].as_array().unwrap().clone();
        assert_eq!(tr.len(), 1, "{scalar}: {tr:?}");
        assert_eq!(
            (tr[0]["cause"].as_str(), tr[0]["action"].as_str()),
            (Some("actuators"), Some("descend"))
        );
        assert!((tr[0]["t"].as_f64().unwrap() - 6.06).abs() < 1e-9, "{tr:?}");
        let (h, rows) = read_csv(&out.join("trajectory.csv"));
        let (t, rzz, z) = (
            column(&h, &rows, "t"),
            column(&h, &rows, "q_22"),
            column(&h, &rows, "q_23"),
        );
        let level = t
            .iter()
            .zip(&rzz)
            .filter(|(t, _)| **t > 6.0)
            .map(|(_, r)| *r)
            .fold(1.0, f64::min);
        let at = |time: f64| z[t.iter().position(|x| *x >= time - 1e-9).unwrap()];
        let rate = (at(8.0) - at(12.0)) / 4.0;
        println!("{scalar}: R_zz at least {level:.4}, {rate:.4} m/s from 8 s");
        assert!(level > 0.9, "{scalar}: {level}");
        assert!((rate - 0.5).abs() < 0.05, "{scalar}: {rate}");
        heights.push(z);
    }
    // single precision flies the same descent, within a centimetre
    let worst = heights[0]
        .iter()
        .zip(&heights[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-2, "{worst}");
}

/// The firmware's controller reads its allocation's status and residual too: `pil_hexarotor`
/// with its rotors limited to 3 N and `actuators_residual`, flown by the firmware's code in
/// process (`f32`) and by the simulation (`f64`): `actuators` is raised on the same tick.
#[test]
fn the_firmware_raises_actuators_on_a_torque_it_cannot_give() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo("scenarios/pil_hexarotor.toml"))
        .unwrap()
        .replace("max = 8.0", "max = 3.0")
        + "\n[failsafe]\nactuators = \"warn\"\nactuators_residual = 0.05\n";
    let file = dir.path().join("short.toml");
    std::fs::write(&file, text).unwrap();
    let mut seen = Vec::new();
    for scalar in ["f32", "f64"] {
        let (o, summary) = sim_with_scalar(&file, scalar, &dir.path().join(scalar));
        seen.push((o.status.code(), summary["failsafe"].clone()));
    }
    assert_eq!(seen[0], seen[1]);
    assert_eq!(
        seen[0].1,
        serde_json::json!([{ "t": 0.644, "cause": "actuators", "action": "warn" }])
    );
}
