//! The loop closed on what a board measures: simulated sensors, the complementary filter and
//! the equivariant filter on the plant side, driven through the real binaries
//! (docs/architecture.md, "Sensors and the estimator"). Tests run one at a time ([`serial`]).

use pair_tests::{Csv, TempDir, plant, run, scenario, serial, sim_equals_lockstep, summary};
use std::path::Path;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(120);

#[test]
fn lockstep_with_sensors_and_the_filter_equals_the_simulation_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("sensors-lockstep");
    for name in ["sensors_so3", "sensors_se3", "eqf_so3", "eqf_se3"] {
        let (sim, pair) = sim_equals_lockstep(&d, name, &scenario(name));
        // the pair's log holds the samples: replay steps the estimator over them and gets the
        // published estimates back bit for bit
        let (code, text) = run("plant_sim", &["replay", &pair], LONG);
        assert_eq!(code, 0, "{name}: {text}");
        assert!(text.contains(" 0 differ\n"), "{name}: {text}");
        let checked = text
            .lines()
            .find_map(|l| l.strip_prefix("estimator: "))
            .unwrap_or_else(|| panic!("{name}: no estimator check in {text}"));
        assert!(
            checked.starts_with(&format!(
                "{} estimates checked, 0 differ",
                summary(Path::new(&pair))["cycles"]
            )),
            "{name}: {text}"
        );
        // the estimate is what crossed the wire; the samples and the estimate are recorded
        let csv = Csv::read(&Path::new(&sim).join("trajectory.csv"));
        for col in [
            "gyro_0",
            "dir0_2",
            "qhat_00",
            "bias_hat_2",
            "estimate_error",
        ] {
            assert!(csv.header.iter().any(|h| h == col), "{name}: no {col}");
        }
        if name.ends_with("se3") {
            for col in ["acc_2", "pos_0", "xhat_1", "vhat_2"] {
                assert!(csv.header.iter().any(|h| h == col), "{name}: no {col}");
            }
        }
        let s = summary(Path::new(&sim));
        let eqf = name.starts_with("eqf");
        let kind = if eqf { "eqf" } else { "complementary" };
        assert_eq!(s["estimator"]["kind"], kind, "{s}");
        assert_eq!(summary(Path::new(&pair))["estimator"], s["estimator"]);
        // the EqF's covariance diagonal and NEES are recorded beside its estimate, and only
        // for it
        let has = |c: &str| csv.header.iter().any(|h| h == c);
        assert_eq!(has("cov_0") && has("cov_5") && has("nees"), eqf, "{name}");
        assert_eq!(s["estimator"].get("mean_nees").is_some(), eqf, "{s}");
        if eqf {
            for i in 0..6 {
                assert!(csv.col(&format!("cov_{i}")).iter().all(|x| *x > 0.0));
            }
        }
    }
}

#[test]
fn a_real_time_run_with_sensors_replays_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("sensors-replay");
    for (name, kind) in [("sensors_so3", "complementary"), ("eqf_so3", "eqf")] {
        replays(&d.join(name), name, kind);
    }
}

fn replays(out: &str, name: &str, kind: &str) {
    let file = scenario(name);
    let (code, text) = plant(&[
        "run",
        "--scenario",
        &file,
        "--duration",
        "2",
        "--name",
        &format!("t-rt-{name}"),
        "--out",
        out,
    ]);
    assert_eq!(code, 0, "{text}");
    let s = summary(Path::new(out));
    let cycles = s["cycles"].as_u64().unwrap();
    assert!(cycles >= 2000, "{s}");
    assert_eq!(s["estimator"]["kind"], kind, "{s}");
    // sampling the sensors and stepping the filter allocate nothing on the plant's loop
    assert_eq!(s["plant_loop_heap_allocations"].as_u64(), Some(0), "{s}");
    let (code, text) = run("plant_sim", &["replay", out], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");
    assert!(
        text.contains(&format!("replayed {cycles} cycles")),
        "{text}"
    );
    assert!(
        text.contains(&format!("estimator: {cycles} estimates checked, 0 differ")),
        "every estimate of the run is checked: {text}"
    );
    // one gyro sample nudged by one part in 10^12 in a copy of the log: the replayed
    // estimator publishes another estimate from that cycle on, and replay says where
    let planted = format!("{out}-planted");
    std::fs::create_dir_all(&planted).unwrap();
    std::fs::copy(
        format!("{out}/scenario.toml"),
        format!("{planted}/scenario.toml"),
    )
    .unwrap();
    let mut log = std::fs::read(format!("{out}/messages.log")).unwrap();
    let header = recorder::Header::from_bytes(&log).unwrap();
    assert!(header.sensors);
    let k = 1000;
    let at = recorder::HEADER_BYTES + k * header.record_bytes() + recorder::RECORD_BYTES + 8;
    let gyro = f64::from_le_bytes(log[at..at + 8].try_into().unwrap());
    log[at..at + 8].copy_from_slice(&(gyro * (1.0 + 1e-12) + 1e-15).to_le_bytes());
    std::fs::write(format!("{planted}/messages.log"), log).unwrap();
    let (code, text) = run("plant_sim", &["replay", &planted], LONG);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains(&format!("first estimate difference: cycle {k} ")),
        "{text}"
    );
    assert!(text.contains("replayed estimator differs"), "{text}");
}

/// Every number of `path`'s columns except the raw samples (which record what the sensor
/// gave, NaN included) is finite.
fn finite_except_samples(path: &str) -> usize {
    let csv = Csv::read(&Path::new(path).join("trajectory.csv"));
    let raw = |h: &str| {
        h.starts_with("gyro_")
            || h.starts_with("dir")
            || h.starts_with("acc_")
            || h.starts_with("pos_")
    };
    let mut checked = 0;
    for h in csv.header.iter().filter(|h| !raw(h)) {
        for x in csv.col(h) {
            assert!(x.is_finite(), "{path}: {h} = {x}");
            checked += 1;
        }
    }
    checked
}

#[test]
fn bad_samples_are_counted_and_nothing_the_law_sees_or_does_is_nan() {
    let _g = serial();
    let d = TempDir::new("sensors-faults");
    for name in ["sensors_so3", "eqf_so3"] {
        so3_faults(&d.join(name), name);
    }

    // SE(3): the accelerometer far from g is gated out as a direction, a NaN one predicts
    // without acceleration; the same run through the pair in lockstep counts the same
    for name in ["sensors_se3", "eqf_se3"] {
        se3_faults(&d.join(name), name);
    }
}

fn so3_faults(so3: &str, name: &str) {
    let faults = [
        "100:gyro-nan",
        "101:gyro-inf",
        "102:gyro-spike",
        "103:dir-nan",
        "104:dir-inf",
        "105:dir-zero",
        "300:gyro-nan",
        "300:dir-zero",
    ];
    let mut args = vec!["sim", "--scenario"];
    let file = scenario(name);
    args.push(&file);
    args.extend(["--out", so3]);
    for f in &faults {
        args.extend(["--fault-sample", f]);
    }
    let (code, out) = plant(&args);
    assert_eq!(code, 0, "the run completes:\n{out}");
    let s = summary(Path::new(so3));
    let f = &s["estimator"]["faults"];
    assert_eq!(f["gyro"], 3, "{name}: {s}");
    assert_eq!(f["directions"], 4, "{name}: {s}");
    assert_eq!(s["estimator"]["planted_faults"], 8, "{name}: {s}");
    assert!(finite_except_samples(so3) > 50_000);
    // the planted samples are in the record as they came
    let csv = Csv::read(&Path::new(so3).join("trajectory.csv"));
    assert!(csv.col("gyro_1")[100].is_nan());
    assert_eq!(csv.col("dir0_0")[105], 0.0);
    if name.starts_with("eqf") {
        // its variances stay positive through the faults (and finite: checked above)
        for i in 0..6 {
            assert!(
                csv.col(&format!("cov_{i}")).iter().all(|x| *x > 0.0),
                "cov_{i}"
            );
        }
    }
}

fn se3_faults(se3: &str, name: &str) {
    let pair = format!("{se3}-pair");
    let file = scenario(name);
    let planted = ["50:accel-far", "51:accel-far", "52:gyro-nan", "53:dir-inf"];
    let run_name = format!("t-faults-{name}");
    for (cmd, dir) in [("sim", se3), ("run", pair.as_str())] {
        let mut args = vec![cmd, "--scenario", &file, "--out", dir];
        if cmd == "run" {
            args.extend(["--mode", "lockstep", "--name", &run_name]);
        }
        for f in &planted {
            args.extend(["--fault-sample", f]);
        }
        let (code, out) = plant(&args);
        assert_eq!(code, 0, "{cmd}: {out}");
    }
    let s = summary(Path::new(se3));
    let f = &s["estimator"]["faults"];
    assert!(f["accel_gated"].as_u64().unwrap() >= 2, "{name}: {s}");
    assert_eq!(
        (f["gyro"].as_u64(), f["directions"].as_u64()),
        (Some(1), Some(1)),
        "{name}: {s}"
    );
    finite_except_samples(se3);
    assert_eq!(summary(Path::new(&pair))["estimator"], s["estimator"]);
    assert_eq!(
        std::fs::read(format!("{se3}/trajectory.csv")).unwrap(),
        std::fs::read(format!("{pair}/trajectory.csv")).unwrap()
    );
}

#[test]
fn bad_sensor_and_estimator_keys_exit_2_naming_the_key() {
    let d = TempDir::new("sensors-bad");
    let base = std::fs::read_to_string(scenario("sensors_so3")).unwrap();
    let eqf = std::fs::read_to_string(scenario("eqf_so3")).unwrap();
    let cases = [
        (&base, "seed = 7", "seed = -7", "key `sensors.seed`"),
        (
            &base,
            "noise = 0.002",
            "noise = -0.002",
            "key `sensors.gyro.noise`",
        ),
        (
            &base,
            "world = [0.0, 0.0, 1.0]",
            "world = [0.0, 0.0, 0.0]",
            "key `sensors.directions[0].world`",
        ),
        (
            &base,
            "kind = \"complementary\"",
            "kind = \"ekf\"",
            "key `estimator.kind`",
        ),
        (
            &base,
            "weights = [1.0, 1.0]",
            "weights = [1.0]",
            "key `estimator.weights`",
        ),
        (
            &base,
            "bias_limit = 0.2",
            "bias_limit = -1.0",
            "key `estimator.bias_limit`",
        ),
        (
            &base,
            "kp = 1.0",
            "kp = 1.0\nspeed = 3",
            "unknown field `speed`",
        ),
        // the equivariant filter's keys
        (
            &eqf,
            "initial_attitude_std = 0.1",
            "initial_attitude_std = -0.1",
            "key `estimator.initial_attitude_std`",
        ),
        (
            &eqf,
            "initial_bias_std = 0.03",
            "initial_bias_std = 0.03\ndirection_noise = [0.01, 0.0]",
            "key `estimator.direction_noise`: each must be > 0",
        ),
        (
            &eqf,
            "initial_bias_std = 0.03",
            "initial_bias_std = 0.03\ngyro_noise = nan",
            "key `estimator.gyro_noise`",
        ),
        (
            &eqf,
            "initial_bias_std = 0.03",
            "initial_bias_std = 0.03\nkp = 1.0",
            "key `estimator.kp`: a gain of kind = \"complementary\"",
        ),
        // the innovation gate and the scripted sensor faults
        (
            &eqf,
            "initial_bias_std = 0.03",
            "initial_bias_std = 0.03\nhealth_window = 1.0",
            "key `estimator.health_window`: a setting of the innovation gate",
        ),
        (
            &eqf,
            "initial_bias_std = 0.03",
            "initial_bias_std = 0.03\ngate = true\nfalse_alarm_rate = -1",
            "key `estimator.false_alarm_rate`: must be finite and > 0",
        ),
        (
            &base,
            "[estimator]",
            "[[sensors.fault]]\nsensor = \"direction5\"\nt = 1.0\nkind = \"dropout\"\n[estimator]",
            "key `sensors.fault[0].sensor`: the scenario has no sensor \"direction5\"",
        ),
        (
            &base,
            "[estimator]",
            "[[sensors.fault]]\nsensor = \"gyro\"\nt = 1.0\nkind = \"bias\"\n[estimator]",
            "key `sensors.fault[0].value`: a \"bias\" fault on gyro needs `value`",
        ),
    ];
    for (base, from, to, needle) in cases {
        assert!(base.contains(from), "{from}");
        let path = d.join("bad.toml");
        std::fs::write(&path, base.replacen(from, to, 1)).unwrap();
        for args in [
            vec!["sim", "--scenario", &path],
            vec!["run", "--scenario", &path, "--name", "t-sensors-bad"],
        ] {
            let (code, out) = plant(&args);
            assert_eq!(code, 2, "{to}: {out}");
            assert!(out.contains(needle), "{to}: {out}");
        }
    }
    // and the test-build flag names what it accepts
    let (code, out) = plant(&["sim", "--fault-sample", "3:gyro-fire"]);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("--fault-sample: expected K:gyro-nan"), "{out}");
}

/// `hexarotor_eqf` behind the innovation gate for 6 s, its fixes lost from 1 s to 2 s and its
/// first direction turned by 30° from 3 s, written beside its waypoint file in `d`.
fn gated_with_faults(d: &TempDir) -> String {
    let text = std::fs::read_to_string(scenario("hexarotor_eqf")).unwrap();
    let faults = r#"
[[sensors.fault]]
sensor = "direction0"
t = 3.0
kind = "bias"
rotation = [0.0, 0.0, 0.5235987755982989]

[[sensors.fault]]
sensor = "position"
t = 1.0
duration = 1.0
kind = "dropout"

[estimator]"#;
    let text = text
        .replace("duration = 10.0", "duration = 6.0")
        .replace("kind = \"eqf\"", "kind = \"eqf\"\ngate = true")
        .replace("[estimator]", faults);
    let csv = pair_tests::repo("scenarios/hexarotor_eight.csv");
    std::fs::copy(csv, d.join("hexarotor_eight.csv")).unwrap();
    let path = d.join("gated.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The gate and the scripted faults in the lockstep pair: the same bytes as the simulation,
/// the health and its changes recorded, replay checking every estimate; a serial run of a
/// gated scenario is refused, naming the key.
#[test]
fn lockstep_with_the_gate_and_sensor_faults_equals_the_simulation_and_replays() {
    let _g = serial();
    let d = TempDir::new("sensors-gated");
    let file = gated_with_faults(&d);
    let (sim, pair) = sim_equals_lockstep(&d, "gated", &file);
    let (code, text) = run("plant_sim", &["replay", &pair], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("estimates checked, 0 differ"), "{text}");
    let s = summary(Path::new(&sim));
    assert_eq!(summary(Path::new(&pair))["estimator"], s["estimator"]);
    let gate = &s["estimator"]["gate"];
    let changes: Vec<(&str, &str)> = gate["health"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["health"].as_str().unwrap(), c["reason"].as_str().unwrap()))
        .collect();
    assert_eq!(
        changes,
        [
            ("degraded", "missing position"),
            ("healthy", ""),
            ("degraded", "rejected direction0")
        ],
        "{gate}"
    );
    // the biased samples from 3 s to the last tick at 6 s at 500 Hz, every one rejected
    assert_eq!(gate["rejected"]["direction0"], 1501, "{gate}");
    let csv = Csv::read(&Path::new(&sim).join("trajectory.csv"));
    let health = csv.col("health");
    // degraded from a window after the last fix (1.48 s) to the first back (2.0 s), and from 3 s
    assert_eq!(
        health.iter().filter(|h| **h == 1.0).count(),
        260 + 1501,
        "{health:?}"
    );
    // the firmware runs the gate on board: the f32 run (the firmware's code in process) flies
    // (tests/tests/pil.rs holds on its health); the rejections stay on the board, so its
    // summary has no `estimator.gate`
    let text = std::fs::read_to_string(scenario("eqf_se3")).unwrap();
    let gated = d.join("eqf_se3_gated.toml");
    std::fs::write(
        &gated,
        text.replace("kind = \"eqf\"", "kind = \"eqf\"\ngate = true"),
    )
    .unwrap();
    let on_board = d.join("eqf_se3_f32");
    let (code, out) = plant(&[
        "sim",
        "--scenario",
        &gated,
        "--controller-scalar",
        "f32",
        "--out",
        &on_board,
    ]);
    assert_eq!(code, 0, "{out}");
    let f32_summary = summary(Path::new(&on_board));
    assert!(
        f32_summary["estimator"].get("gate").is_none(),
        "{f32_summary}"
    );
}
