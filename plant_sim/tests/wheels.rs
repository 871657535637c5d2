//! Reaction wheels flown by `plant_sim sim` (docs/vehicles.md, "Reaction wheels"): the slew
//! that saturates them, the world momentum kept over a whole flight, the plant's limits
//! counted, and bad tables refused naming the key.

mod common;

use common::{ok, run, text};
use pair_tests::{column, read_csv, repo};
use std::path::Path;

const SLEW: &str = "scenarios/wheels_slew.toml";

fn slew_text() -> String {
    std::fs::read_to_string(repo(SLEW)).unwrap()
}

/// Flies `text` as a scenario in `dir`; returns the trajectory's header and rows.
fn fly(dir: &Path, name: &str, text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let out_dir = dir.join(name);
    let out = run(&[
        "sim",
        "--scenario",
        path.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    ok(&out);
    read_csv(&out_dir.join("trajectory.csv"))
}

fn summary(dir: &Path, name: &str) -> serde_json::Value {
    let s = std::fs::read_to_string(dir.join(name).join("summary.json")).unwrap();
    serde_json::from_str(&s).unwrap()
}

#[test]
fn the_slew_saturates_its_wheels_and_arrives() {
    let dir = tempfile::tempdir().unwrap();
    let (h, rows) = fly(dir.path(), "slew", &slew_text());
    let status = column(&h, &rows, "alloc_status");
    let saturated = status.iter().filter(|s| **s == 1.0).count();
    assert!(
        saturated > 100,
        "the torque asked for is out of the wheels' reach for a while: {saturated} ticks"
    );
    let u0 = column(&h, &rows, "u_cmd_0");
    assert!(u0.iter().all(|u| u.abs() <= 0.01 + 1e-15));
    assert!(
        u0.iter().any(|u| (u.abs() - 0.01).abs() < 1e-12),
        "a motor at its limit"
    );
    let speed = column(&h, &rows, "wheel_speed_0");
    assert!(speed.iter().any(|s| s.abs() > 100.0), "the wheel spun up");
    let err = column(&h, &rows, "attitude_error");
    assert!(err[0] > 1.0, "a large slew: {}", err[0]);
    assert!(
        *err.last().unwrap() < 1e-3,
        "it arrives: {}",
        err.last().unwrap()
    );
    // the wheel's motor torque is its command: nothing was out of the plant's limits
    assert_eq!(
        column(&h, &rows, "wheel_cmd_0")[..rows.len() - 1],
        u0[..rows.len() - 1]
    );
    let s = summary(dir.path(), "slew");
    assert_eq!(s["vehicle"]["wheel_clamps"], 0, "{s}");
    assert!(
        s["vehicle"]["saturated_time_s"][0].as_f64().unwrap() > 1.0,
        "{s}"
    );
}

/// `R (I ω + Σ J_s Ω_i g_i)` at every row of a flight of the slew's spacecraft.
fn world_momentum(h: &[String], rows: &[Vec<String>]) -> Vec<[f64; 3]> {
    let inertia = [[0.5, 0.0, 0.02], [0.0, 0.6, 0.0], [0.02, 0.0, 0.4]];
    let (c, s, js) = (0.8660254037844387, 0.5, 2e-4);
    let axes = [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]];
    let q: Vec<Vec<f64>> = (0..9)
        .map(|k| column(h, rows, &format!("q_{}{}", k / 3, k % 3)))
        .collect();
    let v: Vec<Vec<f64>> = (0..3).map(|i| column(h, rows, &format!("v_{i}"))).collect();
    let w: Vec<Vec<f64>> = (0..4)
        .map(|i| column(h, rows, &format!("wheel_speed_{i}")))
        .collect();
    (0..rows.len())
        .map(|k| {
            let mut body = [0.0; 3];
            for (r, b) in body.iter_mut().enumerate() {
                *b = (0..3).map(|c| inertia[r][c] * v[c][k]).sum::<f64>()
                    + (0..4).map(|i| js * w[i][k] * axes[i][r]).sum::<f64>();
            }
            let mut world = [0.0; 3];
            for (r, x) in world.iter_mut().enumerate() {
                *x = (0..3).map(|c| q[r * 3 + c][k] * body[c]).sum();
            }
            world
        })
        .collect()
}

#[test]
fn the_world_momentum_is_kept_over_a_whole_saturating_flight() {
    let dir = tempfile::tempdir().unwrap();
    // the slew from a tumble with the wheels already turning: the law drives the wheels
    // hard, but nothing outside touches the spacecraft
    let base = slew_text().replace(
        "velocity = [0.0, 0.0, 0.0]\n\n[reference]",
        "velocity = [0.05, -0.04, 0.03]\n\n[reference]",
    );
    let base = base.replacen(
        "stribeck_speed = 0.5",
        "stribeck_speed = 0.5\nspeed = 150.0",
        1,
    );
    assert_ne!(base, slew_text());
    let frictionless = base
        .replace("friction_coulomb = 5e-5", "friction_coulomb = 0.0")
        .replace("friction_static = 1e-4", "friction_static = 0.0")
        .replace("friction_viscous = 1e-7", "friction_viscous = 0.0");
    for (name, text) in [("friction", base), ("frictionless", frictionless)] {
        let (h, rows) = fly(dir.path(), name, &text);
        let m = world_momentum(&h, &rows);
        let size = m[0].iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(size > 0.01, "{name}: a momentum to keep: {size}");
        let drift = m
            .iter()
            .map(|x| (0..3).map(|i| (x[i] - m[0][i]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        assert!(drift < 1e-9 * size, "{name}: drift {drift} of {size}");
        let status = column(&h, &rows, "alloc_status");
        assert!(status.contains(&1.0), "{name}: the wheels saturated");
    }
}

#[test]
fn a_power_limit_is_the_plants_and_each_clamp_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    // the allocator knows the torque and speed limits, not the power: the plant clamps
    let text = slew_text().replace("max_speed = 600.0", "max_speed = 600.0\nmax_power = 0.5");
    let (h, rows) = fly(dir.path(), "power", &text);
    let clamps = summary(dir.path(), "power")["vehicle"]["wheel_clamps"]
        .as_u64()
        .unwrap();
    let (cmd, applied, speed) = (
        column(&h, &rows, "u_cmd_0"),
        column(&h, &rows, "wheel_cmd_0"),
        column(&h, &rows, "wheel_speed_0"),
    );
    let changed = (0..rows.len() - 1)
        .filter(|&k| cmd[k] != applied[k])
        .count();
    assert!(
        changed > 0 && clamps as usize >= changed,
        "{changed} rows, {clamps} clamps"
    );
    for k in 0..rows.len() - 1 {
        assert!(
            (applied[k] * speed[k]).abs() <= 0.5 + 1e-12 || applied[k] == cmd[k],
            "row {k}: {} N·m at {} rad/s",
            applied[k],
            speed[k]
        );
    }
}

#[test]
fn bad_wheel_tables_exit_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let good = slew_text();
    let wheel = &good[good.find("[[vehicle.wheel]]").unwrap()..];
    let first = wheel[1..]
        .find("[[vehicle.wheel]]")
        .map_or(wheel, |e| &wheel[..e + 1]);
    let seven = format!("{good}\n{}", first.repeat(3));
    let thrusters = std::fs::read_to_string(repo("scenarios/spacecraft.toml")).unwrap();
    let cases = [
        (
            "zero-axis",
            good.replacen(
                "axis = [0.8660254037844387, 0.0, 0.5]",
                "axis = [0.0, 0.0, 0.0]",
                1,
            ),
            "vehicle.wheel[0].axis",
            "zero",
        ),
        (
            "nan-axis",
            good.replacen(
                "axis = [0.8660254037844387, 0.0, 0.5]",
                "axis = [nan, 0.0, 0.5]",
                1,
            ),
            "vehicle.wheel[0].axis",
            "finite",
        ),
        (
            "inertia",
            good.replacen("inertia = 2e-4", "inertia = 0.0", 1),
            "vehicle.wheel[0].inertia",
            "> 0",
        ),
        (
            "torque",
            good.replacen("max_torque = 0.01", "max_torque = -0.01", 1),
            "vehicle.wheel[0].max_torque",
            "> 0",
        ),
        (
            "speed-limit",
            good.replacen("max_speed = 600.0", "max_speed = inf", 1),
            "vehicle.wheel[0].max_speed",
            "finite",
        ),
        (
            "power",
            good.replacen("max_speed = 600.0", "max_speed = 600.0\nmax_power = 0.0", 1),
            "vehicle.wheel[0].max_power",
            "> 0",
        ),
        (
            "coulomb",
            good.replacen("friction_coulomb = 5e-5", "friction_coulomb = -5e-5", 1),
            "vehicle.wheel[0].friction_coulomb",
            "≥ 0",
        ),
        (
            "viscous",
            good.replacen("friction_viscous = 1e-7", "friction_viscous = nan", 1),
            "vehicle.wheel[0].friction_viscous",
            "finite",
        ),
        (
            "stribeck",
            good.replacen("stribeck_speed = 0.5", "stribeck_speed = 0.0", 1),
            "vehicle.wheel[0].stribeck_speed",
            "> 0",
        ),
        (
            "speed",
            good.replacen(
                "stribeck_speed = 0.5",
                "stribeck_speed = 0.5\nspeed = 700.0",
                1,
            ),
            "vehicle.wheel[0].speed",
            "max_speed",
        ),
        (
            "unknown",
            good.replacen("inertia = 2e-4", "inertia = 2e-4\nmomentum = 1.0", 1),
            "momentum",
            "unknown",
        ),
        ("seven", seven, "vehicle.wheel", "at most 6"),
        (
            "spin",
            good.replace("inertia = 2e-4", "inertia = 0.5"),
            "vehicle.wheel",
            "positive definite",
        ),
        (
            "thirteen",
            format!("{thrusters}\n{first}"),
            "vehicle.actuator",
            "12",
        ),
        (
            "failsafe",
            format!("{good}\n[failsafe]\n"),
            "failsafe",
            "reaction wheels",
        ),
        (
            "stiff",
            good.replacen("friction_coulomb = 5e-5", "friction_coulomb = 1e-3", 1),
            "vehicle.wheel[0].friction_coulomb",
            "plant_substeps",
        ),
    ];
    for (name, text, key, what) in cases {
        assert_ne!(text, good, "{name}: the case changes the file");
        let err = refused(dir.path(), name, &text, key, what);
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

fn text_of(out: &std::process::Output) -> String {
    text(out)
}

/// Writes `text` as scenario `name` in `dir` and requires `plant_sim sim` to refuse it with
/// exit 2, its message naming `key` and `what`; returns the message.
fn refused(dir: &Path, name: &str, text: &str, key: &str, what: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let out = run(&["sim", "--scenario", path.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{name}: {}", text_of(&out));
    assert!(
        err.contains(key) && err.contains(what),
        "{name}: the message names neither `{key}` nor `{what}`: {err}"
    );
    err
}

/// `|h_w| = |Σ J_s (g_iᵀω + Ω_i) g_i|` at every row of a flight with the slew's wheels.
fn wheel_momentum(h: &[String], rows: &[Vec<String>]) -> Vec<f64> {
    let (c, s, js) = (0.8660254037844387, 0.5, 2e-4);
    let axes = [[c, 0.0, s], [0.0, c, s], [-c, 0.0, s], [0.0, -c, s]];
    let v: Vec<Vec<f64>> = (0..3).map(|i| column(h, rows, &format!("v_{i}"))).collect();
    let w: Vec<Vec<f64>> = (0..4)
        .map(|i| column(h, rows, &format!("wheel_speed_{i}")))
        .collect();
    (0..rows.len())
        .map(|k| {
            let mut total = [0.0f64; 3];
            for (i, g) in axes.iter().enumerate() {
                let hi = js * ((0..3).map(|r| g[r] * v[r][k]).sum::<f64>() + w[i][k]);
                for r in 0..3 {
                    total[r] += hi * g[r];
                }
            }
            total.iter().map(|x| x * x).sum::<f64>().sqrt()
        })
        .collect()
}

#[test]
fn dumping_keeps_the_wheels_momentum_within_a_tenth_above_its_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(repo("scenarios/wheels_dump.toml")).unwrap();
    let (h, rows) = fly(dir.path(), "dump", &text);
    let t = column(&h, &rows, "t");
    assert!(*t.last().unwrap() >= 600.0 - 1e-9, "ten minutes");
    let hw = wheel_momentum(&h, &rows);
    let first = hw
        .iter()
        .position(|x| *x > 0.05)
        .expect("the momentum reached the threshold");
    let top = hw[first..].iter().fold(0.0f64, |a, x| a.max(*x));
    assert!(top <= 1.1 * 0.05, "|h_w| rose to {top}");
    let fired = (0..6)
        .map(|j| column(&h, &rows, &format!("u_cmd_{j}")))
        .any(|u| u.iter().any(|x| *x > 1e-4));
    assert!(fired, "the thrusters dumped");
    let err = column(&h, &rows, "attitude_error");
    assert!(err.iter().all(|e| *e < 5e-3), "the wheels kept pointing");
    // without the dump the same torque fills the wheels far past the threshold
    let start = text.find("[vehicle.momentum]").unwrap();
    let (h2, rows2) = fly(dir.path(), "no-dump", &text[..start]);
    let undumped = wheel_momentum(&h2, &rows2);
    assert!(
        undumped.iter().fold(0.0f64, |a, x| a.max(*x)) > 2.0 * 0.05,
        "without dumping the momentum grows"
    );
}

#[test]
fn the_null_space_brings_the_wheels_to_their_bias_and_the_slew_still_arrives() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "{}\n[vehicle.momentum]\nnull_space_gain = 0.5\nbias = [100.0, -100.0, 100.0, -100.0]\n",
        slew_text()
    );
    let (h, rows) = fly(dir.path(), "null", &text);
    let last = rows.len() - 1;
    for (i, bias) in [100.0, -100.0, 100.0, -100.0].iter().enumerate() {
        let s = column(&h, &rows, &format!("wheel_speed_{i}"))[last];
        assert!(
            (s - bias).abs() < 1.0,
            "wheel {i} at {s} rad/s, bias {bias}"
        );
    }
    let err = column(&h, &rows, "attitude_error");
    assert!(err[last] < 1e-3, "it arrives: {}", err[last]);
    // without it the wheels end near rest
    let (h0, rows0) = fly(dir.path(), "plain", &slew_text());
    let s0 = column(&h0, &rows0, "wheel_speed_0")[rows0.len() - 1];
    assert!(s0.abs() < 10.0, "{s0}");
}

#[test]
fn bad_momentum_tables_exit_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let slew = slew_text();
    let dump = std::fs::read_to_string(repo("scenarios/wheels_dump.toml")).unwrap();
    let thrusters = std::fs::read_to_string(repo("scenarios/spacecraft.toml")).unwrap();
    let with = |base: &str, table: &str| format!("{base}\n[vehicle.momentum]\n{table}\n");
    let three = {
        let cut = slew.rfind("[[vehicle.wheel]]").unwrap();
        slew[..cut].to_owned()
    };
    // the ROV (SE(3), eight thrusters) with the slew's four wheels and a dump
    let rov = std::fs::read_to_string(repo("scenarios/rov_failure.toml")).unwrap();
    let wheels = &slew[slew.find("[[vehicle.wheel]]").unwrap()..];
    let se3 =
        format!("{rov}\n{wheels}\n[vehicle.momentum]\ndump_threshold = 0.05\ndump_gain = 0.2\n");
    let cases = [
        ("se3-dump", se3, "vehicle.momentum.dump_gain", "SE(3)"),
        (
            "no-wheels",
            with(&thrusters, "null_space_gain = 0.1"),
            "vehicle.momentum",
            "reaction wheels",
        ),
        (
            "three",
            with(&three, "null_space_gain = 0.1"),
            "vehicle.momentum.null_space_gain",
            "four or more",
        ),
        (
            "fast",
            with(&slew, "null_space_gain = 100.0"),
            "vehicle.momentum.null_space_gain",
            "1/h",
        ),
        (
            "negative",
            with(&slew, "null_space_gain = -0.1"),
            "vehicle.momentum.null_space_gain",
            "≥ 0",
        ),
        (
            "bias-length",
            with(&slew, "null_space_gain = 0.1\nbias = [1.0]"),
            "vehicle.momentum.bias",
            "4",
        ),
        (
            "bias-speed",
            with(&slew, "bias = [0.0, 0.0, 700.0, 0.0]"),
            "vehicle.momentum.bias",
            "max_speed",
        ),
        (
            "no-thrusters",
            with(&slew, "dump_gain = 0.2\ndump_threshold = 0.05"),
            "vehicle.momentum.dump_gain",
            "thrusters",
        ),
        (
            "no-threshold",
            dump.replace("dump_threshold = 0.05\n", ""),
            "vehicle.momentum.dump_threshold",
            "threshold",
        ),
        (
            "threshold",
            dump.replace("dump_threshold = 0.05", "dump_threshold = 0.0"),
            "vehicle.momentum.dump_threshold",
            "> 0",
        ),
        (
            "unknown",
            dump.replace("dump_gain = 0.2", "dump_gain = 0.2\ndump_rate = 1.0"),
            "dump_rate",
            "unknown",
        ),
    ];
    for (name, text, key, what) in cases {
        refused(dir.path(), name, &text, key, what);
    }
}

#[test]
fn a_dead_wheel_told_to_the_allocator_leaves_three_that_still_arrive() {
    let dir = tempfile::tempdir().unwrap();
    // wheel 1 (actuator 1: the wheels are the only actuators) dies at 2 s, mid-slew; without
    // friction, whose dead band (a command below f_C moves nothing) would leave a law without
    // an integral short of the target by about f_C/k_p either way
    let frictionless = slew_text()
        .replace("friction_coulomb = 5e-5", "friction_coulomb = 0.0")
        .replace("friction_static = 1e-4", "friction_static = 0.0")
        .replace("friction_viscous = 1e-7", "friction_viscous = 0.0");
    let dead = |told: bool| {
        format!(
            "{frictionless}\n[[vehicle.failure]]\nactuator = 1\nt = 2.0\nkind = \"dead\"\nreconfigure = {told}\n"
        )
    };
    let (h, rows) = fly(dir.path(), "told", &dead(true));
    let t = column(&h, &rows, "t");
    let (cmd, applied) = (
        column(&h, &rows, "u_cmd_1"),
        column(&h, &rows, "wheel_cmd_1"),
    );
    let after: Vec<usize> = (0..rows.len() - 1)
        .filter(|&k| t[k] >= 2.0 - 1e-9)
        .collect();
    assert!(
        after.iter().all(|&k| applied[k] == 0.0),
        "the dead motor gives nothing"
    );
    assert!(
        after.iter().all(|&k| cmd[k] == 0.0),
        "and the told allocator asks nothing of it"
    );
    let before = (0..rows.len()).filter(|&k| t[k] < 2.0 - 1e-9);
    assert!(
        before.clone().any(|k| applied[k] != 0.0),
        "it worked before"
    );
    let err = column(&h, &rows, "attitude_error");
    assert!(
        *err.last().unwrap() < 1e-3,
        "three wheels arrive: {}",
        err.last().unwrap()
    );
    // untold, the allocator keeps asking the dead wheel for torque
    let (h2, rows2) = fly(dir.path(), "untold", &dead(false));
    let t2 = column(&h2, &rows2, "t");
    let cmd2 = column(&h2, &rows2, "u_cmd_1");
    let applied2 = column(&h2, &rows2, "wheel_cmd_1");
    let asked = (0..rows2.len() - 1)
        .filter(|&k| t2[k] >= 2.0 && cmd2[k] != 0.0)
        .count();
    assert!(asked > 100, "untold, it is still commanded: {asked}");
    assert!(
        (0..rows2.len() - 1)
            .filter(|&k| t2[k] >= 2.0)
            .all(|k| applied2[k] == 0.0)
    );
    // a wheel's stuck value is a torque within its motor's range
    let bad = slew_text() + "\n[[vehicle.failure]]\nactuator = 2\nt = 1.0\nvalue = 0.5\n";
    refused(dir.path(), "bad", &bad, "vehicle.failure[0].value", "0.01");
}

#[test]
fn the_detector_finds_an_unannounced_dead_wheel_and_flags_nothing_in_nominal_flight() {
    let dir = tempfile::tempdir().unwrap();
    // the slew with friction (which the detector does not model) and the detector's defaults:
    // two seconds of warm-up, two of calibration
    let watched = format!("{}\n[fault_detection]\n", slew_text());
    fly(dir.path(), "nominal", &watched);
    let s = summary(dir.path(), "nominal");
    assert_eq!(s["vehicle"]["detections"], serde_json::json!([]), "{s}");
    assert_eq!(s["vehicle"]["alarms"], 0, "{s}");
    // wheel 1's motor dies at 8 s, mid-slew, and nobody says so
    let dead = format!(
        "{watched}\n[[vehicle.failure]]\nactuator = 1\nt = 8.0\nkind = \"dead\"\nreconfigure = false\n"
    );
    let (h, rows) = fly(dir.path(), "dead", &dead);
    let s = summary(dir.path(), "dead");
    let found = &s["vehicle"]["detections"];
    assert_eq!(found.as_array().map(Vec::len), Some(1), "{s}");
    assert_eq!(found[0]["actuator"], 1, "{s}");
    assert_eq!(found[0]["kind"], "dead", "{s}");
    let latency = found[0]["latency"].as_f64().unwrap();
    assert!(latency > 0.0 && latency < 0.5, "{s}");
    // told by the detector, the allocator asks nothing more of it and three wheels arrive
    let t = column(&h, &rows, "t");
    let cmd = column(&h, &rows, "u_cmd_1");
    let after = found[0]["t"].as_f64().unwrap();
    assert!(
        (0..rows.len() - 1)
            .filter(|&k| t[k] > after + 1e-9)
            .all(|k| cmd[k] == 0.0)
    );
    let err = column(&h, &rows, "attitude_error");
    assert!(*err.last().unwrap() < 1e-3, "{}", err.last().unwrap());
}
