//! `[estimator]` with `kind = "eqf"`: its defaults, overrides and bad values.

use crate::Scenario;

const SENSORS: &str = r#"
[sensors]
seed = 7
gyro = { noise = 0.002, bias = [0.02, -0.01, 0.03], bias_walk = 1e-5 }
directions = [ { world = [0.0, 0.0, 1.0], noise = 0.01 }, { world = [0.5, 0.0, 0.866], noise = 0.02 } ]
"#;

fn seed_with(estimator: &str) -> Result<Scenario, String> {
    let text = format!(
        "{}\n{SENSORS}\n[estimator]\n{estimator}",
        crate::BUILTINS[0].1
    );
    Scenario::from_toml(&text, "test.toml", "test").map_err(|e| e.to_string())
}

#[test]
fn the_eqf_defaults_to_the_sensors_noise_and_takes_overrides() {
    let s = seed_with("kind = \"eqf\"\n").unwrap();
    let e = s.estimator.eqf.unwrap();
    assert_eq!((e.gyro_noise, e.bias_walk), (0.002, 1e-5));
    assert_eq!(e.direction_noise, vec![0.01, 0.02]);
    assert_eq!((e.initial_attitude_std, e.initial_bias_std), (0.1, 0.03));
    let s = seed_with(
        "kind = \"eqf\"\ngyro_noise = 0.01\nbias_walk = 0.0\ndirection_noise = [0.1, 0.2]\n\
         initial_attitude_std = 2.5\ninitial_bias_std = 0.1\ninitial_attitude = [0.0, 0.0, 2.5]\n",
    )
    .unwrap();
    let e = s.estimator.eqf.as_ref().unwrap();
    assert_eq!((e.gyro_noise, e.bias_walk), (0.01, 0.0));
    assert_eq!(e.direction_noise, vec![0.1, 0.2]);
    assert_eq!((e.initial_attitude_std, e.initial_bias_std), (2.5, 0.1));
    assert_eq!(s.estimator.initial_attitude, Some([0.0, 0.0, 2.5]));
    // the estimator is not the controller's: the fingerprint is the seed's
    assert_eq!(
        s.fingerprint(),
        Scenario::builtin("seed").unwrap().fingerprint()
    );
}

#[test]
fn bad_eqf_values_name_the_key_and_what_is_wrong() {
    for (text, needle) in [
        (
            "kind = \"eqf\"\ngyro_noise = -1.0\n",
            "key `estimator.gyro_noise`: must be a finite number ≥ 0",
        ),
        (
            "kind = \"eqf\"\nbias_walk = nan\n",
            "key `estimator.bias_walk`",
        ),
        (
            "kind = \"eqf\"\ndirection_noise = [0.1]\n",
            "key `estimator.direction_noise`: expected 2 numbers (one per direction)",
        ),
        (
            "kind = \"eqf\"\ndirection_noise = [0.1, 0.0]\n",
            "key `estimator.direction_noise`: each must be > 0",
        ),
        (
            "kind = \"eqf\"\ndirection_noise = [0.1, inf]\n",
            "key `estimator.direction_noise`: entry 1 is not a finite number",
        ),
        (
            "kind = \"eqf\"\ninitial_attitude_std = 0.0\n",
            "key `estimator.initial_attitude_std`: must be a finite number > 0",
        ),
        (
            "kind = \"eqf\"\ninitial_bias_std = -0.1\n",
            "key `estimator.initial_bias_std`",
        ),
        (
            "kind = \"eqf\"\nkp = 1.0\n",
            "key `estimator.kp`: a gain of kind = \"complementary\"",
        ),
        (
            "kind = \"complementary\"\ngyro_noise = 0.01\n",
            "key `estimator.gyro_noise`: a key of kind = \"eqf\"",
        ),
        (
            "kind = \"truth\"\ndirection_noise = [0.1, 0.1]\n",
            "key `estimator.direction_noise`: kind = \"truth\"",
        ),
        (
            "kind = \"eqf\"\ngyro_noise = \"low\"\n",
            "invalid type: string \"low\", expected f64",
        ),
    ] {
        let e = seed_with(text).unwrap_err();
        assert!(e.contains(needle), "{text}: {e}");
    }
    // a noiseless direction sensor has no default: the filter divides by it
    let text = format!(
        "{}\n{}\n[estimator]\nkind = \"eqf\"\n",
        crate::BUILTINS[0].1,
        SENSORS.replace("noise = 0.02", "noise = 0.0")
    );
    let e = Scenario::from_toml(&text, "t.toml", "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("key `estimator.direction_noise`: missing, and its default sensors.directions[1].noise is 0"),
        "{e}"
    );
    // no sensors, no filter
    let text = format!("{}\n[estimator]\nkind = \"eqf\"\n", crate::BUILTINS[0].1);
    let e = Scenario::from_toml(&text, "t.toml", "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("kind = \"eqf\": a filter needs a [sensors] table"),
        "{e}"
    );
}
