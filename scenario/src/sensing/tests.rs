//! `[sensors]` and `[estimator]`: the tables parse, and bad values name their key.

use crate::Scenario;

const SO3: &str = r#"
[sensors]
seed = 7
gyro = { noise = 0.002, bias = [0.02, -0.01, 0.03], bias_walk = 1e-5 }
directions = [ { world = [0.0, 0.0, 2.0], noise = 0.01 }, { world = [0.5, 0.0, 0.866], noise = 0.02 } ]

[estimator]
kind = "complementary"
kp = 2.0
ki = 0.5
weights = [1.0, 0.5]
bias_limit = 0.1
"#;

fn seed_with(extra: &str) -> Result<Scenario, String> {
    let text = format!("{}\n{extra}", crate::BUILTINS[0].1);
    Scenario::from_toml(&text, "test.toml", "test").map_err(|e| e.to_string())
}

fn se3_with(extra: &str) -> Result<Scenario, String> {
    let text = format!("{}\n{extra}", crate::BUILTINS[2].1);
    Scenario::from_toml(&text, "test.toml", "test").map_err(|e| e.to_string())
}

#[test]
fn the_tables_parse_and_directions_are_normalised() {
    let s = seed_with(SO3).unwrap();
    let sensors = s.sensors.as_ref().unwrap();
    assert_eq!(sensors.seed, 7);
    assert_eq!(sensors.gyro.bias, [0.02, -0.01, 0.03]);
    assert_eq!(sensors.directions[0].world, [0.0, 0.0, 1.0]);
    let w = sensors.directions[1].world;
    assert!(((w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt() - 1.0).abs() < 1e-15);
    assert_eq!(s.estimator.kind, super::EstimatorKind::Complementary);
    assert_eq!(s.estimator.weights, vec![1.0, 0.5]);
    assert_eq!(s.estimator.bias_limit, Some(0.1));
    // neither table changes what the controller takes
    let plain = Scenario::builtin("seed").unwrap();
    assert_eq!(s.fingerprint(), plain.fingerprint());
    assert!(plain.sensors.is_none() && !plain.estimator.estimates());
}

#[test]
fn se3_needs_the_accelerometer_and_fixes_and_weighs_the_accelerometer_last() {
    let ok = r#"
[sensors]
directions = [ { world = [1.0, 0.0, 0.0], noise = 0.01 } ]
accelerometer = { noise = 0.05 }
position = { noise = 0.005, rate_hz = 100.0 }
[estimator]
kind = "complementary"
weights = [1.0, 2.0]
accel_gate = 1.0
"#;
    let s = se3_with(ok).unwrap();
    assert_eq!(s.estimator.weights, vec![1.0, 2.0]);
    assert_eq!(s.sensors.unwrap().position.unwrap().rate_hz, 100.0);
    let e = se3_with(&ok.replace("position = { noise = 0.005, rate_hz = 100.0 }", "")).unwrap_err();
    assert!(e.contains("key `sensors.position`: missing"), "{e}");
    let e = se3_with(&ok.replace("weights = [1.0, 2.0]", "weights = [1.0]")).unwrap_err();
    assert!(
        e.contains("key `estimator.weights`: expected 2 numbers"),
        "{e}"
    );
}

#[test]
fn bad_values_name_the_key_and_what_is_wrong() {
    for (from, to, needle) in [
        ("seed = 7", "seed = -1", "key `sensors.seed`: must be ≥ 0"),
        (
            "noise = 0.002",
            "noise = -0.002",
            "key `sensors.gyro.noise`: must be a finite number ≥ 0",
        ),
        (
            "bias_walk = 1e-5",
            "bias_walk = nan",
            "key `sensors.gyro.bias_walk`",
        ),
        (
            "bias = [0.02, -0.01, 0.03]",
            "bias = [0.02, -0.01]",
            "key `sensors.gyro.bias`: expected 3 numbers",
        ),
        (
            "bias = [0.02, -0.01, 0.03]",
            "bias = [0.02, -0.01, inf]",
            "key `sensors.gyro.bias`: entry 2 is not a finite number",
        ),
        (
            "world = [0.0, 0.0, 2.0]",
            "world = [0.0, 0.0, 0.0]",
            "key `sensors.directions[0].world`: a direction must not be zero",
        ),
        (
            "noise = 0.02 }",
            "noise = -1.0 }",
            "key `sensors.directions[1].noise`",
        ),
        (
            "kind = \"complementary\"",
            "kind = \"kalman\"",
            "key `estimator.kind`: unknown kind `kalman`",
        ),
        ("kp = 2.0", "kp = -2.0", "key `estimator.kp`"),
        ("ki = 0.5", "ki = inf", "key `estimator.ki`"),
        (
            "weights = [1.0, 0.5]",
            "weights = [1.0, 0.0]",
            "key `estimator.weights`: must be > 0",
        ),
        (
            "weights = [1.0, 0.5]",
            "weights = [1.0, 0.5, 1.0]",
            "key `estimator.weights`: expected 2 numbers (one per direction)",
        ),
        (
            "bias_limit = 0.1",
            "bias_limit = 0.0",
            "key `estimator.bias_limit`",
        ),
        (
            "bias_limit = 0.1",
            "accel_gate = 1.0",
            "key `estimator.accel_gate`: only se3",
        ),
        (
            "seed = 7",
            "seed = 7\naccelerometer = { noise = 0.1 }",
            "key `sensors.accelerometer`: only se3",
        ),
        (
            "seed = 7",
            "seed = 7\nposition = { noise = 0.1, rate_hz = 10.0 }",
            "key `sensors.position`: only se3",
        ),
        (
            "seed = 7",
            "seed = 7\nmagnetometer = 1",
            "unknown field `magnetometer`",
        ),
        ("kp = 2.0", "kp = 2.0\ngain = 1", "unknown field `gain`"),
        (
            "noise = 0.002,",
            "noise = \"low\",",
            "invalid type: string \"low\", expected f64",
        ),
    ] {
        assert!(SO3.contains(from), "{from}");
        let e = seed_with(&SO3.replacen(from, to, 1)).unwrap_err();
        assert!(e.contains(needle), "{to}: {e}");
    }
    // one direction is not enough for an attitude
    let one = SO3.replace(", { world = [0.5, 0.0, 0.866], noise = 0.02 }", "");
    let e = seed_with(&one.replace("weights = [1.0, 0.5]", "")).unwrap_err();
    assert!(
        e.contains("key `sensors.directions`: the filter needs two"),
        "{e}"
    );
    let five = "directions = [ {world=[1.0,0.0,0.0]}, {world=[0.0,1.0,0.0]}, {world=[0.0,0.0,1.0]}, {world=[1.0,1.0,0.0]}, {world=[0.0,1.0,1.0]} ]";
    let e = seed_with(&format!("[sensors]\n{five}\n")).unwrap_err();
    assert!(e.contains("key `sensors.directions`: at most 4"), "{e}");
    // a filter needs sensors; truth takes no gains
    let e = seed_with("[estimator]\nkind = \"complementary\"\n").unwrap_err();
    assert!(e.contains("needs a [sensors] table"), "{e}");
    let e = seed_with("[estimator]\nkind = \"truth\"\nkp = 1.0\n").unwrap_err();
    assert!(e.contains("key `estimator.kp`: kind = \"truth\""), "{e}");
}

/// `[[sensors.fault]]` on se3: every kind on every sensor parses, and each bad value is
/// refused naming its key.
#[test]
fn sensor_faults_parse_and_bad_ones_name_the_key() {
    use super::{Sensor, SensorFault, SensorFaultKind};
    let sensors = r#"
[sensors]
directions = [ { world = [1.0, 0.0, 0.0], noise = 0.01 }, { world = [0.0, 1.0, 0.0] } ]
accelerometer = { noise = 0.05 }
position = { noise = 0.005, rate_hz = 100.0 }
"#;
    let fault = |body: &str| format!("{sensors}[[sensors.fault]]\n{body}\n");
    let ok = fault(
        "sensor = \"direction1\"\nt = 5.0\nduration = 2.5\nkind = \"bias\"\nrotation = [0.0, 0.5, 0.0]",
    ) + "[[sensors.fault]]\nsensor = \"position\"\nt = 1.0\nkind = \"dropout\"\n"
        + "[[sensors.fault]]\nsensor = \"gyro\"\nt = 7.5\nkind = \"stuck\"\n"
        + "[[sensors.fault]]\nsensor = \"direction1\"\nt = 7.5\nduration = 1\nkind = \"dropout\"\n"
        + "[[sensors.fault]]\nsensor = \"accelerometer\"\nt = 0\nkind = \"bias\"\nvalue = [0, 0, 1]\n";
    let s = se3_with(&ok).unwrap();
    let f = &s.sensors.as_ref().unwrap().faults;
    assert_eq!(
        f[0],
        SensorFault {
            sensor: Sensor::Direction(1),
            t: 5.0,
            duration: Some(2.5),
            kind: SensorFaultKind::Bias([0.0, 0.5, 0.0]),
        }
    );
    assert_eq!(
        (f[1].sensor, f[1].duration, f[1].kind),
        (Sensor::Position, None, SensorFaultKind::Dropout)
    );
    assert_eq!(
        (f[2].sensor, f[2].kind),
        (Sensor::Gyro, SensorFaultKind::Stuck)
    );
    assert_eq!(f[4].kind, SensorFaultKind::Bias([0.0, 0.0, 1.0]));
    // the interval is [t, t + duration) to the nearest tick
    assert!(!f[0].active(4.98, 0.02) && f[0].active(4.99, 0.02) && f[0].active(7.48, 0.02));
    assert!(!f[0].active(7.49, 0.02) && f[1].active(1e6, 0.02));
    let bias = |sensor: &str, keys: &str| {
        fault(&format!(
            "sensor = \"{sensor}\"\nt = 1.0\nkind = \"bias\"\n{keys}"
        ))
    };
    for (text, needle) in [
        (
            bias("gyro", "value = [1, 2, 3]").replace("\"gyro\"", "\"magnetometer\""),
            "key `sensors.fault[0].sensor`: the scenario has no sensor \"magnetometer\" (it has \"gyro\", \"direction0\", \"direction1\", \"accelerometer\", \"position\")",
        ),
        (
            bias("direction2", "rotation = [0, 0, 1]"),
            "key `sensors.fault[0].sensor`: the scenario has no sensor \"direction2\"",
        ),
        (
            bias("direction", "rotation = [0, 0, 1]"),
            "key `sensors.fault[0].sensor`: the scenario has no sensor \"direction\"",
        ),
        (
            bias("direction+1", "rotation = [0, 0, 1]"),
            "key `sensors.fault[0].sensor`",
        ),
        (
            bias("direction01", "rotation = [0, 0, 1]"),
            "key `sensors.fault[0].sensor`: the scenario has no sensor \"direction01\"",
        ),
        (
            bias("direction0", "rotation = [0, 0, 3.2]"),
            "key `sensors.fault[0].rotation`: a turn of at most 3.14",
        ),
        (
            bias("direction0", "rotation = [1e200, 0, 0]"),
            "key `sensors.fault[0].rotation`: a turn of at most",
        ),
        (
            bias("gyro", "value = [2e6, 0, 0]"),
            "key `sensors.fault[0].value`: a bias of at most 1000000 in length",
        ),
        (
            bias("gyro", "value = [1, 2, 3]").replace("t = 1.0", "t = -1.0"),
            "key `sensors.fault[0].t`: must be finite and ≥ 0, got -1",
        ),
        (
            bias("gyro", "value = [1, 2, 3]").replace("t = 1.0", "t = nan"),
            "key `sensors.fault[0].t`: must be finite",
        ),
        (
            bias("gyro", "value = [1, 2, 3]\nduration = 0.0"),
            "key `sensors.fault[0].duration`: must be finite and > 0",
        ),
        (
            bias("gyro", "value = [1, 2, 3]\nduration = -2.0"),
            "key `sensors.fault[0].duration`: must be finite and > 0",
        ),
        (
            bias("gyro", "value = [1, 2, 3]\nduration = inf"),
            "key `sensors.fault[0].duration`",
        ),
        (
            bias("gyro", ""),
            "key `sensors.fault[0].value`: a \"bias\" fault on gyro needs `value`",
        ),
        (
            bias("gyro", "value = [1, 2]"),
            "key `sensors.fault[0].value`: expected 3 numbers",
        ),
        (
            bias("position", "value = [1, 2, nan]"),
            "key `sensors.fault[0].value`: entry 2 is not a finite number",
        ),
        (
            bias("gyro", "rotation = [1, 2, 3]"),
            "key `sensors.fault[0].rotation`: a bias on gyro is given as `value`",
        ),
        (
            bias("direction0", "value = [1, 2, 3]"),
            "key `sensors.fault[0].value`: a bias on direction0 is given as `rotation`",
        ),
        (
            bias("direction0", ""),
            "key `sensors.fault[0].rotation`: a \"bias\" fault on direction0 needs `rotation`",
        ),
        (
            bias("gyro", "value = [1, 2, 3]").replace("\"bias\"", "\"dropout\""),
            "key `sensors.fault[0].value`: a \"dropout\" fault takes no `value`",
        ),
        (
            bias("direction0", "rotation = [1, 2, 3]").replace("\"bias\"", "\"stuck\""),
            "key `sensors.fault[0].rotation`: a \"stuck\" fault takes no `rotation`",
        ),
        (
            bias("gyro", "value = [1, 2, 3]").replace("\"bias\"", "\"drift\""),
            "key `sensors.fault[0].kind`: unknown sensor fault kind \"drift\"",
        ),
        (
            bias("gyro", "value = [1, 2, 3]\nscale = 2.0"),
            "unknown field `scale`",
        ),
        (
            bias("gyro", "value = [1, 2, 3]").replace("kind = \"bias\"\n", ""),
            "missing field `kind`",
        ),
        (
            bias("gyro", "value = [1, 2, 3]\nduration = 2.0")
                + "[[sensors.fault]]\nsensor = \"gyro\"\nt = 2.5\nkind = \"dropout\"\n",
            "key `sensors.fault[1].t`: overlaps sensors.fault[0] on the same sensor (gyro)",
        ),
    ] {
        let e = se3_with(&text).unwrap_err();
        assert!(e.contains(needle), "{text}\n{e}");
    }
    // faults that touch end to end, or strike different sensors, do not overlap
    let touching = bias("gyro", "value = [1, 2, 3]\nduration = 2.0")
        + "[[sensors.fault]]\nsensor = \"gyro\"\nt = 3.0\nkind = \"dropout\"\n"
        + "[[sensors.fault]]\nsensor = \"position\"\nt = 2.0\nkind = \"dropout\"\n";
    assert_eq!(
        se3_with(&touching).unwrap().sensors.unwrap().faults.len(),
        3
    );
    // on so3 there is no accelerometer or position fix to strike
    let so3 =
        format!("{SO3}[[sensors.fault]]\nsensor = \"position\"\nt = 1.0\nkind = \"dropout\"\n");
    let e = seed_with(&so3).unwrap_err();
    assert!(
        e.contains("no sensor \"position\" (it has \"gyro\", \"direction0\", \"direction1\")"),
        "{e}"
    );
}

/// `[estimator] gate = true`: its defaults and thresholds from the false-alarm rate, and each
/// bad value refused naming its key.
#[test]
fn the_gate_takes_its_thresholds_from_the_false_alarm_rate_and_bad_keys_name_themselves() {
    let gated = SO3.replace("bias_limit = 0.1", "bias_limit = 0.1\ngate = true");
    let s = seed_with(&gated).unwrap();
    let spec = s.estimator.gate.clone().unwrap();
    assert_eq!(
        (spec.false_alarm_rate, spec.window, spec.noise.clone()),
        (0.01, 0.5, vec![0.01, 0.02])
    );
    let c = s.gate_config().unwrap();
    // α = λh/3600 per sample, and χ²₂'s upper quantile is −2 ln α
    let alpha: f64 = 0.01 * 0.01 / 3600.0;
    assert!(
        (c.direction / (-2.0 * alpha.ln()) - 1.0).abs() < 1e-9,
        "{}",
        c.direction
    );
    assert_eq!((c.window, c.noise[..2].to_vec()), (50, vec![0.01, 0.02]));
    // the fewest rejections a nominal sensor reaches within a sliding window no more than λ
    // an hour: one rejection comes at the gate's own rate, λ, so one is enough
    let rate = |r: u64| 3600.0 / 0.01 * alpha * super::gate::binomial_tail(49, alpha, r - 1);
    assert!((rate(1) / 0.01 - 1.0).abs() < 1e-9 && rate(2) < 1e-6);
    assert_eq!(c.rejections, 1);
    // the complementary filter's directions have no χ² band (no covariance to test) ...
    assert_eq!(c.direction_band.samples, 0);
    // ... the EqF's do: blocks of a window's 50 samples, one test per block, so a block
    // fails with probability λ · 0.5 s / 3600 s; its bound is χ²₁₀₀'s upper quantile there,
    // past the block's mean of 100
    let eqf_text = gated
        .replace("kind = \"complementary\"", "kind = \"eqf\"")
        .replace("kp = 2.0\nki = 0.5\nweights = [1.0, 0.5]\n", "");
    let eqf = seed_with(&eqf_text).unwrap().gate_config().unwrap();
    let block = 0.01 * 0.5 / 3600.0;
    assert_eq!(eqf.direction_band.samples, 50);
    let upper = eqf.direction_band.upper;
    assert!(
        (detection::threshold::chi2_survival(100, upper) / block - 1.0).abs() < 1e-6,
        "{upper}"
    );
    assert!((150.0..250.0).contains(&upper), "{upper}");
    // a looser rate gives a lower threshold
    let loose = seed_with(&gated.replace("gate = true", "gate = true\nfalse_alarm_rate = 1e5"))
        .unwrap()
        .gate_config()
        .unwrap();
    assert!(loose.direction < 3.0 && c.direction > 30.0, "{loose:?}");
    // the complementary filter behind the gate may be given the noise it is tested against
    let noise = gated.replace("gate = true", "gate = true\ndirection_noise = [0.1, 0.2]");
    assert_eq!(
        seed_with(&noise).unwrap().estimator.gate.unwrap().noise,
        vec![0.1, 0.2]
    );
    // SE(3): the accelerometer's noise over g, the window spans two fixes
    let se3 = r#"
[sensors]
directions = [ { world = [1.0, 0.0, 0.0], noise = 0.01 } ]
accelerometer = { noise = 0.0981 }
position = { noise = 0.005, rate_hz = 10.0 }
[estimator]
kind = "eqf"
gate = true
"#;
    let s = se3_with(se3).unwrap();
    assert_eq!(s.estimator.gate.clone().unwrap().noise, vec![0.01, 0.01]);
    // a fix's α is λ/(3600 f)
    let p = crate::sensing::gate::binomial_tail(1, 0.01 / 36000.0, 1);
    assert!(
        (detection::threshold::chi2_survival(3, s.gate_config().unwrap().position) / p - 1.0).abs()
            < 1e-6
    );
    // 10 Hz fixes over a 0.5 s window: the band's block is five fixes (15 degrees)
    let band = s.gate_config().unwrap().position_band;
    assert_eq!(band.samples, 5);
    let block = 0.01 * 5.0 / 36000.0;
    assert!((detection::threshold::chi2_survival(15, band.upper) / block - 1.0).abs() < 1e-6);
    for (text, needle) in [
        (
            gated.replace("gate = true", "false_alarm_rate = 1.0"),
            "key `estimator.false_alarm_rate`: a setting of the innovation gate: give `gate = true`",
        ),
        (
            gated.replace("gate = true", "health_window = 1.0"),
            "key `estimator.health_window`: a setting of the innovation gate",
        ),
        (
            gated.replace("gate = true", "gate = true\nfalse_alarm_rate = 0.0"),
            "key `estimator.false_alarm_rate`: must be finite and > 0",
        ),
        (
            gated.replace("gate = true", "gate = true\nfalse_alarm_rate = -1.0"),
            "key `estimator.false_alarm_rate`: must be finite and > 0",
        ),
        (
            gated.replace("gate = true", "gate = true\nfalse_alarm_rate = inf"),
            "key `estimator.false_alarm_rate`",
        ),
        (
            gated.replace("gate = true", "gate = true\nhealth_window = 0.0"),
            "key `estimator.health_window`: must be finite and at least one control period (0.01 s)",
        ),
        (
            gated.replace("gate = true", "gate = true\nhealth_window = nan"),
            "key `estimator.health_window`",
        ),
        (
            gated.replace("gate = true", "gate = true\nhealth_window = 1e9"),
            "key `estimator.health_window`: must span at most 100000 samples",
        ),
        (
            gated.replace("gate = true", "gate = \"yes\""),
            "invalid type: string \"yes\", expected a boolean",
        ),
        (
            gated.replace("gate = true", "direction_noise = [0.1, 0.2]"),
            "key `estimator.direction_noise`: a key of kind = \"eqf\"",
        ),
        (
            gated.replace("gate = true", "gate = true\ndirection_noise = [0.1]"),
            "key `estimator.direction_noise`: expected 2 numbers",
        ),
        (
            gated.replace("gate = true", "gate = true\ndirection_noise = [0.1, 0.0]"),
            "key `estimator.direction_noise`: each must be > 0 (the gate divides by it)",
        ),
        (
            gated.replace("noise = 0.02 }", "noise = 0.0 }"),
            "key `estimator.direction_noise`: missing, and its default sensors.directions[1].noise is 0: the gate needs",
        ),
        (
            gated.replace("gate = true", "gate = true\nfalse_alarm_rate = 180000"),
            "key `estimator.false_alarm_rate`: must be below 180000 an hour",
        ),
        (
            SO3.replace("kind = \"complementary\"", "kind = \"truth\"\ngate = true")
                .replace(
                    "kp = 2.0\nki = 0.5\nweights = [1.0, 0.5]\nbias_limit = 0.1\n",
                    "",
                ),
            "key `estimator.gate`: kind = \"truth\"",
        ),
    ] {
        let e = seed_with(&text).unwrap_err();
        assert!(e.contains(needle), "{text}\n{e}");
    }
    // with slow fixes the default window spans two of them
    let slow = se3.replace("rate_hz = 10.0", "rate_hz = 2.0");
    assert_eq!(se3_with(&slow).unwrap().estimator.gate.unwrap().window, 1.0);
    let e =
        se3_with(&slow.replace("gate = true", "gate = true\nfalse_alarm_rate = 3600")).unwrap_err();
    assert!(e.contains("must be below 3600 an hour"), "{e}");
    let e = se3_with(&se3.replace("gate = true", "gate = true\nhealth_window = 0.15")).unwrap_err();
    assert!(
        e.contains(
            "key `estimator.health_window`: must span at least two position fixes (0.2 s at 10 Hz)"
        ),
        "{e}"
    );
}
