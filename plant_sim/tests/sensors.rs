//! The loop closed on noisy estimates, in process: the estimate error over seeded runs lies in
//! the band the docs state, and the closed loop on estimates converges on SO(3) and SE(3)
//! with the tracking error bounded as documented (docs/maths.md, "What noise costs").

use plant_sim::trajectory::simulate;
use scenario::Scenario;
use std::path::Path;

fn scenario(name: &str) -> Scenario {
    Scenario::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../scenarios/{name}.toml")),
    )
    .unwrap()
}

fn no_progress(_: u64) -> Result<(), plant_sim::SimError> {
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
    // docs/maths.md, "What noise costs": mean in [0.020, 0.035] rad (measured 0.0266, runs
    // from 0.022 to 0.038)
    assert!((0.020..=0.035).contains(&mean), "{mean}");
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
        // documented: over t in [50, 60] s the attitude error stays below 0.1 rad on both
        // groups (measured 0.070 on SO(3), 0.069 on SE(3)) and |Q_E − I| below 0.15 (0.107
        // on SE(3)); the truth-fed loop is tighter (0.013 and 1.5e-4)
        assert!(att < 0.1 && cfg < 0.15, "{name}: {att} {cfg}");
        assert!(att_t < att, "{name}: the estimates cost something");
        assert!(est < 0.05, "{name}: {est}");
    }
}
