//! Lockstep is exact whatever the machine is doing (docs/architecture.md, "Lockstep"): the
//! plant waits for each command and reads no clock, so a CPU hog on every core, a stopped
//! controller or a slow emulator changes how long a run takes, never what it writes. Only
//! `--lockstep-timeout` ends a run for lack of a command, and a run that cannot apply a
//! command stops with a non-zero exit naming the step. Tests run one at a time ([`serial`]).

use pair_tests::{
    CpuHog, Proc, TempDir, plant, recorded_cycles, scenario, serial, summary, wait_for_cycles,
    wait_until,
};
use std::path::Path;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(300);

fn read(path: &str) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `file` flown by `plant_sim sim` into `d/<tag>-sim`.
fn sim(d: &TempDir, tag: &str, file: &str) -> String {
    let out = d.join(&format!("{tag}-sim"));
    let (code, text) = plant(&["sim", "--scenario", file, "--out", &out]);
    assert_eq!(code, 0, "{text}");
    out
}

/// The seed scenario lasting `seconds` (100 cycles a second at its 10 ms period), in `d`.
fn long_seed(d: &TempDir, seconds: u32) -> String {
    let text = std::fs::read_to_string(scenario("seed")).unwrap();
    let longer = text.replace("duration = 20.0", &format!("duration = {seconds}.0"));
    assert_ne!(text, longer, "the template changed");
    let path = d.join("long_seed.toml");
    std::fs::write(&path, longer).unwrap();
    path
}

#[test]
fn lockstep_under_a_cpu_hog_equals_the_simulation_byte_for_byte() {
    let _g = serial();
    let d = TempDir::new("lockstep-hog");
    let _hog = CpuHog::start();
    // the seed at a 0.2 ms period: under the hog the pair is far slower than real time
    let fast = std::fs::read_to_string(scenario("seed"))
        .unwrap()
        .replace("duration = 20.0", "duration = 1.0")
        .replace("control_period = 0.01", "control_period = 0.0002")
        .replace("plant_substeps = 10", "plant_substeps = 1")
        .replace("reference_substeps = 10", "reference_substeps = 1");
    assert_eq!(
        fast.matches("= 1\n").count(),
        2,
        "the template changed:\n{fast}"
    );
    let fast_file = d.join("seed_fast.toml");
    std::fs::write(&fast_file, fast).unwrap();
    // the feedforward series on both groups, the rejection terms, both estimators
    let names = [
        "seed_fast",
        "seed",
        "se3_circle",
        "reject_so3",
        "sensors_so3",
        "eqf_so3",
    ];
    for name in names {
        let file = if name == "seed_fast" {
            fast_file.clone()
        } else {
            scenario(name)
        };
        let sim = sim(&d, name, &file);
        let runs: Vec<String> = ["a", "b"]
            .iter()
            .map(|k| {
                let out = d.join(&format!("{name}-{k}"));
                let run_name = format!("t-hog-{name}");
                let (code, text) = plant(&[
                    "run",
                    "--scenario",
                    &file,
                    "--mode",
                    "lockstep",
                    "--name",
                    &run_name,
                    "--out",
                    &out,
                ]);
                assert_eq!(code, 0, "{name}: {text}");
                out
            })
            .collect();
        let csv = |dir: &str| read(&format!("{dir}/trajectory.csv"));
        assert!(
            csv(&sim) == csv(&runs[0]) && csv(&sim) == csv(&runs[1]),
            "{name}: a lockstep run under the hog differs from the simulation"
        );
        let log = |dir: &str| read(&format!("{dir}/messages.log"));
        assert!(
            log(&runs[0]) == log(&runs[1]),
            "{name}: two lockstep runs wrote different messages.log"
        );
        let s = summary(Path::new(&runs[0]));
        assert_eq!(s["deadline_misses"], 0, "{s}");
        assert_eq!(s["late_commands"], 0, "{s}");
        assert_eq!(s["safe_mode_entries"], 0, "{s}");
        assert!(
            s["deadline_note"]
                .as_str()
                .is_some_and(|n| n.contains("do not apply")),
            "{s}"
        );
    }
}

/// Starts `plant_sim run --mode lockstep --no-spawn` of `file` under `run_name` into `out`
/// with `extra` arguments, and a controller by hand; returns both once they are connected.
fn hand_started_pair(file: &str, run_name: &str, out: &str, extra: &[&str]) -> (Proc, Proc) {
    let mut args = vec![
        "run",
        "--scenario",
        file,
        "--mode",
        "lockstep",
        "--no-spawn",
        "--name",
        run_name,
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    let plant = Proc::start("plant_sim", &args);
    let ctl = Proc::start("controller_node", &["--scenario", file, "--name", run_name]);
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(30)),
        "{}",
        plant.output()
    );
    (plant, ctl)
}

/// SIGSTOP to the controller once `out` has 500 cycles; returns the cycles recorded while it
/// is stopped: the plant waits, so the count settles (what was on its way is written, then
/// nothing more), and the count is taken once it has stood still for half a second.
fn stop_controller(ctl: &Proc, out: &str) -> u64 {
    wait_for_cycles(out, 500, LONG);
    ctl.signal("STOP");
    let (mut last, mut since) = (recorded_cycles(out), std::time::Instant::now());
    let settled = wait_until(LONG, || {
        let now = recorded_cycles(out);
        if now != last {
            (last, since) = (now, std::time::Instant::now());
        }
        since.elapsed() >= Duration::from_millis(500)
    });
    assert!(settled, "the recorded count never settled ({last})");
    last
}

#[test]
fn a_controller_stopped_for_less_than_the_lockstep_timeout_changes_nothing() {
    let _g = serial();
    let d = TempDir::new("lockstep-pause");
    let file = long_seed(&d, 60);
    let sim = sim(&d, "pause", &file);
    // with event wake-up the controller sleeps between states; with busy polling it is
    // almost always between reading the board and looking at its clock when it is stopped
    for wake in ["event", "spin"] {
        let out = d.join(&format!("pair-{wake}"));
        let extra = ["--lockstep-timeout", "30", "--wake", wake];
        let (mut plant, ctl) = hand_started_pair(&file, "t-lock-pause", &out, &extra);
        let at = stop_controller(&ctl, &out);
        // two seconds stopped: longer than any period and than the controller's 1 s silence
        // timeout, far shorter than the lockstep timeout
        std::thread::sleep(Duration::from_secs(2));
        let still = recorded_cycles(&out);
        ctl.signal("CONT");
        assert!(
            at < 6000 && still == at,
            "{wake}: the plant waited at cycle {at} (recorded {still} after the stop)"
        );
        let status = plant.wait_timeout(LONG);
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(0),
            "{wake}: {}",
            plant.output()
        );
        assert!(
            read(&format!("{sim}/trajectory.csv")) == read(&format!("{out}/trajectory.csv")),
            "{wake}: a pause of the controller changed the lockstep run"
        );
    }
}

#[test]
fn a_controller_stopped_for_longer_than_the_lockstep_timeout_ends_the_run_non_zero() {
    let _g = serial();
    let d = TempDir::new("lockstep-timeout");
    let file = long_seed(&d, 60);
    let out = d.join("pair");
    let (mut plant, ctl) =
        hand_started_pair(&file, "t-lock-timeout", &out, &["--lockstep-timeout", "1"]);
    let at = stop_controller(&ctl, &out);
    let status = plant.wait_timeout(LONG);
    ctl.signal("CONT");
    let text = plant.output();
    assert_eq!(status.and_then(|s| s.code()), Some(1), "{text}");
    let needle = format!("lockstep: no command for step {at} within 1.0 s (--lockstep-timeout)");
    assert!(text.contains(&needle), "missing `{needle}` in:\n{text}");
    assert!(
        !Path::new(&out).join("summary.json").exists(),
        "a run that timed out writes no summary of a run that did not happen"
    );
}

#[test]
fn a_rejected_command_ends_a_lockstep_run_at_once_naming_the_step() {
    let _g = serial();
    let d = TempDir::new("lockstep-reject");
    // the spawned controller publishes a NaN torque for step K: the plant's checks reject it,
    // and lockstep cannot hold the previous torque instead. Step 0 is the first command,
    // which the plant takes while it waits for a controller.
    for step in [50u64, 0] {
        let out = d.join(&format!("pair-{step}"));
        let k = step.to_string();
        let mut p = Proc::start(
            "plant_sim",
            &[
                "run",
                "--mode",
                "lockstep",
                "--name",
                "t-lock-reject",
                "--out",
                &out,
                "--lockstep-timeout",
                "120",
                "--connect-timeout",
                "120",
                "--fault-nan-torque",
                &k,
            ],
        );
        let status = p.wait_timeout(Duration::from_secs(60));
        let text = p.output();
        assert!(
            !text.contains("unexpected argument '--fault"),
            "the binaries lack the test-only fault-injection feature: run the workspace's tests\n{text}"
        );
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(1),
            "the run stops long before its 120 s timeouts:\n{text}"
        );
        let needle = format!(
            "lockstep: the controller's command for step {step} was rejected by the plant's checks (seq {step}: non-finite number)"
        );
        assert!(text.contains(&needle), "missing `{needle}` in:\n{text}");
        assert!(
            wait_until(Duration::from_secs(10), || recorded_cycles(&out) == step),
            "the log holds the {step} steps applied, got {}",
            recorded_cycles(&out)
        );
    }
}
