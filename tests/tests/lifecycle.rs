//! Stopping, refusing and staying allocation-free: signals to either process, configuration
//! mismatches, a plant that dies or pauses.

use pair_tests::{Csv, Proc, TempDir, plant, serial, summary, wait_for_cycles, wait_until};
use std::path::Path;
use std::time::{Duration, Instant};

/// No `controller_node` of this run is left (its process list entry, by run name).
fn controller_of_run_alive(run: &str) -> bool {
    let out = std::process::Command::new("pgrep")
        .args(["-f", &format!("controller_node.*--name {run}")])
        .output()
        .expect("pgrep");
    !out.stdout.is_empty()
}

/// SIGINT or SIGTERM once a real-time run has recorded 1.6 s: exit 128+N promptly (within
/// 5 s, generous for a loaded machine), the rows that ran written, the summary says so, the
/// spawned controller gone, the name reusable.
fn interrupt_run(sig: &str, code: i32) {
    let _g = serial();
    let d = TempDir::new(&format!("int-{sig}"));
    let name = format!("t-int-{sig}");
    let out_dir = d.join("run");
    let mut p = Proc::start(
        "plant_sim",
        &[
            "run",
            "--duration",
            "20",
            "--name",
            &name,
            "--out",
            &out_dir,
        ],
    );
    assert!(
        p.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        p.output()
    );
    wait_for_cycles(&out_dir, 1600, Duration::from_secs(60));
    p.signal(sig);
    let sent = Instant::now();
    let status = p.wait_timeout(Duration::from_secs(10));
    let took = sent.elapsed();
    let out = p.output();
    assert_eq!(status.and_then(|s| s.code()), Some(code), "{out}");
    assert!(
        took < Duration::from_secs(5),
        "took {took:?} to stop:\n{out}"
    );
    let csv = Csv::read(&Path::new(&out_dir).join("trajectory.csv"));
    let t = csv.col("t");
    assert!(
        *t.last().unwrap() >= 1.5,
        "rows up to {} s",
        t.last().unwrap()
    );
    assert!(*t.last().unwrap() < 19.0);
    let s = summary(Path::new(&out_dir));
    assert_eq!(s["interrupted"], true, "{s}");
    assert_eq!(s["signal"], format!("SIG{sig}"));
    assert_eq!(s["cycles"].as_u64().unwrap() as usize, t.len());
    assert!(Path::new(&out_dir).join("figure.png").exists());
    assert!(
        wait_until(Duration::from_secs(10), || !controller_of_run_alive(&name)),
        "a controller_node of {name} is left"
    );
    let (code, out) = plant(&[
        "run",
        "--mode",
        "lockstep",
        "--duration",
        "0.5",
        "--name",
        &name,
        "--out",
        &d.join("again"),
    ]);
    assert_eq!(code, 0, "a new run under the same name: {out}");
}

#[test]
fn sigint_stops_a_real_time_run_and_writes_what_ran() {
    interrupt_run("INT", 130);
}

#[test]
fn sigterm_stops_a_real_time_run_and_writes_what_ran() {
    interrupt_run("TERM", 143);
}

/// A real-time `plant_sim run --no-spawn` of `seconds` under `run` writing to `out`, and a
/// `controller_node` started by hand beside it, once the plant reports the connection.
fn start_pair(run: &str, seconds: &str, out: &str) -> (Proc, Proc) {
    let p = Proc::start(
        "plant_sim",
        &[
            "run",
            "--no-spawn",
            "--duration",
            seconds,
            "--name",
            run,
            "--out",
            out,
        ],
    );
    let ctl = Proc::start("controller_node", &["--name", run]);
    assert!(
        p.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        p.output()
    );
    (p, ctl)
}

#[test]
fn sigterm_to_the_controller_makes_it_leave_and_the_plant_goes_to_safe_mode() {
    let _g = serial();
    let d = TempDir::new("ctl-term");
    let out_dir = d.join("run");
    let (mut p, mut ctl) = start_pair("t-ctl-term", "3", &out_dir);
    wait_for_cycles(&out_dir, 1000, Duration::from_secs(60));
    ctl.signal("TERM");
    ctl.expect_exit(0, Duration::from_secs(10));
    assert!(
        ctl.output().contains("SIGTERM received, leaving the run"),
        "{}",
        ctl.output()
    );
    let status = p.wait_timeout(Duration::from_secs(20));
    let out = p.output();
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(0),
        "the plant finishes its run:\n{out}"
    );
    assert!(out.contains("entering SAFE MODE"), "{out}");
    let csv = Csv::read(&Path::new(&out_dir).join("trajectory.csv"));
    let st = csv.col("command_status");
    // the last fresh command before the end of the run, then held, held, safe (3 periods)
    let last_fresh = st.iter().rposition(|s| *s == 0.0).expect("fresh commands");
    assert!(last_fresh < 2500, "commands went on until row {last_fresh}");
    assert_eq!(&st[last_fresh + 1..=last_fresh + 3], &[1.0, 1.0, 2.0]);
    assert!(
        st[last_fresh + 3..].iter().all(|s| *s == 2.0),
        "safe mode to the end"
    );
}

/// Both processes exit non-zero within 2 s, each naming both sides' settings.
fn mismatch(ctl_args: &[&str], needle: &str) {
    let _g = serial();
    let d = TempDir::new("mismatch");
    let mut p = Proc::start(
        "plant_sim",
        &[
            "run",
            "--no-spawn",
            "--builtin",
            "seed",
            "--name",
            "t-mismatch",
            "--out",
            &d.join("r"),
        ],
    );
    assert!(
        p.wait_for_line("waiting up to", Duration::from_secs(20)),
        "{}",
        p.output()
    );
    let mut args = vec!["--name", "t-mismatch"];
    args.extend_from_slice(ctl_args);
    let started = Instant::now();
    let mut ctl = Proc::start("controller_node", &args);
    let pc = p
        .wait_timeout(Duration::from_secs(5))
        .and_then(|s| s.code());
    let cc = ctl
        .wait_timeout(Duration::from_secs(5))
        .and_then(|s| s.code());
    let took = started.elapsed();
    let (po, co) = (p.output(), ctl.output());
    assert_eq!(pc, Some(2), "plant:\n{po}");
    assert_eq!(cc, Some(2), "controller:\n{co}");
    assert!(took < Duration::from_secs(2), "took {took:?}\n{po}\n{co}");
    for out in [&po, &co] {
        assert!(out.contains(needle), "missing `{needle}`:\n{out}");
        assert!(out.contains("plant: group so3"), "{out}");
    }
}

#[test]
fn a_controller_of_another_group_stops_both_sides() {
    mismatch(&["--builtin", "se3_circle"], "controller: group se3");
}

#[test]
fn a_controller_with_another_scenario_of_the_same_group_stops_both_sides() {
    mismatch(&["--builtin", "montecarlo"], "scenario `montecarlo`");
}

/// The controller's allocation count after start-up, from its last line.
fn allocations(out: &str) -> u64 {
    let tail = out
        .split("heap allocations after start-up: ")
        .nth(1)
        .unwrap_or_else(|| panic!("no allocation count in:\n{out}"));
    tail.split_whitespace().next().unwrap().parse().unwrap()
}

#[test]
fn the_controller_allocates_nothing_when_the_plant_is_killed() {
    let _g = serial();
    let d = TempDir::new("alloc-kill");
    let out_dir = d.join("r");
    let (mut p, mut ctl) = start_pair("t-alloc-kill", "30", &out_dir);
    wait_for_cycles(&out_dir, 1000, Duration::from_secs(60));
    p.kill();
    let out = ctl.expect_exit(1, Duration::from_secs(5));
    assert!(out.contains("is gone"), "{out}");
    assert_eq!(allocations(&out), 0, "{out}");
}

#[test]
fn the_controller_allocates_nothing_when_the_plant_pauses() {
    let _g = serial();
    let d = TempDir::new("alloc-pause");
    let out_dir = d.join("r");
    let (mut p, mut ctl) = start_pair("t-alloc-pause", "3", &out_dir);
    wait_for_cycles(&out_dir, 800, Duration::from_secs(60));
    p.signal("STOP");
    std::thread::sleep(Duration::from_millis(500));
    p.signal("CONT");
    assert_eq!(
        p.wait_timeout(Duration::from_secs(20))
            .and_then(|s| s.code()),
        Some(0),
        "{}",
        p.output()
    );
    let status = ctl.wait_timeout(Duration::from_secs(5));
    let out = ctl.output();
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(0),
        "the run went on:\n{out}"
    );
    assert!(out.contains("the plant ended the run"), "{out}");
    assert_eq!(allocations(&out), 0, "{out}");
}
