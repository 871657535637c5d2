//! Failures nobody announces, in the in-process simulation
//! (docs/vehicles.md, "Failures nobody announces"; docs/maths.md, "Failure detection"): `rov_failure` with its thruster's
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

/// [`blind_rov`] in calm water with its model trusted to 0.1 % (`floor = 0.001`): the
/// simulation's state is exact and nothing unknown pushes the ROV, so its residual is that
/// accurate, and the thruster that dies while holding it down with half a newton is seen.
fn calm_rov(kind: FailureKind, value: f64) -> Scenario {
    let mut s = blind_rov(kind, value);
    s.fault_detection = Some(scenario::fault_detection::FaultDetectionSpec {
        floor: 0.001,
        ..DEFAULTS
    });
    s
}

#[test]
fn an_unannounced_dead_thruster_is_found_and_flown_around_as_if_announced_then() {
    let s = calm_rov(FailureKind::Dead, 0.0);
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
    // the detector changes nothing until it detects: the same flight without it is the
    // same run to the bit up to the detection's tick
    let mut off = s.clone();
    off.fault_detection = None;
    let o = run(&off);
    let mut same = 0;
    for (a, b) in found
        .rows
        .iter()
        .zip(&o.rows)
        .take_while(|(a, _)| a.t < first.t - 1e-9)
    {
        assert_eq!(a.tau, b.tau, "t = {}", a.t);
        assert_eq!(
            a.vehicle.unwrap().u_cmd,
            b.vehicle.unwrap().u_cmd,
            "t = {}",
            a.t
        );
        same += 1;
    }
    assert!(same > 1900, "{same} ticks compared");
    // and the healthy flight raises nothing
    let mut healthy = s.clone();
    healthy.vehicle.as_mut().unwrap().failures.clear();
    let h = run(&healthy);
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
fn two_rov_thrusters_failing_one_after_the_other_are_found_in_turn() {
    // in a current that loads the thrusters: thruster 1 dies at 6.3 s, thruster 6 sticks at
    // -20 N at 9.1 s, neither announced; both found, in order, on the right thrusters, and the
    // ROV flown on the six left
    let mut s = blind_rov(FailureKind::Dead, 0.0);
    s.disturbance_world = Some(vec![0.0, 0.0, 0.0, 15.0, 8.0, -10.0]);
    s.duration = 16.0;
    let v = s.vehicle.as_mut().unwrap();
    v.failures[0].actuator = 1;
    v.failures[0].t = 6.3;
    v.failures.push(FailureSpec {
        actuator: 6,
        t: 9.1,
        kind: FailureKind::Stuck,
        value: -20.0,
        reconfigure: false,
    });
    let t = run(&s);
    let d: Vec<_> = detections(&t).into_iter().filter(|x| !x.refined).collect();
    let named: Vec<_> = d.iter().map(|x| (x.actuator, x.kind)).collect();
    assert_eq!(named, vec![(1, "dead"), (6, "stuck")], "{d:?}");
    assert!(
        d.iter()
            .all(|x| x.latency.is_some_and(|l| (0.0..=0.2).contains(&l))),
        "{d:?}"
    );
    assert!((d[1].value.unwrap() + 20.0).abs() < 1.0, "{d:?}");
    // flown as well as the healthy ROV in the same current (which the law, without an
    // integral term, holds a long way off its reference: ‖Q_E − I‖ near 1)
    let mut healthy = s.clone();
    healthy.vehicle.as_mut().unwrap().failures.clear();
    let (end, nominal) = (
        t.rows.last().unwrap().config_error,
        run(&healthy).rows.last().unwrap().config_error,
    );
    assert!(
        end < 1.5 * nominal + 1e-3,
        "ends at {end:e}, healthy {nominal:e}"
    );
    eprintln!("two failures in turn: {d:?}; ends at {end:.3e} (healthy {nominal:.3e})");
}

#[test]
fn a_stuck_and_a_weak_rov_thruster_are_found_with_their_kind() {
    // thruster 1 (horizontal) stuck at +60 % of its range, and at half its effectiveness,
    // from t = 6 s, while the ROV moves along its waypoints
    for (kind, value) in [
        (FailureKind::Stuck, 24.0),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0),
    ] {
        let mut s = calm_rov(kind, value);
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

/// `hexarotor_eqf` in hover: its sensors, EqF, wind and observer, holding the start's
/// position level (a set-point) instead of flying the eight.
fn hovering_hexarotor() -> Scenario {
    let text = std::fs::read_to_string(pair_tests::scenario("hexarotor_eqf")).unwrap();
    let eight = "waypoints = \"hexarotor_eight.csv\"\npath = \"through\"\n";
    assert!(text.contains(eight), "hexarotor_eqf's reference changed");
    let text = text.replace(
        eight,
        "setpoint = { rotation = [0.0, 0.0, 0.0], position = [0.0, 0.0, 0.0] }\n",
    );
    Scenario::from_toml(
        &text,
        "hexarotor_hover",
        "scenarios/hexarotor_eqf.toml, in hover",
    )
    .unwrap()
}

#[test]
fn a_dead_hexarotor_rotor_is_found_on_the_boards_sensors_within_a_tenth_of_a_second() {
    let mut s = hovering_hexarotor();
    s.fault_detection = Some(DEFAULTS);
    // nominal: the sensors' noise, the wind, the EqF: nothing found
    let nominal = run(&s);
    assert!(
        detections(&nominal).is_empty(),
        "{:?}",
        detections(&nominal)
    );
    // each rotor in turn dies at a random time after the detector's calibration (5 to 9 s),
    // each flight with its own sensor noise: found on the right rotor, 95 % within 0.1 s
    let n = runs(6);
    let mut late = Vec::new();
    for i in 0..n {
        let mut f = s.clone();
        f.sensors.as_mut().unwrap().seed = 500 + i as u64;
        let (j, at) = (
            i % 6,
            (500.0 * (5.0 + 4.0 * uniform(66, i as u64))).round() / 500.0,
        );
        f.vehicle.as_mut().unwrap().failures.push(FailureSpec {
            actuator: j,
            t: at,
            kind: FailureKind::Dead,
            value: 0.0,
            reconfigure: false,
        });
        let d = detections(&run(&f));
        assert!(!d.is_empty(), "rotor {j} dead at {at}: nothing found");
        assert_eq!(d[0].actuator, j, "rotor {j} dead at {at}: {d:?}");
        assert!(d[0].t >= at, "rotor {j}: found before it died: {d:?}");
        late.push(d[0].latency.unwrap());
    }
    late.sort_by(f64::total_cmp);
    let p95 = late[((0.95 * n as f64).ceil() as usize).saturating_sub(1)];
    eprintln!(
        "hexarotor in hover, a rotor dead: {n} flights, all on the right rotor, latency median {:.3} s, 95 % {p95:.3} s, worst {:.3} s; histogram (10 ms bins from 0) {:?}",
        late[n / 2],
        late[n - 1],
        histogram(&late)
    );
    assert!(p95 <= 0.1, "{late:?}");
}

/// Counts per 10 ms bin from 0 up to the largest (the latency histograms of
/// docs/vehicles.md).
fn histogram(latencies: &[f64]) -> Vec<usize> {
    let bin = |x: f64| (x / 0.01 + 1e-9).floor().max(0.0) as usize;
    let mut counts = vec![0; latencies.iter().map(|x| bin(*x) + 1).max().unwrap_or(0)];
    for x in latencies {
        counts[bin(*x)] += 1;
    }
    counts
}

/// Runs per study: a few in the test suite, more with `EQTRACK_DETECTION_RUNS` (the figures
/// in BENCHMARKS come from 200).
fn runs(default: usize) -> usize {
    std::env::var("EQTRACK_DETECTION_RUNS")
        .ok()
        .and_then(|x| x.parse().ok())
        .unwrap_or(default)
}

/// A seeded uniform number in [0, 1) (SplitMix64), so the studies need no generator crate.
fn uniform(seed: u64, i: u64) -> f64 {
    let mut z = seed
        .wrapping_add(i.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        .wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Each kind on each thruster in turn, at a random time while the ROV moves (5 to 10 s, after
/// the detector's warm-up and calibration, 4.2 s with the defaults) in a
/// world-frame `current` (N; it loads every thruster), with or without the hexarotor's
/// sensors and EqF. A failure that changes a thrust by less than the
/// detector resolves cannot be seen until the command grows. Every detection must name the
/// right thruster; every failure that changes the thrust by `seen` newtons or more must be
/// found, 95 % of those within 0.2 s; and at least a quarter of them must be that large (the
/// test is not empty). Returns a line per kind.
fn rov_study(sensors: bool, current: [f64; 3], seen_from: f64) -> Vec<String> {
    let n = runs(24);
    let mut lines = Vec::new();
    for (kind, value) in [
        (FailureKind::Dead, 0.0),
        (FailureKind::Stuck, 24.0),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0),
    ] {
        let (mut wrong, mut latencies, mut small, mut missed) = (0, Vec::new(), 0, Vec::new());
        for i in 0..n {
            let mut s = blind_rov(kind, value);
            s.disturbance_world = Some(vec![0.0, 0.0, 0.0, current[0], current[1], current[2]]);
            if sensors {
                let h = pair_tests::load_scenario("hexarotor_eqf");
                s.sensors = h.sensors.clone();
                s.sensors.as_mut().unwrap().seed = 300 + i as u64;
                s.estimator = h.estimator.clone();
            }
            let f = &mut s.vehicle.as_mut().unwrap().failures[0];
            f.actuator = i % 8;
            f.t = (100.0 * (5.0 + 5.0 * uniform(44, i as u64))).round() / 100.0;
            s.duration = f.t + 2.0;
            let (j, at) = (f.actuator, f.t);
            let t = run(&s);
            // the thrust the failure took away, at the tick it struck
            let row = t
                .rows
                .iter()
                .find(|r| r.t >= at - 1e-9)
                .unwrap()
                .vehicle
                .unwrap();
            let change = match kind {
                FailureKind::Dead => row.u_cmd[j].abs(),
                FailureKind::Stuck => (value - row.u_cmd[j]).abs(),
                FailureKind::Effectiveness { factor } => (1.0 - factor) * row.u_cmd[j].abs(),
            };
            let d = detections(&t);
            if std::env::var("EQTRACK_DETECTION_VERBOSE").is_ok() {
                eprintln!("{kind:?} thruster {j} at {at}: change {change:.3}, {d:?}");
            }
            wrong += d.iter().filter(|x| x.actuator != j).count();
            if let Some(first) = d.first() {
                assert!(
                    first.t >= at,
                    "{kind:?} thruster {j}: found at {} before it failed at {at}",
                    first.t
                );
            }
            match d.first() {
                Some(first) if change >= seen_from => latencies.push(first.t - at),
                None if change >= seen_from => missed.push((j, at, change)),
                _ => small += 1,
            }
        }
        latencies.sort_by(f64::total_cmp);
        let seen = latencies.len();
        let p95 = latencies
            .get(((0.95 * seen as f64).ceil() as usize).saturating_sub(1))
            .copied()
            .unwrap_or(0.0);
        lines.push(format!(
            "{kind:?}: {seen} of {n} changed the thrust by {seen_from} N or more, all found, latency median {:.3} s, 95 % {p95:.3} s; {small} smaller; {wrong} wrong; latency histogram (10 ms bins from 0) {:?}",
            latencies.get(seen / 2).copied().unwrap_or(f64::NAN),
            histogram(&latencies)
        ));
        assert_eq!(wrong, 0, "{kind:?}: a wrong thruster named; {lines:?}");
        assert!(missed.is_empty(), "{kind:?}: missed {missed:?}; {lines:?}");
        assert!(
            4 * seen >= n,
            "{kind:?}: too few loaded failures; {lines:?}"
        );
        assert!(p95 <= 0.2, "{kind:?}: {lines:?}");
    }
    lines
}

#[test]
fn rov_thrusters_failing_at_random_times_in_the_move_are_found_on_the_right_one() {
    // the exact state: every failure of 2 N or more
    eprintln!("{}", rov_study(false, [15.0, 8.0, -10.0], 2.0).join("\n"));
}

#[test]
fn on_sensors_and_the_eqf_rov_thrusters_failing_by_5_n_are_found_on_the_right_one() {
    // the hexarotor's sensors (their noise is what the residual's spread is made of here), a
    // stronger current: every failure of 5 N or more
    eprintln!("{}", rov_study(true, [30.0, 20.0, -25.0], 5.0).join("\n"));
}

/// Nominal flights of `base` (its sensors' seed changed per flight): a world-frame wind up
/// to `wind` N in a random horizontal direction, the plant's inertia off by up to ±10 % per
/// axis and each actuator's thrust by up to ±5 % (plant-only changes the controller is not
/// told), at the default false-alarm rate and at 10⁵ an hour. Returns the detections, the
/// alarms at the default rate, the alarms at 10⁵ an hour, and the hours flown.
fn nominal_study(base: &Scenario, wind: f64, n: usize) -> (usize, u32, u32, f64) {
    let (mut found, mut alarms, mut loud) = (0, 0, 0);
    for i in 0..n as u64 {
        let mut s = base.clone();
        let u = |k: u64| 2.0 * uniform(1000 + i, k) - 1.0;
        s.sensors.as_mut().unwrap().seed = 100 + i;
        let (w, a) = (wind * uniform(7, i), std::f64::consts::PI * u(1));
        s.disturbance_world = Some(vec![0.0, 0.0, 0.0, w * a.cos(), w * a.sin(), 0.0]);
        for axis in 0..6 {
            s.plant_inertia[axis * 6 + axis] *= 1.0 + 0.1 * u(2 + axis as u64);
        }
        let v = s.vehicle.as_mut().unwrap();
        v.failures.clear();
        for j in 0..v.actuators.len() {
            v.failures.push(FailureSpec {
                actuator: j,
                t: 0.0,
                kind: FailureKind::Effectiveness {
                    factor: 1.0 + 0.05 * u(10 + j as u64),
                },
                value: 0.0,
                reconfigure: false,
            });
        }
        let mut quiet = s.clone();
        quiet.fault_detection = Some(DEFAULTS);
        let t = run(&quiet);
        found += detections(&t).len();
        alarms += t.vehicle.as_ref().unwrap().alarms.unwrap_or(0);
        // a rate 10⁸ times the default, 10⁵ an hour (about 1 % per test and hypothesis):
        // over these short flights the thousandfold one (one an hour) would be expected to
        // fire less than once in all of them
        let mut eager = s.clone();
        eager.fault_detection = Some(scenario::fault_detection::FaultDetectionSpec {
            false_alarm_rate: 1e8 * DEFAULTS.false_alarm_rate,
            ..DEFAULTS
        });
        let t = run(&eager);
        loud += t.vehicle.as_ref().unwrap().alarms.unwrap_or(0);
    }
    (found, alarms, loud, n as f64 * base.duration / 3600.0)
}

#[test]
fn nominal_flights_with_noise_wind_and_model_error_raise_nothing_and_a_far_higher_rate_fires() {
    // the hexarotor on its sensors and EqF, wind up to 1 N; the ROV on the same sensors, a
    // current up to 20 N
    let mut rov = pair_tests::load_scenario("rov_failure");
    let h = pair_tests::load_scenario("hexarotor_eqf");
    rov.sensors = h.sensors.clone();
    rov.estimator = h.estimator.clone();
    for (name, base, wind) in [("hexarotor", h, 1.0), ("ROV", rov, 20.0)] {
        let n = runs(4);
        let (found, alarms, loud, hours) = nominal_study(&base, wind, n);
        let bound = 1e5 * hours;
        eprintln!(
            "{n} nominal {name} flights ({:.2} h): {found} detections, {alarms} alarms; at 1e5 an hour {loud} alarms (at most about {bound:.0})",
            hours
        );
        assert_eq!(found, 0, "{name}: false detections");
        assert_eq!(alarms, 0, "{name}: alarms at the default rate");
        assert!(loud > 0, "{name}: a rate of 1e5 an hour never fired");
        assert!(
            f64::from(loud) < 3.0 * bound + 3.0,
            "{name}: {loud} alarms, bound {bound}"
        );
    }
}

#[test]
fn a_told_failure_is_not_found_again() {
    // rov_failure's thruster 5 at 20 s, told stuck at -10 N, told dead and told at half its
    // effectiveness: the detector believes the thrust the allocator holds it at from the tick
    // it is told, as the plant's actuator jumps there (it does not ramp through the lag like a
    // command), so nothing is found
    for (kind, value) in [
        (FailureKind::Stuck, -10.0),
        (FailureKind::Dead, 0.0),
        (FailureKind::Effectiveness { factor: 0.5 }, 0.0),
    ] {
        let mut s = blind_rov(kind, value);
        s.disturbance_world = Some(vec![0.0, 0.0, 0.0, 15.0, 8.0, -10.0]);
        s.vehicle.as_mut().unwrap().failures[0].reconfigure = true;
        let t = run(&s);
        let d = detections(&t);
        assert!(d.is_empty(), "{kind:?} told, then found: {d:?}");
    }
}
