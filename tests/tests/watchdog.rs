//! Watchdogs on the host (docs/pair-on-a-board.md, "Watchdogs"): `controller_node` and
//! `plant_sim run`, each under a stand-in for systemd's supervision (`pair_tests::supervise`:
//! `Type=notify`, a watchdog, `Restart=on-watchdog`). A controller whose loop stops is killed
//! when its pings stop and started again; the plant, which pings all along and is never
//! killed, holds, goes to safe mode, greets the new controller and the run carries on to its
//! end, recorded and replayed, without a heap allocation in either loop. A side thread that pings while the loop
//! hangs keeps the hung process alive, and the check below catches it. Tests run one at a
//! time ([`serial`]).

use pair_tests::supervise::{Supervision, Supervisor};
use pair_tests::{Csv, TempDir, bin, run, serial, summary, wait_for_cycles};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

const LONG: Duration = Duration::from_secs(120);
/// `WatchdogSec=` and `RestartSec=` of the stand-in.
const WATCHDOG: Duration = Duration::from_millis(300);
const RESTART: Duration = Duration::from_millis(100);

/// What a supervised run left: what the stand-in saw, the stand-in's time of the hang (s),
/// the plant's output and its output directory.
struct Run {
    seen: Supervision,
    hung_at: f64,
    plant: String,
    out: String,
}

/// A 500 Hz real-time run of the seed, 3.5 s, with its controller under supervision started
/// with `extra`; `hang` is called once 600 cycles are recorded and returns the stand-in's
/// time of the hang. The stand-in waits `settle` for the controller to exit after the run.
fn supervised_run(
    d: &TempDir,
    name: &str,
    extra: &[&str],
    hang: impl FnOnce(&Supervisor) -> f64,
    settle: Duration,
) -> Run {
    let out = d.join("run");
    let plant = Supervisor::start(
        &bin("plant_sim"),
        &[
            "run",
            "--no-spawn",
            "--rate-hz",
            "500",
            "--duration",
            "3.5",
            "--name",
            name,
            "--out",
            &out,
        ],
        Path::new(&d.join("plant-supervisor")),
        WATCHDOG,
        RESTART,
    );
    let mut args = vec!["--name", name];
    args.extend_from_slice(extra);
    let sup = Supervisor::start(
        &bin("controller_node"),
        &args,
        Path::new(&d.join("supervisor")),
        WATCHDOG,
        RESTART,
    );
    wait_for_cycles(&out, 600, LONG);
    let hung_at = hang(&sup);
    let plant_seen = plant.finish(LONG);
    let plant_out =
        std::fs::read_to_string(Path::new(&d.join("plant-supervisor")).join("supervised.log"))
            .unwrap_or_default();
    // the plant pinged from its wait and its loop all along (at half of 300 ms: about 7 a
    // second), was never killed, and ended its run
    assert_eq!(plant_seen.ready.len(), 1, "{plant_seen:?}\n{plant_out}");
    assert!(
        plant_seen.watchdog_kills.is_empty(),
        "{plant_seen:?}\n{plant_out}"
    );
    assert_eq!(plant_seen.exits, [Some(0)], "{plant_seen:?}\n{plant_out}");
    assert!(plant_seen.pings >= 15, "{plant_seen:?}");
    let seen = sup.finish(settle);
    Run {
        seen,
        hung_at,
        plant: plant_out,
        out,
    }
}

/// The run was restarted by its watchdog as systemd would: one kill after the hang and within
/// the watchdog's period of it (plus the stand-in's 5 ms poll and a pass of the loop, 20 ms),
/// one start after the restart delay, which said `READY=1` within half a second (it opens
/// its endpoint first) and ran to the run's end (exit 0).
fn restarted(seen: &Supervision, hung_at: f64) -> Result<(), String> {
    let slack = 0.05;
    let w = WATCHDOG.as_secs_f64();
    let r = RESTART.as_secs_f64();
    match (
        &seen.watchdog_kills[..],
        &seen.restarts[..],
        &seen.ready[..],
    ) {
        ([kill], [again], [_, ready])
            if *kill > hung_at
                && *kill <= hung_at + w + slack
                && *again >= kill + r
                && *again <= kill + r + slack
                && *ready >= *again
                && *ready <= again + 0.5 => {}
        _ => return Err(format!("not restarted once by the watchdog: {seen:?}")),
    }
    if seen.exits != [Some(0)] {
        return Err(format!("the new start did not run to the end: {seen:?}"));
    }
    Ok(())
}

/// The plant's side of a restart: safe mode, then the new controller answering to the end;
/// and the log replays, the restart included.
fn carried_on(r: &Run) {
    assert!(r.plant.contains("entering SAFE MODE"), "{}", r.plant);
    assert!(r.plant.contains("leaving safe mode"), "{}", r.plant);
    let csv = Csv::read(&Path::new(&r.out).join("trajectory.csv"));
    let status = csv.col("command_status");
    // the new controller answers to the end: fresh commands in the last second (about half
    // of its 500 under CI's CPU hog on every core, nearly all without), and in its last tenth
    let fresh = |rows: usize| {
        status[status.len() - rows..]
            .iter()
            .filter(|s| **s == 0.0)
            .count()
    };
    assert!(
        fresh(500) > 150,
        "{} fresh commands in the last second",
        fresh(500)
    );
    assert!(fresh(50) > 0, "no fresh command in the last 0.1 s");
    let (code, text) = run("plant_sim", &["replay", &r.out], LONG);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");
    // pinging a live manager allocates nothing in the restarted controller's loop after its
    // first cycle (the plant's loop allocates when it greets a new controller; the run below
    // without a restart shows its pings allocate nothing)
    let s = summary(Path::new(&r.out));
    assert_eq!(s["controller_heap_allocations"], 0, "{s}");
}

#[test]
fn a_stopped_controller_is_restarted_by_its_watchdog_and_the_run_carries_on() {
    let _g = serial();
    let d = TempDir::new("watchdog-stop");
    let r = supervised_run(
        &d,
        "t-wd-stop",
        &[],
        |sup| {
            sup.signal("STOP");
            sup.elapsed()
        },
        Duration::from_secs(10),
    );
    println!("stopped at {:.3} s: {:?}", r.hung_at, r.seen);
    assert!(r.seen.pings > 10, "{:?}", r.seen);
    restarted(&r.seen, r.hung_at).unwrap();
    carried_on(&r);
}

#[test]
fn a_hung_loop_is_restarted_but_not_while_a_side_thread_pings_for_it() {
    let _g = serial();
    // the loop hangs at state 700, 1.4 s into the run, within 0.2 s of the 600 cycles
    // waited for: its pings stop and the watchdog restarts it
    let hang = |sup: &Supervisor| sup.elapsed() + 0.2;
    let d = TempDir::new("watchdog-hang");
    let r = supervised_run(
        &d,
        "t-wd-hang",
        &["--fault-hang-at", "700"],
        hang,
        Duration::from_secs(10),
    );
    println!("hung by {:.3} s: {:?}", r.hung_at, r.seen);
    restarted(&r.seen, r.hung_at).unwrap();
    carried_on(&r);
    // the same hang with a side thread that pings whatever the loop does: the hung process
    // is never restarted, the plant flies safe mode to the end, and the check fails
    let d = TempDir::new("watchdog-side");
    let r = supervised_run(
        &d,
        "t-wd-side",
        &["--fault-hang-at", "700", "--fault-side-notifier"],
        hang,
        Duration::from_millis(500),
    );
    println!("with a side thread: {:?}", r.seen);
    assert!(r.seen.watchdog_kills.is_empty(), "{:?}", r.seen);
    assert!(restarted(&r.seen, r.hung_at).is_err());
    // safe mode from the hang (state 700, and three misses) to the end
    let csv = Csv::read(&Path::new(&r.out).join("trajectory.csv"));
    let status = csv.col("command_status");
    assert!(status[705..].iter().all(|s| *s == 2.0), "{}", r.plant);
    // the plant pinged a live manager for the whole run, its loop without a heap allocation
    let s = summary(Path::new(&r.out));
    assert_eq!(s["plant_loop_heap_allocations"], 0, "{s}");
}

/// A bad notification environment stops either process at start with exit 2, naming the
/// variable: a period that is not a positive whole number of µs, a socket that is not there.
#[test]
fn a_bad_notification_environment_exits_2_naming_the_variable() {
    let d = TempDir::new("notify-env");
    let socket = Path::new(&d.join("")).join("notify");
    let _listening = std::os::unix::net::UnixDatagram::bind(&socket).unwrap();
    let socket = socket.to_str().unwrap();
    for (program, args) in [
        ("controller_node", vec!["--name", "t-notify-env"]),
        (
            "plant_sim",
            vec!["run", "--name", "t-notify-env", "--out", &d.join("run")],
        ),
    ] {
        for (vars, says) in [
            (
                vec![("NOTIFY_SOCKET", socket), ("WATCHDOG_USEC", "0")],
                "WATCHDOG_USEC=\"0\"",
            ),
            (
                vec![
                    ("NOTIFY_SOCKET", socket),
                    ("WATCHDOG_USEC", "half a second"),
                ],
                "WATCHDOG_USEC=\"half a second\"",
            ),
            (
                vec![
                    ("NOTIFY_SOCKET", socket),
                    ("WATCHDOG_USEC", "500000"),
                    ("WATCHDOG_PID", "x"),
                ],
                "WATCHDOG_PID=\"x\"",
            ),
            (
                vec![("NOTIFY_SOCKET", "/nonexistent/notify")],
                "NOTIFY_SOCKET=\"/nonexistent/notify\"",
            ),
        ] {
            let out = Command::new(bin(program))
                .args(&args)
                .envs(vars.iter().copied())
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{program} {vars:?}: {err}");
            assert!(err.contains(says), "{program} {vars:?}: {err}");
        }
    }
}
