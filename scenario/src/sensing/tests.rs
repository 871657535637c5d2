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
