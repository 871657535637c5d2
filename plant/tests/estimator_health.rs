//! The innovation gate and the estimator's health
//! (docs/estimators.md, "The innovation gate and health") on `hexarotor_eqf`: a direction sensor turned by 30° is rejected and the
//! attitude estimate holds; position fixes lost for 10 s degrade the health within the window
//! and it recovers when they return; nominal noisy flights never degrade.

use plant::trajectory::{SimulatedTrajectory, simulate};
use scenario::Scenario;

/// `hexarotor_eqf` for `duration` seconds with `extra` in `[estimator]` and `faults` after
/// `[sensors]`; the sensors' seed replaced by `seed` when given.
fn variant(duration: f64, extra: &str, faults: &str, seed: Option<u64>) -> Scenario {
    let text = std::fs::read_to_string(pair_tests::scenario("hexarotor_eqf")).unwrap();
    let mut text = text
        .replace("duration = 10.0", &format!("duration = {duration:?}"))
        .replace("kind = \"eqf\"", &format!("kind = \"eqf\"\n{extra}"))
        .replace("[estimator]", &format!("{faults}\n[estimator]"));
    if let Some(seed) = seed {
        text = text.replace("seed = 5", &format!("seed = {seed}"));
    }
    let base = pair_tests::repo("scenarios");
    Scenario::from_toml_in(&text, "variant", "variant", Some(base.as_ref())).unwrap()
}

fn run(s: &Scenario) -> SimulatedTrajectory {
    simulate(s, &|_| Ok(())).unwrap()
}

const BIAS: &str = r#"
[[sensors.fault]]
sensor = "direction0"
t = 5.0
kind = "bias"
rotation = [0.0, 0.0, 0.5235987755982989]
"#;

/// The largest attitude estimate error after `from` (rad).
fn worst_after(t: &SimulatedTrajectory, from: f64) -> f64 {
    t.rows
        .iter()
        .filter(|r| r.t >= from)
        .map(|r| r.estimate.unwrap().estimate_error)
        .fold(0.0, f64::max)
}

#[test]
fn the_gate_rejects_a_direction_turned_by_30_degrees_and_the_attitude_holds() {
    let gated = run(&variant(10.0, "gate = true", BIAS, None));
    let open = run(&variant(10.0, "", BIAS, None));
    let two_degrees = 2f64.to_radians();
    let (with, without) = (worst_after(&gated, 5.0), worst_after(&open, 5.0));
    println!("worst attitude estimate error after 5 s: gated {with:.5} rad, open {without:.5} rad");
    assert!(with < two_degrees, "gated: {with} rad");
    assert!(
        without > two_degrees,
        "without the gate the bias pulls it: {without} rad"
    );
    let report = gated.estimator.as_ref().unwrap().gate.clone().unwrap();
    println!("{report:?}");
    // every biased sample is rejected (the ticks from 5 s to 10 s), and none before
    assert_eq!(report.rejected["direction0"], 2501);
    assert_eq!(report.rejected.values().sum::<u64>(), 2501);
    let first = &report.health[0];
    assert_eq!(
        (first.health, first.reason.as_str()),
        ("degraded", "rejected direction0")
    );
    assert!((5.0..5.01).contains(&first.t), "{}", first.t);
}

/// A direction turned by 1°: each sample's NIS stays far below the gate's threshold (about 5
/// against 38), so none is rejected, but a window of them sums above the χ² band and the
/// health says so at the first block's end. The EqF then takes most of the bias into its
/// estimate (docs/estimators.md); the same flight without it stays healthy.
#[test]
fn the_band_finds_a_bias_too_small_for_the_gate() {
    let small = BIAS.replace("0.5235987755982989", &1f64.to_radians().to_string());
    let t = run(&variant(10.0, "gate = true", &small, None));
    let g = t.estimator.as_ref().unwrap().gate.clone().unwrap();
    println!("{:?} {:?} {:?}", g.rejected, g.mean_nis, g.health);
    assert_eq!(g.rejected.values().sum::<u64>(), 0);
    let first = &g.health[0];
    assert_eq!(
        (first.health, first.reason.as_str()),
        ("degraded", "inconsistent direction0")
    );
    // the first block after the turn ends within a window (0.5 s) of it
    assert!((5.0..=5.5).contains(&first.t), "{}", first.t);
    assert!(g.inconsistent_blocks["direction0"] >= 1, "{g:?}");
    assert_eq!(g.inconsistent_blocks["direction1"], 0);
    // without the bias the same flight stays healthy
    let t = run(&variant(10.0, "gate = true", "", None));
    assert!(changes(&t).is_empty(), "{:?}", changes(&t));
}

/// The health's changes as `(t, health, reason)`.
fn changes(t: &SimulatedTrajectory) -> Vec<(f64, &'static str, String)> {
    let g = t.estimator.as_ref().unwrap().gate.clone().unwrap();
    g.health
        .into_iter()
        .map(|c| (c.t, c.health, c.reason))
        .collect()
}

#[test]
fn lost_fixes_degrade_the_health_within_the_window_and_it_recovers_when_they_return() {
    let dropout = r#"
[[sensors.fault]]
sensor = "position"
t = 5.0
duration = 10.0
kind = "dropout"
"#;
    let t = run(&variant(25.0, "gate = true", dropout, None));
    let c = changes(&t);
    println!("{c:?}");
    assert_eq!(c.len(), 3, "{c:?}");
    let (down, reset, up) = (&c[0], &c[1], &c[2]);
    assert_eq!((down.1, down.2.as_str()), ("degraded", "missing position"));
    // the last fix before 5 s came at 4.98 s: a window (0.5 s) later, to the tick
    assert!((5.47..=5.49).contains(&down.0), "{}", down.0);
    // the dead-reckoned position has drifted past the first fix back: it is taken, a reset,
    // reported for a window, and the fixes after it pass
    assert_eq!((reset.1, reset.2.as_str()), ("degraded", "reset position"));
    assert!((15.0..15.01).contains(&reset.0), "{}", reset.0);
    assert_eq!((up.1, up.2.as_str()), ("healthy", ""));
    assert!((15.49..15.51).contains(&up.0), "{}", up.0);
    // the csv's column says the same, tick by tick
    let code = |r: &plant::trajectory::Row| r.estimate.unwrap().health.unwrap().code();
    assert!(
        t.rows
            .iter()
            .filter(|r| r.t > 5.5 && r.t < 14.99)
            .all(|r| code(r) == 1)
    );
    assert!(
        t.rows
            .iter()
            .filter(|r| r.t < 5.4 || r.t > 15.51)
            .all(|r| code(r) == 0)
    );
}

/// 200 nominal noisy flights, each with its own sensor seed, wind and noise as the scenario
/// has them: the gate at its default false-alarm rate never degrades the health; the same
/// flights with the rate raised a millionfold (1e4 an hour: a threshold of 10.4 on a
/// direction's NIS, 7.5 on a fix's) do, which shows the check can fail.
#[test]
fn nominal_flights_never_degrade() {
    let flights = 200;
    let (mut degraded, mut rejected) = (0, 0);
    let mut loose = 0;
    for seed in 0..flights {
        let t = run(&variant(10.0, "gate = true", "", Some(100 + seed)));
        let g = t.estimator.as_ref().unwrap().gate.clone().unwrap();
        degraded += usize::from(!g.health.is_empty());
        rejected += g.rejected.values().sum::<u64>();
        if seed < 20 {
            let t = run(&variant(
                10.0,
                "gate = true\nfalse_alarm_rate = 1e4",
                "",
                Some(100 + seed),
            ));
            loose += usize::from(!changes(&t).is_empty());
        }
    }
    println!(
        "{flights} flights: {degraded} degraded, {rejected} samples rejected; at 1e4 an hour, {loose} of 20 degraded"
    );
    assert_eq!((degraded, rejected), (0, 0));
    assert!(loose >= 10, "{loose}");
}

/// `name` with `extra` after its `kind` line and `faults` before `[estimator]`, for `duration`.
fn scenario_with(name: &str, duration: f64, extra: &str, faults: &str) -> Scenario {
    let text = std::fs::read_to_string(pair_tests::scenario(name)).unwrap();
    let at = text.find("duration = ").unwrap();
    let end = at + text[at..].find('\n').unwrap();
    let text = format!("{}duration = {duration:?}{}", &text[..at], &text[end..])
        .replacen("\nkind = \"", &format!("\n{extra}\nkind = \""), 1)
        .replace("[estimator]", &format!("{faults}\n[estimator]"));
    let base = pair_tests::repo("scenarios");
    Scenario::from_toml_in(&text, name, name, Some(base.as_ref())).unwrap()
}

/// Each filter on each group behind the gate: nominal flights keep every direction source
/// and stay healthy; the first direction turned by 30° half-way is rejected from then on,
/// degrading the health at once, and with one direction source left (two on SO(3), the
/// accelerometer on SE(3)) the attitude is lost a window later. On SE(3) the fixes are tested
/// against the Kalman filter's covariance, which leaves out the attitude's error: while the
/// EqF of `eqf_se3` converges from its start (TRIAD on an accelerating body), fixes are
/// rejected and the health is degraded (docs/estimators.md states it).
#[test]
fn every_filter_on_every_group_is_gated() {
    for name in ["sensors_so3", "eqf_so3", "eqf_se3"] {
        let nominal = run(&scenario_with(name, 20.0, "gate = true", ""));
        let g = nominal.estimator.as_ref().unwrap().gate.clone().unwrap();
        println!(
            "{name} nominal: {:?} {:?} mean NIS {:?}",
            g.rejected, g.health, g.mean_nis
        );
        let changes: Vec<_> = g
            .health
            .iter()
            .map(|c| (c.health, c.reason.as_str()))
            .collect();
        // the EqF's directions are consistent: their mean NIS is their two degrees of
        // freedom (the complementary filter's, tested against the noise alone, carry its
        // estimate's error: 3.1 on `sensors_so3`)
        if name != "sensors_so3" {
            for (source, mean) in &g.mean_nis {
                if source.starts_with("direction") {
                    assert!((1.8..2.2).contains(mean), "{name} {source}: {mean}");
                }
            }
        }
        if name == "eqf_se3" {
            // the fixes rejected while the attitude converges; then, the position filter
            // leaving the attitude's error out of its covariance (its fixes' mean NIS is 4.7
            // against 3), blocks of them above the band, until 15 s
            assert_eq!(changes[0], ("degraded", "rejected position"), "{changes:?}");
            assert!(
                changes[1..]
                    .iter()
                    .all(|c| *c == ("degraded", "inconsistent position") || *c == ("healthy", "")),
                "{changes:?}"
            );
            let last = g.health.last().unwrap();
            assert!(last.health == "healthy" && last.t < 15.0, "{:?}", g.health);
            assert!(g.mean_nis["position"] > 3.0, "{:?}", g.mean_nis);
        } else {
            assert!(changes.is_empty(), "{name}: {changes:?}");
        }
        // the directions pass, but for the odd sample while the filter converges
        assert!(g.rejected["direction0"] <= 2, "{name}: {:?}", g.rejected);
        let turned = BIAS.replace("t = 5.0", "t = 10.0");
        let biased = run(&scenario_with(name, 20.0, "gate = true", &turned));
        let g = biased.estimator.as_ref().unwrap().gate.clone().unwrap();
        println!("{name} turned: {:?} {:?}", g.rejected, g.health);
        // 1 000 ticks from 10 s at 100 Hz, every one rejected
        assert!(
            (1000..=1003).contains(&g.rejected["direction0"]),
            "{name}: {:?}",
            g.rejected
        );
        let n = g.health.len();
        let last: Vec<_> = g.health[n - 2..]
            .iter()
            .map(|c| (c.t, c.health, c.reason.as_str()))
            .collect();
        assert_eq!(
            (last[0].1, last[0].2, last[1].1, last[1].2),
            (
                "degraded",
                "rejected direction0",
                "lost",
                "missing attitude"
            ),
            "{name}: {last:?}"
        );
        assert!(
            (10.0..10.01).contains(&last[0].0) && (10.48..10.51).contains(&last[1].0),
            "{last:?}"
        );
    }
}
