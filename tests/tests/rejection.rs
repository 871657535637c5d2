//! Disturbance rejection through the real binaries (docs/maths.md, "Disturbance rejection"):
//! the lockstep pair with the observer and the integral equals the in-process simulation,
//! a real-time run with a stopped controller replays bit for bit and winds nothing up, and
//! bad keys are refused. Tests run one at a time ([`serial`]).

use pair_tests::{
    Csv, Proc, TempDir, plant, realtime_priority, run, scenario, serial, sim_equals_lockstep,
    summary, wait_for_cycles,
};
use std::path::Path;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(120);

#[test]
fn lockstep_with_the_observer_and_the_integral_equals_the_simulation_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("reject-lockstep");
    // the two scenarios, and the SO(3) one with the integral instead of the observer
    let integral = d.join("reject_so3_integral.toml");
    let so3 = std::fs::read_to_string(scenario("reject_so3")).unwrap();
    let with_integral = so3.replace(
        "disturbance_observer = { gain = 20.0 }",
        "integral = { ki = 1.0, c = 5.0 }",
    );
    assert_ne!(so3, with_integral);
    std::fs::write(&integral, with_integral).unwrap();
    for (name, file) in [
        ("reject_so3", scenario("reject_so3")),
        ("reject_se3", scenario("reject_se3")),
        ("reject_so3_integral", integral.clone()),
    ] {
        let (sim, pair) = sim_equals_lockstep(&d, name, &file);
        // the terms crossed the wire and are recorded
        let csv = Csv::read(&Path::new(&sim).join("trajectory.csv"));
        let m = if name.ends_with("se3") { 6 } else { 3 };
        let (observer, integral) = (!name.ends_with("integral"), name.ends_with("integral"));
        for i in 0..m {
            let nonzero = |c: &str| csv.col(&format!("{c}_{i}")).iter().any(|x| *x != 0.0);
            assert_eq!(nonzero("dhat"), observer, "{name}");
            assert_eq!(nonzero("integral"), integral, "{name}");
        }
        let s = summary(Path::new(&pair));
        assert_eq!(s["controller_heap_allocations"].as_u64(), Some(0), "{s}");
        let (code, text) = plant(&["replay", &pair]);
        assert_eq!(code, 0, "{text}");
        assert!(text.contains(", 0 differ"), "{text}");
    }
    // on SO(3) the set-point is reached exactly and the estimate is the disturbance, by
    // either term
    for (name, column, sign) in [
        ("reject_so3", "dhat", 1.0),
        ("reject_so3_integral", "integral", -1.0),
    ] {
        let csv = Csv::read(&Path::new(&d.join(&format!("{name}-sim"))).join("trajectory.csv"));
        let last = csv.col("t").len() - 1;
        assert!(csv.col("attitude_error")[last] < 1e-6, "{name}");
        for (i, di) in [0.1, -0.05, 0.08].iter().enumerate() {
            let estimate = sign * csv.col(&format!("{column}_{i}"))[last];
            assert!((estimate - di).abs() < 1e-5, "{name}: {estimate} vs {di}");
        }
    }
}

#[test]
fn a_stopped_controller_with_the_observer_replays_bit_for_bit_and_winds_nothing_up() {
    let _g = serial();
    let Some(prio) = realtime_priority(
        "a_stopped_controller_with_the_observer_replays_bit_for_bit_and_winds_nothing_up",
    ) else {
        return;
    };
    let d = TempDir::new("reject-stop");
    // the set-point with the torque limited, so the safe mode and the clamps act
    let text = std::fs::read_to_string(scenario("reject_so3"))
        .unwrap()
        .replace("[plant]\n", "[plant]\ntorque_limit = 0.3\n");
    let file = d.join("reject_limited.toml");
    std::fs::write(&file, text).unwrap();
    let out = d.join("run");
    let name = "t-reject-stop";
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--scenario",
            &file,
            "--duration",
            // 1.5 s to the stop, and over 4 s after it to settle even on a busy machine
            "6",
            "--name",
            name,
            "--out",
            &out,
            "--no-spawn",
            prio[0],
            prio[1],
        ],
    );
    let ctl = Proc::start(
        "controller_node",
        &["--name", name, "--scenario", &file, prio[0], prio[1]],
    );
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
    wait_for_cycles(&out, 1500, LONG);
    // 30 ms (or longer, on a loaded machine) without a controller at 1 kHz: misses, then
    // the safe mode
    ctl.signal("STOP");
    std::thread::sleep(Duration::from_millis(30));
    ctl.signal("CONT");
    plant.expect_exit(0, Duration::from_secs(30));
    let s = summary(Path::new(&out));
    assert!(s["deadline_misses"].as_u64().unwrap() >= 5, "{s}");
    assert!(s["safe_mode_entries"].as_u64().unwrap() >= 1, "{s}");
    // the terms allocate nothing, on either side
    assert_eq!(s["plant_loop_heap_allocations"].as_u64(), Some(0), "{s}");
    assert_eq!(s["controller_heap_allocations"].as_u64(), Some(0), "{s}");
    // replay skips the states the stopped controller never saw, as the controller did
    let (code, text) = plant_replay(&out);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(", 0 differ"), "{text}");

    let csv = Csv::read(&Path::new(&out).join("trajectory.csv"));
    let (t, status, err) = (
        csv.col("t"),
        csv.col("command_status"),
        csv.col("attitude_error"),
    );
    // the end of the stop's safe mode: the longest run of 2s (on a jittery machine single late
    // commands (1), or another short safe mode, may come before or after it)
    let mut runs = Vec::new();
    let mut k = 0;
    while k < status.len() {
        if status[k] == 2.0 {
            let start = k;
            while k < status.len() && status[k] == 2.0 {
                k += 1;
            }
            runs.push((k - start, k));
        }
        k += 1;
    }
    let recovered = runs.iter().max().expect("a safe mode").1;
    let stopped = status.iter().position(|x| *x != 0.0).unwrap();
    println!("stopped at t = {:.3} s", t[stopped]);
    let d_true = [0.1, -0.05, 0.08];
    let mut worst_estimate = 0.0f64;
    for k in 0..t.len() {
        for (i, di) in d_true.iter().enumerate() {
            if k >= recovered {
                worst_estimate = worst_estimate.max((csv.col(&format!("dhat_{i}"))[k] - di).abs());
            }
        }
    }
    let settled_again = err[recovered..]
        .iter()
        .position(|e| *e < 1e-3)
        .map(|i| t[recovered + i] - t[recovered]);
    println!(
        "after the stop (recovered at t = {:.3} s): the estimate within {worst_estimate:.2e} \
         of d, back below 1e-3 after {settled_again:?} s, final error {:.2e}",
        t[recovered],
        err[err.len() - 1]
    );
    assert!(worst_estimate < 5e-3, "{worst_estimate}");
    assert!(settled_again.is_some_and(|s| s < 1.0), "{settled_again:?}");
    // settled once undisturbed: at the end of the longest stretch after the recovery in
    // which every command arrived on time. To 1e-4 when that stretch lasted a second and a
    // half (the usual case); to 5e-3 when a loaded machine kept holding commands (CI's hog
    // once held one 77 ms before the end, and the damping-only safe mode let the error
    // drift to 2e-3 there; another run's longest quiet stretch was 0.61 s, ending at 1.5e-3).
    // Wind-up is what the estimate's bound above and the settling within a second check.
    let mut best = (0.0f64, recovered);
    let mut start = recovered;
    for k in recovered..t.len() {
        if status[k] != 0.0 {
            start = k + 1;
        } else if t[k] - t[start.min(k)] > best.0 {
            best = (t[k] - t[start.min(k)], k);
        }
    }
    let (quiet, at) = best;
    let bound = if quiet > 1.5 { 1e-4 } else { 5e-3 };
    assert!(
        err[at] < bound,
        "error {} at t = {:.3} s, the end of {quiet:.3} s without a held command",
        err[at],
        t[at]
    );
}

fn plant_replay(dir: &str) -> (i32, String) {
    run("plant_sim", &["replay", dir], LONG)
}

#[test]
fn bad_rejection_keys_exit_2_naming_the_key() {
    let d = TempDir::new("reject-bad");
    let base = std::fs::read_to_string(scenario("reject_so3")).unwrap();
    for (from, to, needle) in [
        (
            "disturbance_observer = { gain = 20.0 }",
            "disturbance_observer = { gain = -20.0 }",
            "key `controller.disturbance_observer.gain`: must be a finite number > 0",
        ),
        (
            "disturbance_observer = { gain = 20.0 }",
            "disturbance_observer = { gain = 20.0, frame = \"inertial\" }",
            "key `controller.disturbance_observer.frame`",
        ),
        (
            "disturbance_observer = { gain = 20.0 }\n",
            "integral = { ki = 1.0, c = [5.0, 5.0] }\n",
            "key `controller.integral.c`: expected 3 numbers",
        ),
        (
            "disturbance = [0.1, -0.05, 0.08]",
            "disturbance = [0.1, -0.05, 0.08]\ndisturbance_world = [nan, 0.0, 0.0]",
            "key `plant.disturbance_world`",
        ),
        (
            "disturbance = [0.1, -0.05, 0.08]",
            "disturbance = [0.1, -0.05, 0.08]\ndisturbance_steps = [{ t = 2.0, value = [0.1] }]",
            "key `plant.disturbance_steps[0].value`",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        let file = d.join("bad.toml");
        std::fs::write(&file, base.replace(from, to)).unwrap();
        for (bin, args) in [
            (
                "plant_sim",
                vec!["sim", "--scenario", &file, "--out", &d.join("o")],
            ),
            (
                "controller_node",
                vec!["--scenario", &file, "--name", "t-reject-bad"],
            ),
        ] {
            let (code, text) = run(bin, &args, LONG);
            assert_eq!(code, 2, "{bin} {to}: {text}");
            assert!(text.contains(needle), "{bin}: {text}\n  wanted: {needle}");
        }
    }
}
