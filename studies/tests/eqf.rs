//! The equivariant filter in the simulator's Monte Carlo study (docs/maths.md, "Consistency"
//! and "The two filters compared"): its NEES over seeded closed-loop runs in its χ² band with
//! matched noise and out of it with the noise understated, its convergence from 2.5 rad, and
//! the filters flown on the same sensor streams.

use scenario::{EstimatorKind, Scenario};
use studies::estimator_study::{StudyRun, chi2_band, run_study, stats};
use studies::montecarlo::draw_samples;

fn eqf_so3() -> Scenario {
    pair_tests::load_scenario("eqf_so3")
}

fn eqf_se3() -> Scenario {
    pair_tests::load_scenario("eqf_se3")
}

fn study(
    base: &Scenario,
    runs: usize,
    kinds: &[EstimatorKind],
    initial: Option<f64>,
) -> Vec<StudyRun> {
    let samples = draw_samples(runs, 1);
    let stop = link::StopFlag::never();
    run_study(
        base,
        &samples,
        kinds,
        eqtrack_controller::Law::Eqt,
        initial,
        None,
        &|| {},
        &stop,
    )
    .unwrap()
}

#[test]
fn over_100_closed_loop_runs_the_nees_is_in_its_band_and_leaves_it_with_noise_understated() {
    let base = eqf_so3();
    let (lo, hi) = chi2_band(6.0, 100);
    // measured: 6.13 in (5.34, 6.70)
    let matched = stats(
        &study(&base, 100, &[EstimatorKind::Eqf], None),
        &[EstimatorKind::Eqf],
    );
    let nees = matched[0].mean_nees.unwrap();
    eprintln!("MATCHED {nees} inside {:?}", matched[0].nees_inside);
    assert!(lo < nees && nees < hi, "matched: {lo} < {nees} < {hi}");
    // every noise and initial deviation a tenth of the sensors': measured 613
    let mut under = base.clone();
    let q = under.estimator.eqf.as_mut().unwrap();
    q.gyro_noise /= 10.0;
    q.bias_walk /= 10.0;
    q.direction_noise.iter_mut().for_each(|x| *x /= 10.0);
    let understated = stats(
        &study(&under, 100, &[EstimatorKind::Eqf], None),
        &[EstimatorKind::Eqf],
    );
    let nees = understated[0].mean_nees.unwrap();
    assert!(nees > hi, "understated: {nees} > {hi}");
    let inside = understated[0].nees_inside.unwrap();
    assert!(
        inside < 0.05,
        "understated: inside the band at {inside} of the ticks"
    );
}

#[test]
fn from_two_and_a_half_radians_the_eqf_converges_in_a_fraction_of_a_second() {
    let kinds = [EstimatorKind::Complementary, EstimatorKind::Eqf];
    let s = stats(&study(&eqf_so3(), 20, &kinds, Some(2.5)), &kinds);
    // measured over 20 runs: EqF median 0.10 s, max 0.18 s; the complementary filter
    // (k_P = 1) takes 10 s and more, and not every run converges within the 20 s
    let (cf, eqf) = (&s[0], &s[1]);
    assert_eq!(eqf.converged, 20, "{eqf:?}");
    assert!(eqf.max_convergence_time.unwrap() < 1.0, "{eqf:?}");
    assert!(
        cf.median_convergence_time.unwrap_or(f64::INFINITY) > 5.0,
        "{cf:?}"
    );
}

#[test]
fn the_filters_fly_each_run_once_and_the_eqf_estimates_better() {
    let kinds = [
        EstimatorKind::Truth,
        EstimatorKind::Complementary,
        EstimatorKind::Eqf,
    ];
    let runs = study(&eqf_so3(), 10, &kinds, None);
    assert_eq!(runs.len(), 30);
    let s = stats(&runs, &kinds);
    // truth-fed has no estimate error; measured 2.8e-2 rad (complementary) and 4.6e-3 (EqF)
    assert_eq!(s[0].rms_estimate_error, 0.0);
    assert!(
        s[2].rms_estimate_error < 0.5 * s[1].rms_estimate_error,
        "{s:?}"
    );
    assert!(s[2].rms_bias_error < s[1].rms_bias_error, "{s:?}");
    // run by run in order, each estimator once, with the run's own initial condition
    for (i, r) in runs.iter().enumerate() {
        assert_eq!((r.run, r.estimator), (i / 3, kinds[i % 3]));
    }
    // the same run flown twice gives the same numbers (seeded sensors, whatever the threads)
    // (compared as text: a NaN, where a tick has no NEES, is not equal to itself)
    let again = study(&eqf_so3(), 10, &kinds, None);
    assert!(
        format!("{runs:?}") == format!("{again:?}"),
        "a second study differs"
    );
}

#[test]
fn the_study_refuses_se3_and_no_samples_with_an_error() {
    let stop = link::StopFlag::never();
    let kinds = [EstimatorKind::Eqf];
    let law = eqtrack_controller::Law::Eqt;
    let e = run_study(
        &eqf_se3(),
        &draw_samples(2, 1),
        &kinds,
        law,
        None,
        None,
        &|| {},
        &stop,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("defined on so3, not se3"), "{e}");
    let e = run_study(&eqf_so3(), &[], &kinds, law, None, None, &|| {}, &stop)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no samples"), "{e}");
}

#[test]
fn on_se3_the_eqf_takes_four_direction_sensors_and_the_accelerometer() {
    // 4 directions + "up" = 5 slots, as many as the complementary filter takes
    let mut s = eqf_se3();
    let sensors = s.sensors.as_mut().unwrap();
    let d = sensors.directions[0];
    for world in [[0.0, 1.0, 0.0], [0.6, 0.8, 0.0], [0.0, 0.6, 0.8]] {
        sensors
            .directions
            .push(scenario::DirectionSpec { world, ..d });
    }
    s.estimator.eqf.as_mut().unwrap().direction_noise = vec![0.01, 0.01, 0.01, 0.01, 0.1];
    s.duration = 2.0;
    let t = plant::trajectory::simulate(&s, &|_| Ok(())).unwrap();
    let report = t.estimator.unwrap();
    assert_eq!((report.kind.as_str(), report.directions), ("eqf", 4));
    // measured 0.0027 rad
    assert!(report.rms_estimate_error < 0.05, "{report:?}");
}
