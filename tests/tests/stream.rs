//! The streamed reference, through the real processes: `planner` publishes path pieces on the
//! run's plan board, `controller_node --reference stream` tracks them, `plant_sim run
//! --no-spawn` is the plant. Tests run one at a time ([`serial`]).

use eqtrack_controller::group::So3;
use eqtrack_controller::path::{Path as GroupPath, PathReference};
use eqtrack_controller::{Controller, Trajectory};
use nalgebra::{Matrix3, SMatrix, Vector3};
use pair_tests::{
    CpuHog, Csv, Proc, TempDir, realtime_priority, recorded_cycles, run, serial, wait_for_cycles,
};
use scenario::Scenario;
use std::path::Path;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(60);

fn scenarios() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios").to_owned()
}

/// The lockstep pair with its reference streamed by a planner whose horizon covers the whole
/// path (lockstep runs faster than real time), written to `out`; the controller's output.
fn streamed_lockstep(scenario: &str, run_name: &str, out: &str) -> String {
    streamed_lockstep_from(scenario, scenario, run_name, out)
}

/// [`streamed_lockstep`] with the planner on its own scenario (its waypoints and period).
fn streamed_lockstep_from(planned: &str, scenario: &str, run_name: &str, out: &str) -> String {
    let mut planner = Proc::start(
        "planner",
        &[
            "--scenario",
            planned,
            "--name",
            run_name,
            "--horizon",
            "1000",
        ],
    );
    assert!(
        planner.wait_for_line("published pieces", Duration::from_secs(20)),
        "{}",
        planner.output()
    );
    let mut ctl = Proc::start(
        "controller_node",
        &[
            "--scenario",
            scenario,
            "--name",
            run_name,
            "--reference",
            "stream",
        ],
    );
    let (code, plant_out) = run(
        "plant_sim",
        &[
            "run",
            "--scenario",
            scenario,
            "--mode",
            "lockstep",
            "--no-spawn",
            "--name",
            run_name,
            "--out",
            out,
        ],
        LONG,
    );
    assert_eq!(code, 0, "{plant_out}");
    for p in [&mut ctl, &mut planner] {
        p.expect_exit(0, Duration::from_secs(5));
    }
    ctl.output()
}

/// `slew_{group}.toml` flown through its waypoints (`path = "through"`), written into `d`.
fn through_scenario(d: &TempDir, group: &str) -> String {
    let name = format!("slew_{group}");
    let toml = std::fs::read_to_string(format!("{}/{name}.toml", scenarios())).unwrap();
    let line = format!("waypoints = \"{name}.csv\"");
    assert!(toml.contains(&line), "the template changed");
    let toml = toml.replace(
        &line,
        &format!(
            "waypoints = {:?}\npath = \"through\"",
            format!("{}/{name}.csv", scenarios())
        ),
    );
    let path = d.join(&format!("{name}_through.toml"));
    std::fs::write(&path, toml).unwrap();
    path
}

#[test]
fn a_streamed_lockstep_run_equals_the_same_waypoints_from_the_file_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("stream-lock");
    let cases = ["so3", "se3", "se2"].into_iter().flat_map(|group| {
        [
            (
                group.to_owned(),
                format!("{}/slew_{group}.toml", scenarios()),
            ),
            (format!("{group}-through"), through_scenario(&d, group)),
        ]
    });
    // the streamed planner a kilometre away, turned: it streams the same flight moved
    // (the moved file's flight is the original's moved: `plant_sim move --check`)
    let moved = d.join("moved");
    let (code, out) = run(
        "plant_sim",
        &[
            "move",
            "--scenario",
            &through_scenario(&d, "se3"),
            "--offset",
            "1000,-700,300",
            "--heading",
            "0.7",
            "--out",
            &moved,
            "--check",
        ],
        LONG,
    );
    assert_eq!(code, 0, "{out}");
    let cases = cases.chain([(
        "se3-through-moved".to_owned(),
        format!("{moved}/slew_se3.toml"),
    )]);
    for (group, scenario) in cases {
        let (file, streamed) = (
            d.join(&format!("{group}-file")),
            d.join(&format!("{group}-stream")),
        );
        let (code, out) = run(
            "plant_sim",
            &[
                "run",
                "--scenario",
                &scenario,
                "--mode",
                "lockstep",
                "--name",
                &format!("t-sfile-{group}"),
                "--out",
                &file,
            ],
            LONG,
        );
        assert_eq!(code, 0, "{out}");
        let ctl = streamed_lockstep(&scenario, &format!("t-stream-{group}"), &streamed);
        assert!(ctl.contains("stream started"), "{ctl}");
        assert!(
            ctl.contains("heap allocations after start-up: 0 in"),
            "the streamed reference allocates nothing per cycle:\n{ctl}"
        );
        let a = std::fs::read(format!("{file}/trajectory.csv")).unwrap();
        let b = std::fs::read(format!("{streamed}/trajectory.csv")).unwrap();
        assert!(
            a == b,
            "{group}: the streamed run's trajectory.csv differs from the file run's"
        );
    }
}

/// A streamed lockstep run of `slew_so3` is exact with a CPU hog on every core: its
/// trajectory is the simulation's, and a second run writes the same messages.log (the
/// planner's first message holds the whole path, and the log keeps no clock reading and no
/// process id).
#[test]
fn a_streamed_lockstep_run_under_a_cpu_hog_equals_the_simulation_and_its_log_repeats() {
    let _g = serial();
    let d = TempDir::new("stream-hog");
    let scenario = format!("{}/slew_so3.toml", scenarios());
    let sim = d.join("sim");
    let (code, out) = run(
        "plant_sim",
        &["sim", "--scenario", &scenario, "--out", &sim],
        LONG,
    );
    assert_eq!(code, 0, "{out}");
    let _hog = CpuHog::start();
    let (a, b) = (d.join("a"), d.join("b"));
    for out in [&a, &b] {
        streamed_lockstep(&scenario, "t-stream-hog", out);
    }
    let read = |p: String| std::fs::read(&p).unwrap_or_else(|e| panic!("{p}: {e}"));
    assert!(
        read(format!("{sim}/trajectory.csv")) == read(format!("{a}/trajectory.csv")),
        "the streamed lockstep run under the hog differs from the simulation"
    );
    assert!(
        read(format!("{a}/messages.log")) == read(format!("{b}/messages.log")),
        "two streamed lockstep runs wrote different messages.log"
    );
}

/// Waypoints one second apart, so a real-time run covers running dry and resuming in 7 s.
const KILL_CSV: &str =
    "t,rx,ry,rz\n0.5,0,0,0\n1.5,0,0,0.8\n2.5,0.6,0,0.8\n3.5,0,-0.5,0\n4.5,0.3,0.3,0\n";

fn kill_scenario(d: &TempDir) -> String {
    let toml = std::fs::read_to_string(format!("{}/slew_so3.toml", scenarios()))
        .unwrap()
        .replace("name = \"slew_so3\"", "name = \"stream_kill\"")
        .replace("duration = 16.0", "duration = 7.0")
        .replace("control_period = 0.01", "control_period = 0.001")
        .replace("plant_substeps = 10", "plant_substeps = 2")
        .replace("torque_limit = 5.0", "torque_limit = 20.0")
        .replace("kp = 2.0", "kp = 8.0")
        .replace("kd = 2.0", "kd = 6.0")
        .replace("rotation = [0.3, -0.3, 0.2]", "rotation = [0.0, 0.0, 0.0]")
        .replace("slew_so3.csv", "kill.csv");
    for want in [
        "name = \"stream_kill\"",
        "duration = 7.0",
        "control_period = 0.001",
        "plant_substeps = 2",
        "torque_limit = 20.0",
        "kp = 8.0",
        "kd = 6.0",
        "rotation = [0.0, 0.0, 0.0]",
        "kill.csv",
    ] {
        assert!(
            toml.contains(want),
            "the template changed: {want} missing in\n{toml}"
        );
    }
    std::fs::write(d.join("kill.csv"), KILL_CSV).unwrap();
    let path = d.join("kill.toml");
    std::fs::write(&path, toml).unwrap();
    path
}

/// `t` of the controller's log line containing `what` (`t = 2.501 s: ...`), in order.
fn log_times(log: &str, what: &str) -> Vec<f64> {
    log.lines()
        .filter(|l| l.contains(what))
        .filter_map(|l| l.split("t = ").nth(1)?.split(' ').next()?.parse().ok())
        .collect()
}

fn rotation(r: [f64; 3]) -> Matrix3<f64> {
    Scenario::pose::<3>(r, [0.0; 3])
}

#[test]
fn killing_the_planner_holds_the_last_pose_and_a_new_planner_resumes() {
    let _g = serial();
    // a real-time run: the hold's length and the tracking after it need the pair on time
    let Some(prio) =
        realtime_priority("killing_the_planner_holds_the_last_pose_and_a_new_planner_resumes")
    else {
        return;
    };
    let d = TempDir::new("stream-kill");
    let scenario = kill_scenario(&d);
    let out = d.join("run");
    let args = [
        "--scenario",
        &scenario,
        "--name",
        "t-stream-kill",
        "--horizon",
        "0.4",
    ];
    let mut first = Proc::start("planner", &args);
    assert!(
        first.wait_for_line("writer slot 0", Duration::from_secs(20)),
        "{}",
        first.output()
    );
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--scenario",
            &scenario,
            "--no-spawn",
            "--name",
            "t-stream-kill",
            "--out",
            &out,
            prio[0],
            prio[1],
        ],
    );
    let ctl_args = [
        "--scenario",
        &scenario,
        "--name",
        "t-stream-kill",
        "--reference",
        "stream",
        prio[0],
        prio[1],
    ];
    let mut ctl = Proc::start("controller_node", &ctl_args);
    // the pieces up to the waypoint at 2.5 s are out once the plant's clock passes 1.1 s
    assert!(
        first.wait_for_line("published pieces 0..1", Duration::from_secs(20)),
        "{}\n{}",
        first.output(),
        plant.output()
    );
    first.kill(); // SIGKILL, and reaped
    // the end of the last piece it published: where the controller runs dry (normally 2.5 s;
    // later if the plant's clock passed 1.5 s before the kill)
    let given_until = first
        .output()
        .lines()
        .filter(|l| l.contains("published pieces"))
        .filter_map(|l| {
            l.split(" .. ")
                .nth(1)?
                .split(' ')
                .next()?
                .parse::<f64>()
                .ok()
        })
        .fold(0.0f64, f64::max);
    assert!((2.5..4.5).contains(&given_until), "{}", first.output());
    assert!(
        ctl.wait_for_line("ran dry", Duration::from_secs(5)),
        "{}",
        ctl.output()
    );
    // half a second of holding before a new planner starts
    wait_for_cycles(&out, recorded_cycles(&out) + 500, LONG);
    let mut second = Proc::start("planner", &args);
    assert_eq!(
        plant.wait_timeout(LONG).and_then(|s| s.code()),
        Some(0),
        "{}",
        plant.output()
    );
    for p in [&mut ctl, &mut second] {
        p.expect_exit(0, Duration::from_secs(5));
    }
    let (log, planner_log) = (ctl.output(), second.output());
    assert!(
        planner_log.contains("writer slot 1"),
        "the killed planner's slot stays taken; the new one takes the next:\n{planner_log}"
    );
    let dry = log_times(&log, "ran dry");
    let resumed = log_times(&log, "stream resumed");
    assert_eq!(resumed.len(), 1, "{log}");
    assert!(
        dry.len() == 2
            && (given_until..given_until + 0.01).contains(&dry[0])
            && dry[0] < resumed[0]
            && resumed[0] < 4.5,
        "dry once at the end of the last piece given ({given_until} s), once at the end of the path:\n{log}"
    );

    // While dry the controller tracks a set-point at the last waypoint given: its Lyapunov
    // value, recomputed from the recorded states, must not rise.
    let s = Scenario::from_file(Path::new(&scenario)).unwrap();
    let controller: Controller<f64, So3, 3, 3> = s.controller::<So3, 3, 3>().unwrap();
    let inertia = SMatrix::from_row_slice(&s.model_inertia);
    // the waypoint at the time the given pieces end
    let held_at = KILL_CSV
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .find(|w| (w[0] - given_until).abs() < 1e-9)
        .unwrap_or_else(|| panic!("no waypoint at {given_until} s"));
    let held_pose = rotation([held_at[1], held_at[2], held_at[3]]);
    let held = PathReference::new(
        GroupPath::<f64, So3, 3, 3>::hold(held_pose).unwrap(),
        inertia,
        1e-3,
    )
    .unwrap()
    .desired();
    let csv = Csv::read(&Path::new(&out).join("trajectory.csv"));
    let t = csv.col("t");
    let q: Vec<Vec<f64>> = (0..3)
        .flat_map(|i| (0..3).map(move |j| format!("q_{i}{j}")))
        .map(|c| csv.col(&c))
        .collect();
    let v: Vec<Vec<f64>> = (0..3).map(|i| csv.col(&format!("v_{i}"))).collect();
    let at = |k: usize| {
        let qk = Matrix3::from_fn(|i, j| q[3 * i + j][k]);
        let vk = Vector3::new(v[0][k], v[1][k], v[2][k]);
        controller.compute(&qk, &vk, &held).unwrap().lyapunov.total
    };
    let hold: Vec<usize> = (0..t.len())
        .filter(|&k| t[k] >= dry[0] && t[k] < resumed[0])
        .collect();
    assert!(hold.len() > 300, "{} cycles held", hold.len());
    let l: Vec<f64> = hold.iter().map(|&k| at(k)).collect();
    let rise = l
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::NEG_INFINITY, f64::max);
    eprintln!(
        "hold from t = {} s to {} s: L from {:e} to {:e}, largest one-step change {rise:e}",
        dry[0],
        resumed[0],
        l[0],
        l[l.len() - 1]
    );
    assert!(
        rise <= 1e-9 * l[0],
        "L rose by {rise:e} (from {:e}) while holding",
        l[0]
    );
    assert!(
        l[l.len() - 1] < 0.9 * l[0],
        "L did not fall while holding: {l:?}"
    );

    // After the new planner's pieces the body tracks the rest of the path: at the end it
    // is at the last waypoint, far from the pose it held.
    let end = t.len() - 1;
    let q_end = Matrix3::from_fn(|i, j| q[3 * i + j][end]);
    let err = |r: [f64; 3]| (rotation(r).transpose() * q_end - Matrix3::identity()).norm();
    eprintln!(
        "at the end: |Rᵀ Q - I| = {:e} to the last waypoint",
        err([0.3, 0.3, 0.0])
    );
    assert!(err([0.3, 0.3, 0.0]) < 1e-2, "{}", err([0.3, 0.3, 0.0]));
    assert!((held_pose.transpose() * q_end - Matrix3::identity()).norm() > 0.5);

    // The run replays bit for bit: the recorder kept both planners' messages, and each
    // command says which the controller had taken.
    let (code, text) = run("plant_sim", &["replay", &out], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ\n"), "{text}");
    let taken = text
        .lines()
        .find_map(|l| l.strip_prefix("streamed reference: "))
        .and_then(|l| l.split(' ').next()?.parse::<u64>().ok())
        .unwrap_or_else(|| panic!("no streamed-reference line: {text}"));
    assert!(
        taken >= 2,
        "both planners' messages are handed over: {text}"
    );
}

/// A streamed run replays bit for bit from its recorded plan messages; a plan message
/// changed in the record makes replay fail at the first cycle that uses the change, and a
/// record without the plan messages is refused, naming the cycle that needs one.
#[test]
fn a_streamed_run_replays_and_a_changed_plan_message_is_caught_at_its_cycle() {
    use recorder::{PLANS_FILE, format::plans_header, read_plans};
    let _g = serial();
    let d = TempDir::new("stream-replay");
    let scenario = format!("{}/slew_so3.toml", scenarios());
    let out = d.join("run");
    streamed_lockstep(&scenario, "t-stream-replay", &out);
    let (code, text) = run("plant_sim", &["replay", &out], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ\n"), "{text}");
    assert!(text.contains("streamed reference: "), "{text}");
    // the export has a plan channel: each recorded message, at the cycle the controller
    // took it (the first, before the first answer: cycle 0)
    let (code, text) = run("plant_sim", &["export", &out, "--format", "jsonl"], LONG);
    assert_eq!(code, 0, "{text}");
    let jsonl = std::fs::read_to_string(format!("{out}/run.jsonl")).unwrap();
    let plan_text: Vec<&str> = jsonl
        .lines()
        .filter(|l| l.contains("\"topic\":\"/eqtrack/plan\""))
        .collect();
    let plan_lines: Vec<serde_json::Value> = plan_text
        .iter()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .collect();
    let plans = read_plans(Path::new(&out)).unwrap();
    assert_eq!(plan_lines.len(), plans.len(), "{plan_lines:?}");
    assert_eq!(plan_lines[0]["sequence"], 0);
    assert_eq!(plan_lines[0]["fields"]["seq"], 1);
    assert_eq!(plan_lines[0]["fields"]["taken"], true);
    // each piece's geometry: its start pose (9 entries on SO(3)) and five twists of 3, bit
    // for bit (compared as JSON text: ryu's shortest form is one text per f64, whereas
    // serde_json's default parse may round the last bit)
    let first = &plans[0].msg;
    let pieces = first.used();
    assert!(pieces.len() > 2, "{first:?}");
    let start: Vec<f64> = pieces.iter().flat_map(|w| w.start[..9].to_vec()).collect();
    let twists: Vec<f64> = pieces
        .iter()
        .flat_map(|w| (0..5).flat_map(|k| w.twist(k, 3).to_vec()))
        .collect();
    for (name, values) in [("start", &start), ("twists", &twists)] {
        let text = format!("\"{name}\":{}", serde_json::to_string(values).unwrap());
        assert!(plan_text[0].contains(&text), "{text} in {}", plan_text[0]);
    }
    assert_eq!(
        plan_lines[0]["fields"]["start"].as_array().unwrap().len(),
        9 * pieces.len()
    );
    assert_eq!(
        plan_lines[0]["fields"]["twists"].as_array().unwrap().len(),
        15 * pieces.len()
    );

    // the first message holds every piece (the planner's horizon covers the path): nudge
    // the third piece's first displacement; it starts at t0, so cycle t0/period + 1 is the
    // first whose torque changes
    assert!(!plans.is_empty());
    let mut changed = plans.clone();
    let seg = &mut changed[0].msg.segments[2];
    assert!(seg.twists[0] != 0.0, "{seg:?}");
    seg.twists[0] *= 1.0 + 1e-9;
    let t0 = seg.t0;
    let planted = d.join("planted");
    std::fs::create_dir_all(&planted).unwrap();
    for f in ["messages.log", "scenario.toml", "waypoints.csv"] {
        std::fs::copy(format!("{out}/{f}"), format!("{planted}/{f}")).unwrap();
    }
    let mut bytes = plans_header().to_vec();
    for e in &changed {
        bytes.extend_from_slice(&e.to_bytes());
    }
    std::fs::write(format!("{planted}/{PLANS_FILE}"), bytes).unwrap();
    let (code, text) = run("plant_sim", &["replay", &planted], LONG);
    assert_eq!(code, 1, "{text}");
    let s = Scenario::from_file(Path::new(&scenario)).unwrap();
    let cycle = (t0 / s.control_period).round() as u64 + 1;
    assert!(
        text.contains(&format!("first difference: cycle {cycle} ")),
        "the change shows at cycle {cycle}: {text}"
    );

    // without plans.log the streamed run cannot be checked: an error naming the cycle
    std::fs::remove_file(format!("{planted}/{PLANS_FILE}")).unwrap();
    let (code, text) = run("plant_sim", &["replay", &planted], LONG);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("cycle 0: the controller had taken plan message seq 1")
            && text.contains("cannot be checked"),
        "{text}"
    );
}

/// A planner streaming legs shorter than the controller's control period: the controller
/// refuses the plan message, counts it, says why, and holds its initial reference pose.
#[test]
fn a_streamed_leg_shorter_than_the_control_period_is_refused_and_counted() {
    let _g = serial();
    let d = TempDir::new("stream-short");
    // the planner's scenario: period 1 ms, its last leg 5 ms long (valid for it), so every
    // window it publishes holds that leg
    std::fs::write(
        d.join("short.csv"),
        "t,rx,ry,rz\n0.5,0,0,0\n1.5,0,0.3,0.2\n1.505,0,0.3,0.4\n",
    )
    .unwrap();
    let base = std::fs::read_to_string(format!("{}/slew_so3.toml", scenarios())).unwrap();
    let planner_toml = base
        .replace("control_period = 0.01", "control_period = 0.001")
        .replace("slew_so3.csv", "short.csv");
    assert!(planner_toml.contains("control_period = 0.001"));
    let planner_scenario = d.join("planner.toml");
    std::fs::write(&planner_scenario, planner_toml).unwrap();
    // the pair's scenario: period 10 ms, its own (set-point) reference
    let pair_toml = base
        .replace("duration = 16.0", "duration = 2.0")
        .replace("rotation = [0.3, -0.3, 0.2]", "rotation = [0.0, 0.0, 0.0]")
        .replace(
            "waypoints = \"slew_so3.csv\"",
            "setpoint = { rotation = [0.0, 0.0, 0.0] }",
        );
    let pair_scenario = d.join("pair.toml");
    std::fs::write(&pair_scenario, pair_toml).unwrap();
    let out = d.join("run");
    let log = streamed_lockstep_from(&planner_scenario, &pair_scenario, "t-stream-short", &out);
    let counted = |what: &str| -> Option<u64> {
        let at = log.find(what)?;
        log[..at].rsplit(' ').nth(1)?.parse().ok()
    };
    let refused = counted("plan messages refused (");
    let short = log
        .split("plan messages refused (")
        .nth(1)
        .and_then(|r| r.split(' ').next()?.parse::<u64>().ok());
    assert!(
        refused.is_some_and(|n| n >= 1) && short == refused,
        "the refusals are counted, all for the short leg:\n{log}"
    );
    assert!(!log.contains("stream started"), "{log}");
    // nothing streamed was used: the body stays at the held pose (the identity, where it
    // starts at rest), not on its way to the streamed waypoints
    let csv = Csv::read(&Path::new(&out).join("trajectory.csv"));
    let worst = csv
        .col("attitude_error")
        .iter()
        .fold(0.0f64, |a, b| a.max(*b));
    assert!(worst < 1e-12, "moved: attitude error {worst:e}");
}

#[test]
fn the_planner_refuses_what_it_cannot_stream() {
    let d = TempDir::new("stream-bad");
    let seed_like = d.join("series.toml");
    std::fs::write(
        &seed_like,
        std::fs::read_to_string(format!("{}/slew_so3.toml", scenarios()))
            .unwrap()
            .replace(
                "waypoints = \"slew_so3.csv\"",
                "setpoint = { rotation = [0.1, 0.0, 0.0] }",
            ),
    )
    .unwrap();
    let (code, out) = run("planner", &["--scenario", &seed_like], LONG);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("no pieces to stream"), "{out}");
    let (code, out) = run("planner", &["--scenario", &d.join("missing.toml")], LONG);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("missing.toml"), "{out}");
    let (code, out) = run(
        "planner",
        &[
            "--scenario",
            &format!("{}/slew_so3.toml", scenarios()),
            "--horizon",
            "0",
        ],
        LONG,
    );
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("--horizon"), "{out}");
}
