//! Vehicles in the in-process simulation (docs/maths.md, "Control allocation", "Vehicle
//! physics"): the tilted-rotor hexarotor's tilted hover and figure-eight, and the ROV losing a
//! thruster with and without reconfiguration.

use plant::output::{Summary, write_trajectory_csv};
use plant::trajectory::{SimulatedTrajectory, simulate};
use scenario::Scenario;

fn scenario(name: &str) -> Scenario {
    pair_tests::load_scenario(name)
}

fn run(s: &Scenario) -> SimulatedTrajectory {
    simulate(s, &|_| Ok(())).unwrap()
}

#[test]
fn the_hexarotor_holds_its_tilted_hover_exactly_and_flies_the_eight_within_its_rotors() {
    let s = scenario("hexarotor_eight");
    let t = run(&s);
    // the first 3 s: rolled by 0.3 rad and still, to rounding
    for r in t.rows.iter().take_while(|r| r.t <= 3.0) {
        assert!(
            r.config_error < 1e-12 && r.momentum_error < 1e-12,
            "t = {}: {:?}",
            r.t,
            r.config_error
        );
    }
    // every row, the last included, carries finite vehicle columns within the rotors' range
    for r in &t.rows {
        let v = r.vehicle.expect("a vehicle row");
        assert_eq!(v.count, 6);
        assert!(
            v.demand
                .iter()
                .chain(&v.achieved)
                .chain(&v.u_cmd)
                .chain(&v.u)
                .all(|x| x.is_finite())
        );
        assert!(
            v.u_cmd[..6].iter().all(|u| (0.0..=8.0).contains(u)),
            "t = {}: {:?}",
            r.t,
            v.u_cmd
        );
        assert_eq!(v.status, 0, "t = {}: the eight stays within reach", r.t);
    }
    let worst = t.rows.iter().map(|r| r.attitude_error).fold(0.0, f64::max);
    assert!(
        worst < 0.15,
        "the eight is tracked: worst attitude error {worst}"
    );
    let last = t.rows.last().unwrap();
    assert!(
        last.config_error < 2e-3,
        "it ends near the last waypoint: {}",
        last.config_error
    );
    let summary = Summary::of(&t, &s.name, "eqt");
    let v = summary.vehicle.unwrap();
    assert_eq!(v.saturated_time_s, vec![0.0; 6]);
    assert!(v.residual.max < 1e-9, "{:?}", v.residual);
}

#[test]
fn the_vehicle_columns_are_written_with_their_names() {
    let mut s = scenario("hexarotor_eight");
    s.duration = 0.01;
    let t = run(&s);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("trajectory.csv");
    write_trajectory_csv(&t, &path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let tail: Vec<String> = (0..6)
        .map(|i| format!("demand_{i}"))
        .chain((0..6).map(|j| format!("u_cmd_{j}")))
        .chain((0..6).map(|j| format!("u_{j}")))
        .chain((0..6).map(|i| format!("achieved_{i}")))
        .chain(["alloc_status".to_owned()])
        .collect();
    assert_eq!(
        header[header.len() - tail.len()..],
        tail.iter().map(String::as_str).collect::<Vec<_>>()[..]
    );
    assert_eq!(text.lines().count(), 1 + 6);
}

/// The ROV's configuration error just before the failure and at the end.
fn before_and_after(s: &Scenario) -> (f64, f64, SimulatedTrajectory) {
    before_and_after_at(s, s.vehicle.as_ref().unwrap().failures[0].t)
}

#[test]
fn losing_a_thruster_with_reconfiguration_recovers_and_without_it_does_not() {
    let s = scenario("rov_failure");
    let (before, after, t) = before_and_after(&s);
    // the failed thruster is stuck at 0 from its time on, and the allocator commands it so
    let failure = s.vehicle.as_ref().unwrap().failures[0];
    for r in t.rows.iter().filter(|r| r.t >= failure.t - 0.005) {
        let v = r.vehicle.unwrap();
        assert_eq!(
            (v.u[failure.actuator], v.u_cmd[failure.actuator]),
            (0.0, 0.0),
            "t = {}",
            r.t
        );
    }
    assert!(
        after < 1e-3 && after <= before,
        "reconfigured: error {after} at the end, {before} before the failure"
    );
    let mut blind = s.clone();
    blind.vehicle.as_mut().unwrap().failures[0].reconfigure = false;
    let (blind_before, blind_after, _) = before_and_after(&blind);
    assert_eq!(blind_before, before, "the same run up to the failure");
    assert!(
        blind_after > 50.0 * after && blind_after > 0.05,
        "not reconfigured: error {blind_after} at the end (reconfigured: {after})"
    );
    eprintln!(
        "rov_failure: error before the failure {before:.3e}; at the end {after:.3e} reconfigured, {blind_after:.3e} not"
    );
}

/// The failure kinds in the plant (issue "Actuator failures found, not announced", part 1): a
/// dead thruster is one stuck at 0, byte for byte; a loss of effectiveness leaves the thruster
/// following its command and produces `factor` times its output, so the unannounced ROV drifts
/// less than with the thruster dead, and more than healthy.
#[test]
fn a_dead_thruster_is_stuck_at_zero_and_a_weak_one_produces_its_factor() {
    use scenario::vehicle::FailureKind;
    let s = scenario("rov_failure");
    let dir = std::env::temp_dir().join(format!("eqtrack-failure-kinds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = |t: &SimulatedTrajectory| {
        let path = dir.join("trajectory.csv");
        write_trajectory_csv(t, &path).unwrap();
        std::fs::read(&path).unwrap()
    };
    let (_, stuck_after, stuck) = before_and_after(&s);
    let mut dead = s.clone();
    dead.vehicle.as_mut().unwrap().failures[0].kind = FailureKind::Dead;
    let (_, dead_after, dead_run) = before_and_after(&dead);
    assert_eq!(
        csv(&dead_run),
        csv(&stuck),
        "dead is stuck at 0, byte for byte"
    );
    assert_eq!(dead_after, stuck_after);

    let blind = |kind: FailureKind| {
        let mut b = s.clone();
        let f = &mut b.vehicle.as_mut().unwrap().failures[0];
        f.kind = kind;
        f.reconfigure = false;
        before_and_after(&b)
    };
    let (_, dead_blind, _) = blind(FailureKind::Dead);
    let (_, weak_blind, weak) = blind(FailureKind::Effectiveness { factor: 0.5 });
    let mut healthy = s.clone();
    healthy.vehicle.as_mut().unwrap().failures.clear();
    let (_, healthy_after, _) =
        before_and_after_at(&healthy, s.vehicle.as_ref().unwrap().failures[0].t);
    assert!(
        healthy_after < weak_blind && weak_blind < dead_blind,
        "healthy {healthy_after:.3e} < half as effective {weak_blind:.3e} < dead {dead_blind:.3e}"
    );
    // told, the allocator scales the weak thruster's column and the ROV recovers
    let mut told = s.clone();
    told.vehicle.as_mut().unwrap().failures[0].kind = FailureKind::Effectiveness { factor: 0.5 };
    let (_, weak_told, _) = before_and_after(&told);
    assert!(
        weak_told < 0.1 * weak_blind && weak_told < 1e-3,
        "half as effective, told {weak_told:.3e}, blind {weak_blind:.3e}"
    );
    // the weak thruster follows its command, and produces half of its output
    let j = s.vehicle.as_ref().unwrap().failures[0].actuator;
    let t_fail = s.vehicle.as_ref().unwrap().failures[0].t;
    let late: Vec<_> = weak.rows.iter().filter(|r| r.t > t_fail + 1.0).collect();
    assert!(
        late.iter()
            .any(|r| r.vehicle.unwrap().u_cmd[j].abs() > 1e-3)
    );
    let tau = s.vehicle.as_ref().unwrap().actuator_time_constant;
    assert!(tau > 0.0);
    for r in &late {
        let v = r.vehicle.unwrap();
        assert!(
            v.u[j].abs() <= 0.5 * 40.0 + 1e-12,
            "t = {}: {}",
            r.t,
            v.u[j]
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "rov_failure unannounced: at the end, healthy {healthy_after:.3e}, half as effective {weak_blind:.3e} (told {weak_told:.3e}), dead {dead_blind:.3e}"
    );
}

/// The configuration error just before `t` and at the end.
fn before_and_after_at(s: &Scenario, t_fail: f64) -> (f64, f64, SimulatedTrajectory) {
    let t = run(s);
    let before = t
        .rows
        .iter()
        .rev()
        .find(|r| r.t < t_fail)
        .unwrap()
        .config_error;
    (before, t.rows.last().unwrap().config_error, t)
}
