//! `[vehicle]` and `[allocation]`: bad tables are refused naming the key and what is wrong.

use scenario::Scenario;

fn rov_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/rov_failure.toml"
    ))
    .unwrap()
}

fn hexarotor_text() -> String {
    std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/hexarotor_eight.toml"
    ))
    .unwrap()
    .replace(
        "waypoints = \"hexarotor_eight.csv\"\npath = \"through\"",
        "setpoint = { rotation = [0.3, 0.0, 0.0] }",
    )
}

/// The error a text gives, which must exist.
fn error(text: &str) -> String {
    match Scenario::from_toml(text, "test", "test") {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

fn refused(text: &str, key: &str, what: &str) {
    let e = error(text);
    assert!(
        e.contains(&format!("key `{key}`")),
        "{e} does not name {key}"
    );
    assert!(e.contains(what), "{e} does not say {what}");
}

#[test]
fn the_vehicle_scenarios_load_and_the_model_inertia_defaults_to_the_total() {
    let rov = Scenario::from_toml(
        &rov_text().replace(
            "waypoints = \"rov_failure.csv\"",
            "setpoint = { rotation = [0.0, 0.0, 0.0] }",
        ),
        "rov",
        "rov",
    )
    .unwrap();
    let v = rov.vehicle.as_ref().unwrap();
    assert_eq!((v.actuators.len(), v.failures.len(), v.mass), (8, 1, 11.5));
    // the rigid body's 11.5 kg plus the added 5.5 kg along x
    assert_eq!(rov.model_inertia[3 * 6 + 3], 17.0);
    assert_eq!(rov.total_inertia()[5 * 6 + 5], 11.5 + 14.6);
    assert_eq!(rov.plant_inertia[3 * 6 + 3], 11.5);
    let hex = Scenario::from_toml(&hexarotor_text(), "hex", "hex").unwrap();
    assert_eq!(hex.model_inertia, hex.plant_inertia);
    // the vehicle is in the fingerprint; a scenario without one keeps its own
    let mut other = hex.clone();
    other.vehicle.as_mut().unwrap().actuators[0].max = 9.0;
    assert_ne!(other.fingerprint(), hex.fingerprint());
    let mut plain = hex.clone();
    plain.vehicle = None;
    assert_ne!(plain.fingerprint(), hex.fingerprint());
}

#[test]
fn bad_actuators_are_refused_naming_the_key() {
    let hex = hexarotor_text();
    // an untilted hexarotor: no sideways force
    let flat = hex
        .replace("0.479425538604", "0.0")
        .replace("0.415194695654", "0.0")
        .replace("-0.239712769302", "0.0")
        .replace("-0.415194695654", "0.0")
        .replace("0.239712769302", "0.0")
        .replace("-0.479425538604", "0.0");
    let e = error(&flat);
    assert!(
        e.contains("key `vehicle.actuator`")
            && e.contains("cannot produce every wrench")
            && e.contains("fx"),
        "{e}"
    );
    refused(
        &hex.replacen("min = 0.0\nmax = 8.0", "min = 9.0\nmax = 8.0", 1),
        "vehicle.actuator[0].min",
        "is above `max`",
    );
    refused(
        &hex.replacen(
            "axis = [0.0, 0.479425538604, 0.87758256189]",
            "axis = [0.0, 0.0, 0.0]",
            1,
        ),
        "vehicle.actuator[0].axis",
        "is zero",
    );
    refused(
        &hex.replacen(
            "position = [0.25, 0.0, 0.0]",
            "position = [nan, 0.0, 0.0]",
            1,
        ),
        "vehicle.actuator[0].position",
        "not a finite number",
    );
    refused(
        &hex.replacen(
            "axis = [0.0, 0.479425538604, 0.87758256189]",
            "axis = [0.0, 0.48]",
            1,
        ),
        "vehicle.actuator[0].axis",
        "expected 3 numbers",
    );
    let table = "\n[[vehicle.actuator]]\nposition = [0.0, 0.0, 0.0]\naxis = [0.0, 0.0, 1.0]\nmin = 0.0\nmax = 1.0\n";
    refused(
        &format!("{hex}{}", table.repeat(7)),
        "vehicle.actuator",
        "13 actuators: a vehicle has 1 to 12",
    );
}

#[test]
fn bad_vehicle_and_allocation_keys_are_refused_naming_the_key() {
    let rov = rov_text();
    refused(
        &rov.replace("actuator = 5\n", "actuator = 8\n"),
        "vehicle.failure[0].actuator",
        "no actuator 8 (the vehicle has 8",
    );
    refused(
        &rov.replace("actuator = 5\n", "actuator = -1\n"),
        "vehicle.failure[0].actuator",
        "no actuator -1",
    );
    refused(
        &rov.replace("t = 20.0\n", "t = -1.0\n"),
        "vehicle.failure[0].t",
        "must be finite and ≥ 0",
    );
    refused(
        &rov.replace("gravity = 9.81", "gravity = -9.81"),
        "vehicle.gravity",
        "≥ 0",
    );
    refused(
        &rov.replace("buoyancy = 114.8", "buoyancy = inf"),
        "vehicle.buoyancy",
        "≥ 0",
    );
    refused(
        &rov.replace("gravity = 9.81", "gravity = 1e308"),
        "vehicle.gravity",
        "is not a finite number",
    );
    refused(
        &rov.replace(
            "buoyancy_centre = [0.0, 0.0, 0.02]",
            "buoyancy_centre = [0.0, 0.0, 1e307]",
        ),
        "vehicle.buoyancy_centre",
        "not a finite number",
    );
    refused(
        &rov.replace("damping_linear = [0.5,", "damping_linear = [-0.5,"),
        "vehicle.damping_linear",
        "entry 0 is negative",
    );
    refused(
        &rov.replace(
            "damping_quadratic = [0.5, 0.5, 0.5, 18.0, 21.0, 37.0]",
            "damping_quadratic = [0.5]",
        ),
        "vehicle.damping_quadratic",
        "expected 6 numbers",
    );
    refused(
        &rov.replace(
            "  [0.12, 0.0, 0.0, 0.0, 0.0, 0.0],",
            "  [0.12, 0.3, 0.0, 0.0, 0.0, 0.0],",
        ),
        "vehicle.added_mass",
        "must be symmetric",
    );
    refused(
        &rov.replace(
            "  [0.0, 0.0, 0.0, 5.5, 0.0, 0.0],",
            "  [0.0, 0.0, 0.0, -40.0, 0.0, 0.0],",
        ),
        "vehicle.added_mass",
        "not positive definite",
    );
    refused(
        &rov.replace(
            "actuator_time_constant = 0.05",
            "actuator_time_constant = -0.05",
        ),
        "vehicle.actuator_time_constant",
        "≥ 0",
    );
    // gravity needs a mass: m·1₃ and no coupling
    refused(
        &rov.replace(
            "  [0.0, 0.0, 0.0, 0.0, 11.5, 0.0],",
            "  [0.0, 0.0, 0.0, 0.0, 12.5, 0.0],",
        ),
        "plant.inertia",
        "force block must be m·1₃",
    );
    let alloc = "\n[allocation]\nweights = [1.0, 1.0]\n";
    refused(
        &format!("{rov}{alloc}"),
        "allocation.weights",
        "expected 8 numbers (one per actuator)",
    );
    refused(
        &format!("{rov}\n[allocation]\nweights = [1.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0]\n"),
        "allocation.weights",
        "entry 3 must be positive",
    );
    refused(
        &format!("{rov}\n[allocation]\npriority = \"force\"\n"),
        "allocation.priority",
        "unknown priority `force`",
    );
    for (value, what) in [
        ("0", "from 1 to 1000, got 0"),
        ("-3", "from 1 to 1000, got -3"),
        ("1001", "from 1 to 1000, got 1001"),
    ] {
        refused(
            &format!("{rov}\n[allocation]\nbudget = {value}\n"),
            "allocation.budget",
            what,
        );
    }
    for value in ["2.5", "\"36\"", "true"] {
        let e = error(&format!("{rov}\n[allocation]\nbudget = {value}\n"));
        assert!(
            e.contains("budget") || e.contains("invalid type"),
            "{value}: {e}"
        );
    }
    // accepted: it reaches the allocator, and the fingerprint only when not the default
    let set = rov.replace(
        "waypoints = \"rov_failure.csv\"",
        "setpoint = { rotation = [0.0, 0.0, 0.0] }",
    );
    let fingerprint = |text: &str| Scenario::from_toml(text, "b", "b").unwrap().fingerprint();
    let with = |b: &str| format!("{set}\n[allocation]\nbudget = {b}\n");
    let s = Scenario::from_toml(&with("3"), "b", "b").unwrap();
    assert_eq!(s.vehicle.as_ref().unwrap().budget, 3);
    assert_eq!(
        s.vehicle
            .as_ref()
            .unwrap()
            .allocator::<6>()
            .unwrap()
            .budget(),
        3
    );
    assert_eq!(fingerprint(&with("36")), fingerprint(&set));
    assert_ne!(fingerprint(&with("3")), fingerprint(&set));
    let bare = rov[..rov.find("[vehicle]").unwrap()].to_owned();
    refused(
        &format!("{bare}\n[allocation]\npriority = \"none\"\n"),
        "allocation",
        "needs a [vehicle]",
    );
    let e = error(&rov.replace("reconfigure = true", "reconfigure = true\nstuck = 1"));
    assert!(e.contains("unknown field `stuck`"), "{e}");
}

#[test]
fn gravity_on_so3_is_refused() {
    let seed = scenario::BUILTINS[0].1;
    let text = format!(
        "{seed}\n[vehicle]\ngravity = 9.81\n[[vehicle.actuator]]\nposition = [1.0, 0.0, 0.0]\naxis = [0.0, 1.0, 0.0]\nmin = -1.0\nmax = 1.0\n"
    );
    refused(&text, "vehicle.gravity", "an SO(3) body has no position");
}

/// `[[vehicle.failure]] kind` and the keys each kind takes (issue "Actuator failures found,
/// not announced", part 1): each bad one refused naming the key.
#[test]
fn failure_kinds_and_their_keys_are_checked() {
    let rov = rov_text().replace(
        "waypoints = \"rov_failure.csv\"",
        "setpoint = { rotation = [0.0, 0.0, 0.0] }",
    );
    let with = |keys: &str| {
        rov.replace(
            "t = 20.0\nvalue = 0.0\nreconfigure = true\n",
            &format!("t = 20.0\n{keys}\n"),
        )
    };
    let kinds = |text: &str| {
        let s = Scenario::from_toml(text, "rov", "rov").unwrap();
        let f = s.vehicle.as_ref().unwrap().failures[0];
        (f.kind, f.value, f.reconfigure)
    };
    use scenario::vehicle::FailureKind;
    // the default is today's stuck failure, and the kinds that are accepted
    assert_eq!(kinds(&rov), (FailureKind::Stuck, 0.0, true));
    assert_eq!(
        kinds(&with("kind = \"stuck\"\nvalue = 24.0")),
        (FailureKind::Stuck, 24.0, true)
    );
    assert_eq!(
        kinds(&with("kind = \"dead\"")),
        (FailureKind::Dead, 0.0, true)
    );
    assert_eq!(
        kinds(&with(
            "kind = \"effectiveness\"\nfactor = 0.5\nreconfigure = false"
        )),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0, false)
    );
    refused(
        &with("kind = \"leaking\""),
        "vehicle.failure[0].kind",
        "unknown failure kind \"leaking\"",
    );
    refused(
        &with("value = 40.5"),
        "vehicle.failure[0].value",
        "outside the actuator's range [-40, 40]",
    );
    refused(
        &with("kind = \"stuck\"\nvalue = nan"),
        "vehicle.failure[0].value",
        "not a finite number",
    );
    refused(
        &with("kind = \"stuck\"\nfactor = 0.5"),
        "vehicle.failure[0].factor",
        "a \"stuck\" failure takes no `factor`",
    );
    refused(
        &with("kind = \"dead\"\nvalue = 0.0"),
        "vehicle.failure[0].value",
        "a \"dead\" failure takes no `value`",
    );
    refused(
        &with("kind = \"dead\"\nfactor = 0.5"),
        "vehicle.failure[0].factor",
        "takes no `factor`",
    );
    for bad in ["0.0", "1.0", "-0.5", "1.5", "nan", "inf"] {
        refused(
            &with(&format!(
                "kind = \"effectiveness\"\nfactor = {bad}\nreconfigure = false"
            )),
            "vehicle.failure[0].factor",
            "must be in (0, 1)",
        );
    }
    refused(
        &with("kind = \"effectiveness\"\nreconfigure = false"),
        "vehicle.failure[0].factor",
        "needs a `factor` in (0, 1)",
    );
    refused(
        &with("kind = \"effectiveness\"\nfactor = 0.5\nvalue = 1.0\nreconfigure = false"),
        "vehicle.failure[0].value",
        "takes no `value`",
    );
    // a loss of effectiveness may be told (the allocator scales its column): a told one is
    // fingerprinted with its factor, a blind one as before
    let told = |text: &str| Scenario::from_toml(text, "rov", "rov").unwrap();
    let half = told(&with("kind = \"effectiveness\"\nfactor = 0.5"));
    assert_eq!(
        kinds(&with("kind = \"effectiveness\"\nfactor = 0.5")),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0, true)
    );
    let other = told(&with("kind = \"effectiveness\"\nfactor = 0.6"));
    assert_ne!(half.fingerprint(), other.fingerprint());
    let blind = |f: &str| {
        told(&with(&format!(
            "kind = \"effectiveness\"\nfactor = {f}\nreconfigure = false"
        )))
        .fingerprint()
    };
    assert_eq!(blind("0.5"), blind("0.6"), "the controller does not see it");
    assert_ne!(half.fingerprint(), blind("0.5"));
    // the processor-in-the-loop firmware is not told a loss of effectiveness: refused, named
    let e = half.firmware_config().unwrap_err().to_string();
    assert!(
        e.contains("vehicle.failure.reconfigure") && e.contains("actuator 5"),
        "{e}"
    );
    // (this one is refused for its set-point reference, not for the failure)
    let blind_config = told(&with(
        "kind = \"effectiveness\"\nfactor = 0.5\nreconfigure = false",
    ))
    .firmware_config();
    if let Err(e) = blind_config {
        assert!(!e.to_string().contains("vehicle.failure"), "{e}");
    }
    // a kind that is not a string: the parser's type error, which names the line
    let e = error(&with("kind = 3"));
    assert!(e.contains("invalid type"), "{e}");
}

/// `[fault_detection]` (issue "Actuator failures found, not announced"): an empty table is the
/// design's defaults; every key's bad value is refused naming it; it needs a vehicle; it is
/// fingerprinted only when on; the processor-in-the-loop firmware carries it in `f32`.
#[test]
fn fault_detection_keys_are_checked() {
    use scenario::fault_detection::DEFAULTS;
    let rov = rov_text().replace(
        "waypoints = \"rov_failure.csv\"",
        "setpoint = { rotation = [0.0, 0.0, 0.0] }",
    );
    let with = |keys: &str| format!("{rov}\n[fault_detection]\n{keys}\n");
    let load = |text: &str| Scenario::from_toml(text, "rov", "rov").unwrap();
    let off = load(&rov);
    assert_eq!(off.fault_detection, None, "off by default");
    let on = load(&with(""));
    assert_eq!(on.fault_detection, Some(DEFAULTS));
    assert_ne!(on.fingerprint(), off.fingerprint());
    assert_ne!(load(&with("window = 0.2")).fingerprint(), on.fingerprint());
    let c = on.detector_config::<6>().unwrap();
    assert_eq!(
        (c.decimation, c.window, c.confirm, c.calibration),
        (1, 10, 5, 200)
    );
    // 1e-3 false alarms an hour over 360 000 tests an hour and 8 hypotheses: χ²₁ at 3.5e-10
    use detection::threshold::{chi2_upper, per_test};
    assert_eq!(c.threshold, chi2_upper(1, per_test(1e-3, 0.01, 8)));
    assert!(c.threshold > 35.0 && c.threshold < 45.0, "{}", c.threshold);
    assert!(off.detector_config::<6>().is_none());
    for (keys, key, what) in [
        ("window = 0.0", "window", "finite and positive"),
        ("window = -0.1", "window", "finite and positive"),
        ("window = nan", "window", "finite and positive"),
        ("window = 0.001", "window", "at least one period"),
        ("window = 100.0", "window", "at most 60 s"),
        (
            "false_alarm_rate = 0.0",
            "false_alarm_rate",
            "finite and positive",
        ),
        (
            "false_alarm_rate = inf",
            "false_alarm_rate",
            "finite and positive",
        ),
        (
            "false_alarm_rate = 1e9",
            "false_alarm_rate",
            "chance of half or more",
        ),
        (
            "calibration = 0.1",
            "calibration",
            "shorter than two windows",
        ),
        ("warmup = -1.0", "warmup", "finite and ≥ 0"),
        ("model_error = 1.0", "model_error", "in [0, 1)"),
        (
            "false_alarm_rate = 2e6",
            "false_alarm_rate",
            "chance of half or more",
        ),
        ("model_error = -0.1", "model_error", "in [0, 1)"),
        ("warmup = inf", "warmup", "finite and ≥ 0"),
        ("memory = 0.001", "memory", "shorter than a control period"),
        ("floor = 0.0", "floor", "finite and positive"),
        ("floor = 1.0", "floor", "below 1"),
        ("confirm = 0.5", "confirm", "1 to the window's 10"),
        ("confirm = 0.001", "confirm", "1 to the window's 10"),
        (
            "unexplained = 0.7",
            "unexplained",
            "probability in (0, 0.5)",
        ),
        ("ambiguity = 0.0", "ambiguity", "probability in (0, 0.5)"),
    ] {
        refused(&with(keys), &format!("fault_detection.{key}"), what);
    }
    // a model error of 0 is a detector trusting its model exactly: accepted, and it builds
    let exact = load(&with("model_error = 0.0"));
    assert_eq!(exact.detector_config::<6>().unwrap().relative, 0.0);
    assert!(detection::Detector::new(exact.detector_config::<6>().unwrap()).is_ok());
    // a window of a single period takes the default confirmation (one period) without a word
    let one = load(&with("window = 0.006\ncalibration = 0.5"));
    assert_eq!(one.detector_config::<6>().unwrap().confirm, 1);
    // a long window averages periods into entries; the rate is checked per test
    let long = load(&with("window = 60.0\ncalibration = 120.0"));
    let c = long.detector_config::<6>().unwrap();
    assert!(
        c.decimation > 1 && 2 * c.window <= detection::CAPACITY,
        "{c:?}"
    );
    assert!(detection::Detector::new(c).is_ok());
    refused(
        &with("window = 60.0\ncalibration = 120.0\nfalse_alarm_rate = 2e4"),
        "fault_detection.false_alarm_rate",
        "chance of half or more",
    );
    let e = error(&with("threshold = 3.0"));
    assert!(e.contains("unknown field `threshold`"), "{e}");
    // no vehicle: nothing to watch
    let seed = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/seed.toml"
    ))
    .unwrap();
    refused(
        &format!("{seed}\n[fault_detection]\n"),
        "fault_detection",
        "needs a [vehicle]",
    );
    // the processor-in-the-loop firmware runs it (with a reference it integrates on board):
    // the host's settings cast to f32, and a cycle made from them; without the table, none
    let flown = |text: &str| {
        load(&text.replace(
            "setpoint = { rotation = [0.0, 0.0, 0.0] }",
            "rotation = [0.0, 0.0, 0.0]\nposition = [0.0, 0.0, 0.0]\nvelocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
        ))
    };
    let firmware = flown(&with("")).firmware_config().unwrap();
    let d = firmware.detector.clone().unwrap();
    let c = on.detector_config::<6>().unwrap();
    assert_eq!(d, firmware_cycle::Detector::of(&c, 8));
    assert_eq!(
        (d.decimation, d.window, d.confirm, d.resolution.len()),
        (1, 10, 5, 8)
    );
    assert_eq!(d.threshold, c.threshold as f32);
    assert!(firmware_cycle::Cycle::new(&firmware).is_ok());
    assert_eq!(flown(&rov).firmware_config().unwrap().detector, None);
    // settings the firmware's detector refuses, and a detector without a vehicle
    let mut bad = firmware.clone();
    bad.detector.as_mut().unwrap().window = 0;
    assert!(matches!(
        firmware_cycle::Cycle::new(&bad),
        Err(firmware_cycle::ConfigError::Detector(
            detection::ConfigError::Window
        ))
    ));
    let mut short = firmware.clone();
    short.detector.as_mut().unwrap().floor.pop();
    let e = firmware_cycle::Cycle::new(&short)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("detector.floor: 5 entries"), "{e}");
    let mut lonely = firmware;
    lonely.vehicle = None;
    assert!(matches!(
        firmware_cycle::Cycle::new(&lonely),
        Err(firmware_cycle::ConfigError::DetectorWithoutVehicle)
    ));
}

#[test]
fn the_tilt_priority_is_read_fingerprinted_and_refused_by_the_firmware() {
    let text = std::fs::read_to_string(pair_tests::scenario("pil_hexarotor")).unwrap();
    let load = |extra: &str| {
        let base = pair_tests::repo("scenarios");
        Scenario::from_toml_in(&format!("{text}\n{extra}"), "p", "p", Some(base.as_ref())).unwrap()
    };
    let (torque, tilt) = (load(""), load("[allocation]\npriority = \"tilt\"\n"));
    assert_eq!(
        tilt.vehicle.as_ref().unwrap().priority,
        eqtrack_allocation::Priority::Tilt
    );
    assert_ne!(torque.fingerprint(), tilt.fingerprint());
    assert!(torque.firmware_config().is_ok());
    let e = tilt.firmware_config().unwrap_err().to_string();
    assert!(
        e.contains("allocation.priority") && e.contains("tilt"),
        "{e}"
    );
    let e = error(&format!("{text}\n[allocation]\npriority = \"yaw\"\n"));
    assert!(e.contains("expected torque, tilt or none"), "{e}");
}
