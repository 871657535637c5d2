//! Scripted sensor faults (`[[sensors.fault]]`, docs/scenario.md, "Sensor faults"): each
//! sample is the clean one with exactly its fault applied, and nothing else changes. The law
//! sees the exact state here, so the flight, and with it every clean sample, is the same with
//! and without the faults, and the two runs compare tick by tick.

use eqtrack_controller::group::so3::exp_so3;
use nalgebra::Vector3;
use plant::sensors::Samples;
use plant::trajectory::simulate;
use scenario::Scenario;

/// `eqf_se3`'s body and sensors for 3 s, the law on the exact state, with `faults`
/// appended to `[sensors]`.
fn run(faults: &str) -> Vec<(f64, Samples)> {
    let text = std::fs::read_to_string(pair_tests::scenario("eqf_se3")).unwrap();
    let head = &text[..text
        .find("[estimator]")
        .expect("eqf_se3 ends with [estimator]")];
    let text = head.replace("duration = 60.0", "duration = 3.0") + faults;
    let s = Scenario::from_toml(&text, "faults.toml", "faults").unwrap();
    let t = simulate(&s, &|_| Ok(())).unwrap();
    t.rows
        .iter()
        .map(|r| (r.t, r.estimate.expect("sensors are sampled").samples))
        .collect()
}

const FAULTS: &str = r#"
[[sensors.fault]]
sensor = "gyro"
t = 0.5
duration = 0.5
kind = "bias"
value = [0.1, -0.2, 0.05]

[[sensors.fault]]
sensor = "gyro"
t = 2.2
duration = 0.3
kind = "stuck"

[[sensors.fault]]
sensor = "direction0"
t = 1.0
duration = 0.5
kind = "bias"
rotation = [0.0, 0.0, 0.5235987755982989]

[[sensors.fault]]
sensor = "direction0"
t = 2.6
kind = "dropout"

[[sensors.fault]]
sensor = "accelerometer"
t = 0.6
duration = 0.2
kind = "bias"
value = [0.0, 0.0, 3.0]

[[sensors.fault]]
sensor = "accelerometer"
t = 1.5
duration = 0.3
kind = "dropout"

[[sensors.fault]]
sensor = "position"
t = 0.2
duration = 0.3
kind = "dropout"

[[sensors.fault]]
sensor = "position"
t = 2.0
duration = 0.5
kind = "stuck"

[[sensors.fault]]
sensor = "position"
t = 1.2
duration = 0.4
kind = "bias"
value = [1.0, 0.0, -0.5]
"#;

fn inside(t: f64, from: f64, to: f64) -> bool {
    // the faults start at the first tick t_k >= t - h/2 and end before t + duration - h/2
    t >= from - 0.005 && t < to - 0.005
}

fn same(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    a.iter()
        .zip(b.iter())
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

fn nans(a: &Vector3<f64>) -> bool {
    a.iter().all(|x| x.is_nan())
}

/// The last clean sample strictly before `t`, by `pick`.
fn last_before<T>(
    clean: &[(f64, Samples)],
    t: f64,
    pick: impl Fn(&Samples) -> Option<T>,
) -> Option<T> {
    clean
        .iter()
        .filter(|(tk, _)| *tk < t - 0.005)
        .filter_map(|(_, s)| pick(s))
        .last()
}

#[test]
fn each_sample_is_the_clean_one_with_exactly_its_fault() {
    let clean = run("");
    let faulty = run(FAULTS);
    assert_eq!(clean.len(), faulty.len());
    let (mut biased, mut dropped, mut stuck) = (0, 0, 0);
    let gyro_stuck = last_before(&clean, 2.2, |s| Some(s.gyro)).unwrap();
    let fix_stuck = last_before(&clean, 2.0, |s| s.position).unwrap();
    for ((t, c), (tf, f)) in clean.iter().zip(&faulty) {
        assert_eq!(t.to_bits(), tf.to_bits());
        let t = *t;
        // the truth the samples come from is the same flight
        assert!(same(&c.bias, &f.bias), "t = {t}: the flight changed");
        // gyro
        if inside(t, 0.5, 1.0) {
            assert!(
                same(&f.gyro, &(c.gyro + Vector3::new(0.1, -0.2, 0.05))),
                "t = {t}"
            );
            biased += 1;
        } else if inside(t, 2.2, 2.5) {
            assert!(same(&f.gyro, &gyro_stuck), "t = {t}: {:?}", f.gyro);
            stuck += 1;
        } else {
            assert!(
                same(&f.gyro, &c.gyro),
                "t = {t}: the gyro changed outside its faults"
            );
        }
        // the first direction; the accelerometer is the second sensor of the scenario's list
        let turn = exp_so3(&Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_6));
        if inside(t, 1.0, 1.5) {
            assert!(same(&f.directions[0], &(turn * c.directions[0])), "t = {t}");
            let angle = f.directions[0].angle(&c.directions[0]);
            assert!(
                angle > 1e-3 && angle <= std::f64::consts::FRAC_PI_6 + 1e-9,
                "t = {t}: turned by {angle}"
            );
            biased += 1;
        } else if inside(t, 2.6, f64::INFINITY) {
            assert!(nans(&f.directions[0]), "t = {t}");
            dropped += 1;
        } else {
            assert!(same(&f.directions[0], &c.directions[0]), "t = {t}");
        }
        let (ca, fa) = (c.accel.unwrap(), f.accel.unwrap());
        if inside(t, 0.6, 0.8) {
            assert!(same(&fa, &(ca + Vector3::new(0.0, 0.0, 3.0))), "t = {t}");
        } else if inside(t, 1.5, 1.8) {
            assert!(nans(&fa), "t = {t}");
        } else {
            assert!(same(&fa, &ca), "t = {t}");
        }
        // position fixes (50 Hz: every other tick)
        match (c.position, f.position) {
            (None, None) => {}
            (Some(_), None) if inside(t, 0.2, 0.5) => dropped += 1,
            (Some(x), Some(y)) if inside(t, 1.2, 1.6) => {
                assert!(same(&y, &(x + Vector3::new(1.0, 0.0, -0.5))), "t = {t}");
            }
            (Some(_), Some(y)) if inside(t, 2.0, 2.5) => {
                assert!(same(&y, &fix_stuck), "t = {t}");
                stuck += 1;
            }
            (Some(x), Some(y)) => assert!(same(&x, &y), "t = {t}: a fix changed"),
            other => panic!("t = {t}: a fix appeared or vanished outside a fault: {other:?}"),
        }
    }
    assert!(
        biased > 90 && dropped > 40 && stuck > 50,
        "the faults ran: {biased} biased, {dropped} dropped, {stuck} stuck"
    );
}

/// A fault that lasts to the end, and a stuck sensor with nothing to repeat (from t = 0):
/// it gives nothing, as a dropout.
#[test]
fn a_stuck_sensor_with_no_sample_before_gives_none() {
    let faulty = run(r#"
[[sensors.fault]]
sensor = "gyro"
t = 0.0
kind = "stuck"

[[sensors.fault]]
sensor = "position"
t = 0.0
duration = 1.0
kind = "stuck"
"#);
    assert!(faulty.iter().all(|(_, s)| nans(&s.gyro)));
    assert!(
        faulty
            .iter()
            .all(|(t, s)| s.position.is_none() || *t >= 1.0 - 0.005)
    );
    assert!(faulty.iter().any(|(_, s)| s.position.is_some()));
}

/// Position fixes at any rate are found in bounded time: a rate far above the control rate
/// gives a fix every tick (it hung the fuzz run once, counting fixes one by one), and an odd
/// rate gives its fixes at the ticks a count one by one gives.
#[test]
fn fixes_at_any_rate_come_when_due() {
    let with_rate = |rate: &str| {
        let text = std::fs::read_to_string(pair_tests::scenario("eqf_se3")).unwrap();
        let head = &text[..text.find("[estimator]").unwrap()];
        let text = head
            .replace("duration = 60.0", "duration = 1.0")
            .replace("rate_hz = 50.0", &format!("rate_hz = {rate}"));
        let s = Scenario::from_toml(&text, "rate.toml", "rate").unwrap();
        let t = simulate(&s, &|_| Ok(())).unwrap();
        t.rows
            .iter()
            .map(|r| r.estimate.unwrap().samples.position.is_some())
            .collect::<Vec<bool>>()
    };
    assert!(with_rate("1e300").iter().all(|f| *f));
    let odd = 33.3;
    let (h, mut next) = (0.01, 0u64);
    let expected: Vec<bool> = (0..=100u64)
        .map(|k| {
            let now = k as f64 * h + 1e-9 * h;
            let due = now >= next as f64 / odd;
            while due && next as f64 / odd <= now {
                next += 1;
            }
            due
        })
        .collect();
    assert_eq!(with_rate("33.3"), expected);
    assert_eq!(expected.iter().filter(|f| **f).count(), 34);
}
