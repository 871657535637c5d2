//! Failures nobody announces, in the in-process simulation (docs/vehicles.md, "Failures
//! nobody announces"; docs/maths.md, "Failure detection"): `rov_failure` with its thruster's
//! death kept from the controller, found by `[fault_detection]`, flown around; the detector's
//! reconfiguration equal to the same failure announced at its detection time; a dead rotor of
//! the hexarotor on its sensors and EqF found; nominal flights quiet.

use plant::trajectory::{SimulatedTrajectory, simulate};
use plant::vehicle::DetectionReport;
use scenario::Scenario;
use scenario::fault_detection::DEFAULTS;
use scenario::vehicle::{FailureKind, FailureSpec};

fn run(s: &Scenario) -> SimulatedTrajectory {
    simulate(s, &|_| Ok(())).unwrap()
}

fn detections(t: &SimulatedTrajectory) -> Vec<DetectionReport> {
    t.vehicle
        .as_ref()
        .and_then(|v| v.detections.clone())
        .expect("the detector ran")
}

/// `rov_failure` with its failure kept from the controller (`kind`, not told) and the
/// detector on.
fn blind_rov(kind: FailureKind, value: f64) -> Scenario {
    let mut s = pair_tests::load_scenario("rov_failure");
    let f = &mut s.vehicle.as_mut().unwrap().failures[0];
    f.kind = kind;
    f.value = value;
    f.reconfigure = false;
    s.fault_detection = Some(DEFAULTS);
    s
}

#[test]
fn an_unannounced_dead_thruster_is_found_and_flown_around_as_if_announced_then() {
    let s = blind_rov(FailureKind::Dead, 0.0);
    let t_fail = s.vehicle.as_ref().unwrap().failures[0].t;
    let found = run(&s);
    let d = detections(&found);
    assert!(!d.is_empty(), "nothing found");
    let first = &d[0];
    assert_eq!(first.actuator, 5, "{d:?}");
    assert_eq!(first.kind, "dead", "{d:?}");
    let latency = first.latency.expect("a scripted failure");
    assert!(
        (0.0..=0.2).contains(&latency),
        "found {latency} s after it failed"
    );
    assert!(d.iter().all(|x| x.actuator == 5), "{d:?}");
    // back on its reference: within 1e-3 of it in ‖Q_E − I‖ (so 1e-3 rad and 1 mm)
    let end = found.rows.last().unwrap();
    assert!(end.config_error < 1e-3, "ends at {:e}", end.config_error);
    // the healthy run before the failure is the same run to the bit
    let mut healthy = s.clone();
    healthy.vehicle.as_mut().unwrap().failures.clear();
    let h = run(&healthy);
    for (a, b) in found
        .rows
        .iter()
        .zip(&h.rows)
        .take_while(|(a, _)| a.t < t_fail - 1e-9)
    {
        assert_eq!(a.tau, b.tau, "t = {}", a.t);
    }
    assert!(
        detections(&h).is_empty(),
        "the healthy flight raised {:?}",
        detections(&h)
    );

    // unannounced equals announced, later: the same death, told at the detection's tick with
    // the detection's value, allocates the same commands from then on (until any refinement)
    let mut told = s.clone();
    told.fault_detection = None;
    let v = told.vehicle.as_mut().unwrap();
    v.failures.push(FailureSpec {
        actuator: 5,
        t: first.t,
        kind: FailureKind::Stuck,
        value: first.value.unwrap(),
        reconfigure: true,
    });
    let announced = run(&told);
    let until = d.get(1).map_or(f64::INFINITY, |x| x.t);
    let mut compared = 0;
    for (a, b) in found.rows.iter().zip(&announced.rows) {
        if a.t < until - 1e-9 {
            assert_eq!(
                a.vehicle.unwrap().u_cmd,
                b.vehicle.unwrap().u_cmd,
                "t = {}",
                a.t
            );
            compared += usize::from(a.t >= first.t - 1e-9);
        }
    }
    assert!(
        compared > 100,
        "{compared} ticks after the detection compared"
    );
    eprintln!(
        "rov_failure, thruster 5 dead unannounced: found at {:.3} s ({latency:.3} s late), end error {:.2e}; {d:?}",
        first.t, end.config_error
    );
}

#[test]
fn a_stuck_and_a_weak_rov_thruster_are_found_with_their_kind() {
    // thruster 1 (horizontal) stuck at +60 % of its range, and at half its effectiveness,
    // from t = 6 s, while the ROV moves along its waypoints
    for (kind, value) in [
        (FailureKind::Stuck, 24.0),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0),
    ] {
        let mut s = blind_rov(kind, value);
        let f = &mut s.vehicle.as_mut().unwrap().failures[0];
        f.actuator = 1;
        f.t = 6.0;
        s.duration = 12.0;
        let found = run(&s);
        let d = detections(&found);
        assert!(
            !d.is_empty() && d.iter().all(|x| x.actuator == 1),
            "{kind:?}: {d:?}"
        );
        assert!(d[0].latency.unwrap() <= 0.2, "{kind:?}: {d:?}");
        let last = d.last().unwrap();
        match kind {
            FailureKind::Stuck => {
                assert_eq!(last.kind, "stuck", "{d:?}");
                assert!((last.value.unwrap() - 24.0).abs() < 1.0, "{d:?}");
            }
            _ => {
                assert_eq!(last.kind, "effectiveness", "{d:?}");
                assert!((last.factor.unwrap() - 0.5).abs() < 0.1, "{d:?}");
            }
        }
        eprintln!("{kind:?}: {d:?}");
    }
}

#[test]
fn a_dead_hexarotor_rotor_is_found_on_the_boards_sensors_within_a_tenth_of_a_second() {
    let mut s = pair_tests::load_scenario("hexarotor_eqf");
    s.fault_detection = Some(DEFAULTS);
    // nominal: the sensors' noise, the wind, the EqF: nothing found
    let nominal = run(&s);
    assert!(
        detections(&nominal).is_empty(),
        "{:?}",
        detections(&nominal)
    );
    s.vehicle.as_mut().unwrap().failures.push(FailureSpec {
        actuator: 2,
        t: 6.3,
        kind: FailureKind::Dead,
        value: 0.0,
        reconfigure: false,
    });
    let found = run(&s);
    let d = detections(&found);
    assert!(!d.is_empty(), "nothing found");
    assert_eq!(d[0].actuator, 2, "{d:?}");
    assert!(d[0].latency.unwrap() <= 0.1, "{d:?}");
}
