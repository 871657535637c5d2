//! The loop closed on noisy estimates, in process: the estimate error over seeded runs lies in
//! the band the docs state, and the closed loop on estimates converges on SO(3) and SE(3)
//! with the tracking error bounded as documented (docs/maths.md, "What noise costs").

use plant::trajectory::simulate;
use scenario::Scenario;

fn scenario(name: &str) -> Scenario {
    pair_tests::load_scenario(name)
}

fn no_progress(_: u64) -> Result<(), plant::SimError> {
    Ok(())
}

#[test]
fn over_twenty_seeds_the_mean_rms_estimate_error_lies_in_the_documented_band() {
    let base = scenario("sensors_so3");
    let rms: Vec<f64> = (1..=20u64)
        .map(|seed| {
            let mut s = base.clone();
            s.sensors.as_mut().unwrap().seed = seed;
            let t = simulate(&s, &no_progress).unwrap();
            t.estimator.unwrap().rms_estimate_error
        })
        .collect();
    let mean = rms.iter().sum::<f64>() / rms.len() as f64;
    let (lo, hi) = rms
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    eprintln!("RMS estimate error over 20 seeds: mean {mean:.4e} rad, range {lo:.4e} .. {hi:.4e}");
    // docs/maths.md, "What noise costs": mean in [0.025, 0.045] rad (measured 0.0345, runs
    // from 0.030 to 0.040, flying the default error frame; 0.0266 with the papers' form)
    assert!((0.025..=0.045).contains(&mean), "{mean}");
    assert!(hi < 0.06, "{hi}");
}

#[test]
fn the_closed_loop_on_estimates_converges_on_so3_and_se3() {
    for name in ["sensors_so3", "sensors_se3"] {
        let mut s = scenario(name);
        s.duration = 60.0;
        let t = simulate(&s, &no_progress).unwrap();
        let last: Vec<_> = t.rows.iter().filter(|r| r.t >= 50.0).collect();
        let att = last.iter().map(|r| r.attitude_error).fold(0.0, f64::max);
        let cfg = last.iter().map(|r| r.config_error).fold(0.0, f64::max);
        let est = last
            .iter()
            .map(|r| r.estimate.unwrap().estimate_error)
            .fold(0.0, f64::max);
        let mut truth = s.clone();
        truth.sensors = None;
        truth.estimator = Default::default();
        let tt = simulate(&truth, &no_progress).unwrap();
        let att_t = tt
            .rows
            .iter()
            .filter(|r| r.t >= 50.0)
            .map(|r| r.attitude_error)
            .fold(0.0, f64::max);
        let cfg_t = tt
            .rows
            .iter()
            .filter(|r| r.t >= 50.0)
            .map(|r| r.config_error)
            .fold(0.0, f64::max);
        eprintln!(
            "{name}, t in [50, 60] s: attitude error max {att:.3e} (truth-fed {att_t:.3e}), |Q_E - I| max {cfg:.3e} (truth-fed {cfg_t:.3e}), estimate error max {est:.3e}"
        );
        // documented (docs/maths.md, "What noise costs"), for t in [50, 60] s with the
        // default error frame: on SO(3) the attitude error stays below 0.1 rad (measured
        // 0.079; truth-fed 0.019) and the estimate error below 0.05 (0.036); on SE(3), with
        // the complementary pose filter's 5 mm position fixes at 50 Hz, the attitude error
        // stays below 0.2 (0.155), |Q_L − I| below 0.7 (0.595) and the estimate error below
        // 0.1 (0.075), where the papers' form measured 0.069, 0.107 and 0.017 and
        // re-centring 0.024, 0.096 and 0.018: the transported error's measured price on
        // this filter; the truth-fed loops settle to 1e-7
        let (att_max, cfg_max, est_max) = match name {
            "sensors_so3" => (0.1, 0.15, 0.05),
            _ => (0.2, 0.7, 0.1),
        };
        assert!(att < att_max && cfg < cfg_max, "{name}: {att} {cfg}");
        assert!(att_t < att, "{name}: the estimates cost something");
        assert!(est < est_max, "{name}: {est}");
    }
}

#[test]
fn the_noise_study_degrades_with_gyro_noise_and_truth_fed_rows_do_not_see_it() {
    let base = scenario("sensors_so3");
    let rows = studies::noise::study(&base, &[0.002, 0.1], 3).unwrap();
    assert_eq!(rows.len(), 8, "2 noise levels × bias on/off × truth/filter");
    let find = |noise: f64, bias: bool, est: &str| {
        rows.iter()
            .find(|r| r.gyro_noise == noise && r.bias == bias && r.estimator == est)
            .unwrap()
    };
    for bias in [false, true] {
        let (lo, hi) = (
            find(0.002, bias, "complementary"),
            find(0.1, bias, "complementary"),
        );
        assert!(
            hi.rms_estimate_error > 3.0 * lo.rms_estimate_error,
            "{lo:?} {hi:?}"
        );
        assert!(
            hi.final_attitude_error > lo.final_attitude_error,
            "{lo:?} {hi:?}"
        );
        // the truth-fed loop never sees the sensors
        let (a, b) = (find(0.002, bias, "truth"), find(0.1, bias, "truth"));
        assert_eq!(a.final_attitude_error, b.final_attitude_error);
        assert_eq!((a.rms_estimate_error, b.rms_estimate_error), (0.0, 0.0));
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    studies::noise::write(&rows, "sensors_so3", d).unwrap();
    let csv = std::fs::read_to_string(d.join("noise.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9, "{csv}");
    assert!(d.join("noise.png").exists() && d.join("table.md").exists());
    // a scenario without a filter is refused
    let plain = Scenario::builtin("seed").unwrap();
    assert!(studies::noise::study(&plain, &[0.002], 1).is_err());
}

#[test]
fn the_monte_carlo_study_gives_each_run_its_own_sensors_whatever_the_thread_count() {
    let base = scenario("sensors_so3");
    let (mut a, mut b, mut again) = (base.clone(), base.clone(), base.clone());
    studies::montecarlo::run_sensors(&mut a, 0);
    studies::montecarlo::run_sensors(&mut b, 1);
    studies::montecarlo::run_sensors(&mut again, 0);
    let (sa, sb) = (a.sensors.unwrap(), b.sensors.unwrap());
    assert_ne!(sa.seed, sb.seed);
    assert_ne!(sa.gyro.bias, sb.gyro.bias);
    assert_eq!(again.sensors.unwrap(), sa, "drawn from the run index alone");
    let samples = studies::montecarlo::draw_samples(4, 3);
    let stop = link::StopFlag::never();
    let run = |threads| {
        studies::montecarlo::run_all(
            &base,
            &samples,
            &[eqtrack_controller::Law::Eqt],
            Some(threads),
            &|| {},
            &stop,
        )
        .unwrap()
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    // and the runs' sensors differ: same law and scenario, different estimates
    assert_ne!(one[0].series[100], one[1].series[100]);
}

#[test]
fn the_noise_study_flies_the_eqf_too_and_keeps_its_noise_model_matched() {
    let base = scenario("eqf_so3");
    let rows = studies::noise::study(&base, &[0.002, 0.02], 2).unwrap();
    assert_eq!(rows.len(), 8);
    assert!(rows.iter().any(|r| r.estimator == "eqf"), "{rows:?}");
    for r in rows.iter().filter(|r| r.estimator == "eqf") {
        assert!(
            r.rms_estimate_error > 0.0 && r.rms_estimate_error < 0.05,
            "{r:?}"
        );
    }
    // the filter-fed error grows with the gyro's noise: the EqF follows the study's noise
    let err = |n: f64| {
        rows.iter()
            .find(|r| r.estimator == "eqf" && r.gyro_noise == n && r.bias)
            .unwrap()
            .rms_estimate_error
    };
    assert!(err(0.02) > err(0.002), "{rows:?}");
}
