//! Run-time parameters (`plant_sim run --tunable`, `plant_sim param`), driven as real
//! processes: a change takes effect at the cycle it reports, replay repeats it bit for bit
//! and catches a planted one, bad values are refused with the scenario's own messages, and
//! another user cannot change a gain. Tests run one at a time ([`serial`]).

use pair_tests::{Proc, TempDir, load_scenario, run, scenario, serial, summary, wait_for_cycles};
use std::path::Path;
use std::time::Duration;

/// `plant_sim param --name RUN ARGS...`: exit code and output.
fn param(run_name: &str, args: &[&str]) -> (i32, String) {
    let mut all = vec!["param", "--name", run_name];
    all.extend_from_slice(args);
    run("plant_sim", &all, Duration::from_secs(60))
}

/// `plant_sim replay DIR`: exit code and output.
fn replay(dir: &str) -> (i32, String) {
    run("plant_sim", &["replay", dir], Duration::from_secs(120))
}

fn lines(path: &str) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .lines()
        .map(str::to_owned)
        .collect()
}

fn copy_dir(from: &str, to: &str) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), Path::new(to).join(e.file_name())).unwrap();
    }
}

/// A lockstep plant with `--tunable` and no controller yet (`--no-spawn`), waiting for one
/// with state 0 published.
fn waiting_plant(name: &str, out: &str, extra: &[&str]) -> Proc {
    let mut args = vec![
        "run",
        "--mode",
        "lockstep",
        "--tunable",
        "--no-spawn",
        "--name",
        name,
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    let plant = Proc::start("plant_sim", &args);
    assert!(
        plant.wait_for_line("waiting up to", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
    plant
}

/// Edits `dir/params.log` with `edit` on its text.
fn plant_in_params(dir: &str, edit: impl Fn(&str) -> String) {
    let path = Path::new(dir).join("params.log");
    let text = std::fs::read_to_string(&path).unwrap();
    let edited = edit(&text);
    assert_ne!(text, edited, "the planted change must change the file");
    std::fs::write(&path, edited).unwrap();
}

/// A lockstep run of the seed with `--tunable`, the controller started by the test: the
/// controller is stopped (SIGSTOP) after 2 000 cycles, `param set kd 0.8` is sent, the
/// controller goes on. The change takes effect at the cycle `param` prints, which is also
/// the cycle of `params.log` and the summary; the trajectory equals a run without the change
/// up to that cycle and differs from it there; replay gives 0 differ; a planted cycle or
/// value in `params.log` makes replay fail, naming the cycle.
#[test]
fn param_set_in_lockstep_takes_effect_at_a_known_cycle_and_replays() {
    let _s = serial();
    let d = TempDir::new("params-lockstep");
    let (out, base) = (d.join("tuned"), d.join("base"));
    let mut plant = waiting_plant("tp-lock", &out, &["--duration", "300"]);
    let mut ctl = Proc::start(
        "controller_node",
        &["--name", "tp-lock", "--builtin", "seed"],
    );
    wait_for_cycles(&out, 2000, Duration::from_secs(60));
    ctl.signal("STOP");
    std::thread::sleep(Duration::from_millis(100));
    let setter = std::thread::spawn(|| param("tp-lock", &["set", "kd", "0.8"]));
    std::thread::sleep(Duration::from_millis(300));
    ctl.signal("CONT");
    let (code, said) = setter.join().unwrap();
    assert_eq!(code, 0, "{said}");
    let cycle: u64 = said
        .split("from cycle ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no cycle in `{said}`"));
    assert!(said.contains("controller.kd = 0.8 (was 0.5)"), "{said}");
    assert!(
        cycle > 2000,
        "{cycle}: the controller was stopped after 2000 cycles"
    );
    plant.expect_exit(0, Duration::from_secs(120));
    let _ = ctl.wait_timeout(Duration::from_secs(10));
    // recorded: params.log and the summary name the same cycle
    let log = recorder::read_params(Path::new(&out)).unwrap();
    assert_eq!(log.len(), 1);
    assert_eq!(
        (log[0].cycle, log[0].key.as_str(), log[0].value.as_str()),
        (cycle, "controller.kd", "0.8")
    );
    let changes = &summary(Path::new(&out))["parameter_changes"];
    assert_eq!(changes[0]["cycle"].as_u64(), Some(cycle), "{changes}");
    // the same run without the change: equal up to the cycle, different from it on
    let (code, said) = run(
        "plant_sim",
        &[
            "run",
            "--mode",
            "lockstep",
            "--name",
            "tp-base",
            "--duration",
            "300",
            "--out",
            &base,
        ],
        Duration::from_secs(300),
    );
    assert_eq!(code, 0, "{said}");
    let (tuned, plain) = (
        lines(&format!("{out}/trajectory.csv")),
        lines(&format!("{base}/trajectory.csv")),
    );
    let row = cycle as usize + 1; // the header is line 0
    assert_eq!(
        tuned[..row],
        plain[..row],
        "rows before cycle {cycle} must not change"
    );
    assert_ne!(
        tuned[row], plain[row],
        "the torque of cycle {cycle} must change"
    );
    // replay applies the change at its cycle: bit for bit
    let (code, said) = replay(&out);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains(" 0 differ"), "{said}");
    // the MCAP export has the change on its parameters channel, at the cycle's time
    let (code, said) = run("plant_sim", &["export", &out], Duration::from_secs(120));
    assert_eq!(code, 0, "{said}");
    let bytes = std::fs::read(Path::new(&out).join("run.mcap")).unwrap();
    let params: Vec<_> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == "/eqtrack/params")
        .collect();
    assert_eq!(params.len(), 1);
    assert_eq!(
        params[0].log_time,
        cycle * 10_000_000,
        "t_k of cycle {cycle} in ns"
    );
    assert_eq!(
        params[0].channel.schema.as_ref().map(|s| s.name.as_str()),
        Some("eqtrack_msgs/msg/Param")
    );
    // a planted cycle: the commands between the two cycles differ
    let moved = d.join("moved");
    copy_dir(&out, &moved);
    plant_in_params(&moved, |t| {
        t.replace(
            &format!("\"cycle\":{cycle},"),
            &format!("\"cycle\":{},", cycle + 5),
        )
    });
    let (code, said) = replay(&moved);
    assert_eq!(code, 1, "{said}");
    assert!(said.contains(&format!("first at cycle {cycle} ")), "{said}");
    // a planted value (with its numbers, so only the commands can tell)
    let valued = d.join("valued");
    copy_dir(&out, &valued);
    plant_in_params(&valued, |t| t.replace("0.8", "0.9"));
    let (code, said) = replay(&valued);
    assert_eq!(code, 1, "{said}");
    assert!(said.contains(&format!("first at cycle {cycle} ")), "{said}");
    // params.log gone: replay says so instead of reporting the differences
    let gone = d.join("gone");
    copy_dir(&out, &gone);
    std::fs::remove_file(Path::new(&gone).join("params.log")).unwrap();
    let (code, said) = replay(&gone);
    assert_ne!(code, 0, "{said}");
    assert!(
        said.contains("params.log") && said.contains("missing"),
        "{said}"
    );
    // a planted value alone: its numbers disagree, refused naming the cycle
    let bare = d.join("bare");
    copy_dir(&out, &bare);
    plant_in_params(&bare, |t| {
        t.replace("\"value\":\"0.8\"", "\"value\":\"0.7\"")
    });
    let (code, said) = replay(&bare);
    assert_ne!(code, 0, "{said}");
    assert!(
        said.contains(&format!("the change at cycle {cycle}")),
        "{said}"
    );
}

/// The message the scenario file itself gets for `[controller] key = value`, after its
/// origin.
fn file_message(key: &str, value: toml::Value) -> String {
    let text = std::fs::read_to_string(scenario("seed")).unwrap();
    let mut table: toml::Table = toml::from_str(&text).unwrap();
    table["controller"]
        .as_table_mut()
        .unwrap()
        .insert(key.into(), value);
    let e = ::scenario::Scenario::from_toml(&toml::to_string(&table).unwrap(), "file", "seed")
        .unwrap_err()
        .to_string();
    e.strip_prefix("file: ").unwrap_or(&e).to_owned()
}

/// `param set kp -1`, `nosuchkey 1` and `kd NaN` are refused (exit 2) with the scenario's
/// own messages, and the run goes on untouched: it ends with no change, and its trajectory
/// equals the simulation's.
#[test]
fn bad_param_values_are_refused_with_the_scenarios_messages_and_the_run_goes_on() {
    let _s = serial();
    let d = TempDir::new("params-bad");
    let out = d.join("run");
    let mut plant = waiting_plant("tp-bad", &out, &[]);
    let (code, said) = param("tp-bad", &["set", "kp", "-1"]);
    assert_eq!(code, 2, "{said}");
    let want = file_message("kp", toml::Value::Float(-1.0));
    assert!(
        said.contains(&want),
        "`{said}` lacks the scenario's `{want}`"
    );
    let (code, said) = param("tp-bad", &["set", "kd", "NaN"]);
    assert_eq!(code, 2, "{said}");
    let want = file_message("kd", toml::Value::Float(f64::NAN));
    assert!(
        said.contains(&want),
        "`{said}` lacks the scenario's `{want}`"
    );
    let (code, said) = param("tp-bad", &["set", "nosuchkey", "1"]);
    assert_eq!(code, 2, "{said}");
    assert!(said.contains("unknown field `nosuchkey`"), "{said}");
    let (code, said) = param("tp-bad", &["get", "kd"]);
    assert_eq!((code, said.trim()), (0, "controller.kd = 0.5"));
    // the run goes on, untouched
    let mut ctl = Proc::start(
        "controller_node",
        &["--name", "tp-bad", "--builtin", "seed"],
    );
    plant.expect_exit(0, Duration::from_secs(120));
    let _ = ctl.wait_timeout(Duration::from_secs(10));
    let changes = &summary(Path::new(&out))["parameter_changes"];
    assert_eq!(changes.as_array().map(Vec::len), Some(0), "{changes}");
    let sim = d.join("sim");
    let (code, said) = run(
        "plant_sim",
        &["sim", "--out", &sim],
        Duration::from_secs(120),
    );
    assert_eq!(code, 0, "{said}");
    assert_eq!(
        lines(&format!("{out}/trajectory.csv")),
        lines(&format!("{sim}/trajectory.csv")),
        "a run whose changes were all refused equals the simulation"
    );
    assert!(
        !plant.output().contains("parameter controller"),
        "{}",
        plant.output()
    );
}

/// Another user (`nobody`, through `setpriv`) cannot change a gain: iceoryx2's files and
/// shared memory are the run's user's only. The gain stays as it was.
#[test]
fn another_users_param_set_is_refused() {
    let _s = serial();
    let uid = std::process::Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .unwrap_or_default();
    assert_eq!(
        uid, "0",
        "this test switches to the user nobody with setpriv, which needs root (CI runs as root)"
    );
    let d = TempDir::new("params-user");
    let out = d.join("run");
    let mut plant = waiting_plant("tp-user", &out, &[]);
    let bin = pair_tests::bin("plant_sim");
    let other = std::process::Command::new("setpriv")
        .args(["--reuid=nobody", "--regid=nogroup", "--clear-groups"])
        .arg(&bin)
        .args(["param", "--name", "tp-user", "set", "kd", "0.7"])
        .output()
        .expect("setpriv (util-linux)");
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&other.stdout),
        String::from_utf8_lossy(&other.stderr)
    );
    assert!(
        !other.status.success(),
        "another user changed a gain: {said}"
    );
    assert!(said.contains("parameter service"), "{said}");
    // what keeps it out: the run's shared memory is its user's alone (no group or other
    // bits), whatever layer refused it first
    let shm: Vec<_> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            // iceoryx2's one global node counter (16 bytes, shared by every user's nodes by
            // design) is world-writable; every service's memory is not
            name.starts_with("iox2_") && !name.ends_with(".global_mgmt")
        })
        .collect();
    assert!(!shm.is_empty(), "no iceoryx2 shared memory in /dev/shm");
    for e in &shm {
        use std::os::unix::fs::PermissionsExt;
        let mode = e.metadata().unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "{:?} is mode {mode:o}", e.path());
    }
    // as the run's own user it works, and the gain was not changed by the other one
    let (code, said) = param("tp-user", &["get", "kd"]);
    assert_eq!((code, said.trim()), (0, "controller.kd = 0.5"));
    plant.kill();
    assert!(
        !plant.output().contains("parameter controller.kd"),
        "{}",
        plant.output()
    );
}

/// A real-time run with sensors: `kd` and the complementary filter's `k_P` change while it
/// runs at 1 kHz; each takes effect at a cycle boundary for everything it touches, and
/// replay repeats the commands and the estimator's output bit for bit.
#[test]
fn gains_and_estimator_gains_change_in_real_time_and_replay() {
    let _s = serial();
    let d = TempDir::new("params-rt");
    let out = d.join("run");
    let file = scenario("sensors_so3");
    let _ = load_scenario("sensors_so3");
    let mut plant = Proc::start(
        "plant_sim",
        &[
            "run",
            "--tunable",
            "--name",
            "tp-rt",
            "--duration",
            "4",
            "--scenario",
            &file,
            "--out",
            &out,
        ],
    );
    wait_for_cycles(&out, 500, Duration::from_secs(30));
    // mid-flight, a bad value is refused and changes nothing
    let (code, said) = param("tp-rt", &["set", "kd", "NaN"]);
    assert_eq!(code, 2, "{said}");
    let (code, said) = param("tp-rt", &["set", "kd", "0.8"]);
    assert_eq!(code, 0, "{said}");
    let (code, said) = param("tp-rt", &["set", "estimator.kp", "2.0"]);
    assert_eq!(code, 0, "{said}");
    plant.expect_exit(0, Duration::from_secs(60));
    assert!(
        plant.output().contains("parameter changes: 2"),
        "{}",
        plant.output()
    );
    // a change costs the loops no allocation
    let s = summary(Path::new(&out));
    assert_eq!(s["plant_loop_heap_allocations"].as_u64(), Some(0), "{s}");
    assert_eq!(s["controller_heap_allocations"].as_u64(), Some(0), "{s}");
    let log = recorder::read_params(Path::new(&out)).unwrap();
    assert_eq!(
        log.iter().map(|c| c.key.as_str()).collect::<Vec<_>>(),
        ["controller.kd", "estimator.kp"]
    );
    assert!(
        log[0].cycle < log[1].cycle && log[0].cycle >= 500,
        "{log:?}"
    );
    let (code, said) = replay(&out);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains(" 0 differ"), "{said}");
    assert!(
        said.contains("estimates checked, 0 differ"),
        "the estimator must be checked too: {said}"
    );
}
