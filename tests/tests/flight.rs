//! The flight recorder (`messages.log`), `plant_sim replay` and `plant_sim monitor`, driven as
//! real processes. Tests run one at a time ([`serial`]).

use pair_tests::{
    Proc, TempDir, bin, realtime_priority, run, serial, summary, wait_for_cycles, wait_until,
};
use recorder::{
    HEADER_BYTES, LOG_FILE, LogReader, RECORD_BYTES, RECORD_STATE_OFFSET, torque_byte_offset,
};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// `plant_sim replay ARGS`: exit code and everything printed.
fn replay(args: &[&str]) -> (i32, String) {
    let mut all = vec!["replay"];
    all.extend_from_slice(args);
    run("plant_sim", &all, Duration::from_secs(120))
}

/// A lockstep run of the seed (exact, fast) into `out`, to its end.
fn lockstep_run(name: &str, out: &str, seconds: &str, extra: &[&str]) {
    let mut args = vec!["--mode", "lockstep"];
    args.extend_from_slice(extra);
    let mut plant = start_run(name, out, seconds, &args);
    plant.expect_exit(0, Duration::from_secs(60));
}

fn copy_dir(from: &str, to: &str) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), Path::new(to).join(e.file_name())).unwrap();
    }
}

/// (records, decisions seen) of a log.
fn read_log(dir: &str) -> (Vec<recorder::Record>, LogReader) {
    let mut log = LogReader::open(&Path::new(dir).join(LOG_FILE)).unwrap();
    let mut records = Vec::new();
    while let Some(r) = log.next_record().unwrap() {
        records.push(r);
    }
    (records, log)
}

/// Starts `plant_sim run --duration SECONDS --name NAME --out OUT EXTRA...` in real time.
fn start_run(name: &str, out: &str, seconds: &str, extra: &[&str]) -> Proc {
    let mut args = vec!["run", "--duration", seconds, "--name", name, "--out", out];
    args.extend_from_slice(extra);
    Proc::start("plant_sim", &args)
}

/// Waits until the plant's controller has answered (the run's clock has started).
fn connected(plant: &Proc) {
    assert!(
        plant.wait_for_line("controller connected", Duration::from_secs(20)),
        "{}",
        plant.output()
    );
}

#[test]
fn a_real_time_run_with_misses_and_safe_mode_replays_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("flight-stop");
    let out = d.join("run");
    let mut plant = start_run("t-flight-stop", &out, "3", &["--no-spawn"]);
    let ctl = Proc::start("controller_node", &["--name", "t-flight-stop"]);
    connected(&plant);
    wait_for_cycles(&out, 1000, Duration::from_secs(60));
    // 20 ms without a controller: deadline misses, then safe mode (3 misses in a row at 1 kHz)
    ctl.signal("STOP");
    std::thread::sleep(Duration::from_millis(20));
    ctl.signal("CONT");
    plant.expect_exit(0, Duration::from_secs(30));
    let s = summary(Path::new(&out));
    assert!(s["deadline_misses"].as_u64().unwrap() >= 10, "{s}");
    assert!(s["safe_mode_entries"].as_u64().unwrap() >= 1, "{s}");
    // recording allocates nothing on the plant's loop thread, and the controller nothing
    assert_eq!(s["plant_loop_heap_allocations"].as_u64(), Some(0), "{s}");
    assert_eq!(s["controller_heap_allocations"].as_u64(), Some(0), "{s}");
    // every cycle is in the log, the safe-mode ones too
    let cycles = s["cycles"].as_u64().unwrap();
    assert_eq!(s["recording"]["records"].as_u64(), Some(cycles), "{s}");
    assert_eq!(s["recording"]["dropped"].as_u64(), Some(0), "{s}");
    let (records, _) = read_log(&out);
    assert_eq!(records.len() as u64, cycles);
    let safe = records
        .iter()
        .filter(|r| r.decision == link::Decision::Safe)
        .count();
    let without = records.iter().filter(|r| r.command.is_none()).count();
    assert!(
        safe >= 5 && without >= 10,
        "safe {safe}, no command {without}"
    );
    // replay: every recorded command again, bit for bit
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    let compared = cycles - without as u64;
    assert!(
        text.contains(&format!(
            "replayed {cycles} cycles of {out}: {compared} commands compared, 0 differ"
        )),
        "{text}"
    );
}

#[test]
fn another_law_is_a_what_if_and_a_flipped_torque_byte_is_caught() {
    let _g = serial();
    let d = TempDir::new("flight-diff");
    let out = d.join("run");
    lockstep_run("t-flight-diff", &out, "2", &[]);
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains("0 differ"), "{text}");

    // what-if: another law answers the same states differently; exit 0, replay.csv + figure
    let what = d.join("what-if");
    let (code, text) = replay(&[&out, "--law", "gt", "--out", &what]);
    assert_eq!(code, 0, "{text}");
    let differ: u64 = text
        .split(" commands compared, ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count in {text}"));
    assert!(differ > 100, "{text}");
    assert!(
        text.contains("(what-if)") && text.contains("first difference: cycle"),
        "{text}"
    );
    let csv = pair_tests::Csv::read(&Path::new(&what).join("replay.csv"));
    let (rec, rep) = (csv.col("recorded_tau_1"), csv.col("replayed_tau_1"));
    assert_eq!(rec.len(), 201);
    assert!(rec.iter().zip(&rep).any(|(a, b)| (a - b).abs() > 1e-3));
    assert!(Path::new(&what).join("replay.png").exists());
    // gains too
    let (code, text) = replay(&[&out, "--kd", "4", "--out", &what]);
    assert_eq!(code, 0, "{text}");
    assert!(!text.contains(" 0 differ"), "{text}");
    let (code, text) = replay(&[&out, "--kd", "1,2", "--out", &what]);
    assert_eq!(code, 2, "{text}");
    assert!(
        text.contains("--kd") && text.contains("3 diagonal entries"),
        "{text}"
    );

    // one flipped byte in the torque of cycle 57: plain replay exits 1 naming that cycle
    let bad = d.join("corrupt");
    copy_dir(&out, &bad);
    let log = Path::new(&bad).join(LOG_FILE);
    let mut bytes = std::fs::read(&log).unwrap();
    let at = HEADER_BYTES + 57 * RECORD_BYTES + torque_byte_offset(2) + 3;
    bytes[at] ^= 0x10;
    std::fs::write(&log, bytes).unwrap();
    let (code, text) = replay(&[&bad]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("first difference: cycle 57 ") && text.contains("tau[2]"),
        "{text}"
    );
    assert!(text.contains("1 differ"), "{text}");

    // a corrupted sequence number (its top byte) is refused as the node refuses it: replay
    // neither hangs catching up nor panics, and names the cycle
    let bad = d.join("corrupt-seq");
    copy_dir(&out, &bad);
    let log = Path::new(&bad).join(LOG_FILE);
    let mut bytes = std::fs::read(&log).unwrap();
    bytes[HEADER_BYTES + 90 * RECORD_BYTES + RECORD_STATE_OFFSET + 8 + 7] ^= 0x40;
    std::fs::write(&log, bytes).unwrap();
    let (code, text) = replay(&[&bad]);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("first difference: cycle 90 ") && text.contains("would reject"),
        "{text}"
    );
    assert!(text.contains(" 1 differ"), "{text}");
}

#[test]
fn a_killed_run_replays_up_to_its_last_whole_record_and_an_interrupted_one_is_complete() {
    let _g = serial();
    let d = TempDir::new("flight-kill");
    // SIGKILL mid-run: what reached the file replays
    let out = d.join("killed");
    let mut plant = start_run("t-flight-kill", &out, "30", &[]);
    connected(&plant);
    wait_for_cycles(&out, 600, Duration::from_secs(60));
    plant.kill();
    let (records, log) = read_log(&out);
    assert!(records.len() > 500, "{} records", records.len());
    assert_eq!(log.header.run, "t-flight-kill");
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");
    // cut mid-record, as a kill during a write would
    let path = Path::new(&out).join(LOG_FILE);
    let whole = (std::fs::metadata(&path).unwrap().len() as usize - HEADER_BYTES) / RECORD_BYTES;
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len((HEADER_BYTES + (whole - 1) * RECORD_BYTES + RECORD_BYTES / 2) as u64)
        .unwrap();
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(
        text.contains(&format!(
            "note: the log ends {} bytes into a record",
            RECORD_BYTES / 2
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("replayed {} cycles", whole - 1)),
        "{text}"
    );

    // SIGTERM: the run stops, and its log holds every cycle that ran
    let out = d.join("stopped");
    let mut plant = start_run("t-flight-term", &out, "30", &[]);
    connected(&plant);
    wait_for_cycles(&out, 500, Duration::from_secs(60));
    plant.signal("TERM");
    assert!(plant.wait_timeout(Duration::from_secs(20)).is_some());
    let s = summary(Path::new(&out));
    assert_eq!(s["interrupted"], true, "{s}");
    let (records, log) = read_log(&out);
    assert_eq!(Some(records.len() as u64), s["cycles"].as_u64(), "{s}");
    assert_eq!(log.trailing_bytes, 0);
    // --no-record: no log, no recorder
    let out = d.join("unrecorded");
    lockstep_run("t-flight-none", &out, "0.5", &["--no-record"]);
    assert!(!Path::new(&out).join(LOG_FILE).exists());
    assert!(summary(Path::new(&out))["recording"].is_null());
}

/// tmux, from the system or fetched by the repository's script.
fn tmux() -> String {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/tmux.sh");
    let out = Command::new("bash").arg(script).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let last = text.lines().last().unwrap_or_default().to_owned();
    assert!(
        out.status.success() && !last.starts_with("SKIPPED") && !last.is_empty(),
        "scripts/tmux.sh could not provide tmux (the monitor's test needs a real terminal):\n{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    last
}

/// A tmux server of its own (`-L`), killed on drop.
struct Tmux {
    bin: String,
    socket: String,
}

impl Tmux {
    fn cmd(&self, args: &[&str]) -> String {
        let out = Command::new(&self.bin)
            .args(["-L", &self.socket])
            .args(args)
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
    fn capture(&self) -> String {
        self.cmd(&["capture-pane", "-p", "-t", "mon"])
    }
}

impl Drop for Tmux {
    fn drop(&mut self) {
        self.cmd(&["kill-server"]);
    }
}

/// The value after `label` on the captured screen.
fn field<'a>(screen: &'a str, label: &str) -> Option<&'a str> {
    screen
        .lines()
        .find_map(|l| l.split(label).nth(1))
        .map(|rest| rest.split_whitespace().next().unwrap_or(""))
}

fn wait_file(path: &Path, timeout: Duration) -> Option<String> {
    let until = Instant::now() + timeout;
    while Instant::now() < until {
        if let Ok(t) = std::fs::read_to_string(path)
            && !t.trim().is_empty()
        {
            return Some(t.trim().to_owned());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
}

#[test]
fn the_monitor_shows_the_live_loop_in_a_terminal_and_quits_on_q() {
    let _g = serial();
    // the rate the monitor shows is the plant's: a real-time figure
    let Some(prio) =
        realtime_priority("the_monitor_shows_the_live_loop_in_a_terminal_and_quits_on_q")
    else {
        return;
    };
    let d = TempDir::new("flight-monitor");
    let t = Tmux {
        bin: tmux(),
        socket: format!("eqtrack-test-{}", std::process::id()),
    };
    let rc = d.join("monitor.rc");
    let monitor = format!(
        "{} monitor --name t-flight-mon --wait 30; echo $? > {rc}",
        bin("plant_sim").display()
    );
    t.cmd(&[
        "new-session",
        "-d",
        "-s",
        "mon",
        "-x",
        "120",
        "-y",
        "32",
        &monitor,
    ]);
    let out = d.join("run");
    let mut plant = start_run("t-flight-mon", &out, "8", &prio);
    connected(&plant);
    let t_of = |s: &str| field(s, "│t").and_then(|x| x.parse::<f64>().ok());
    // the first screen whose run time is in `range`
    let screen_at = |range: std::ops::Range<f64>| {
        let mut screen = String::new();
        let seen = wait_until(Duration::from_secs(30), || {
            screen = t.capture();
            t_of(&screen).is_some_and(|x| x >= range.start)
        });
        assert!(seen, "no screen at t >= {}:\n{screen}", range.start);
        let at = t_of(&screen).unwrap_or(f64::NAN);
        assert!(range.contains(&at), "t = {at} is past {range:?}:\n{screen}");
        screen
    };
    // in the run's first second the rate (cycles in the last second) is still climbing
    let first = screen_at(0.2..0.9);
    let second = screen_at(1.8..7.0);
    let rate = |s: &str| field(s, "│rate").and_then(|r| r.parse::<f64>().ok());
    let (r1, r2) = (rate(&first), rate(&second));
    assert!(
        r1.is_some_and(|r| (100.0..900.0).contains(&r)),
        "rate {r1:?} on\n{first}"
    );
    assert!(
        r2.is_some_and(|r| (900.0..1100.0).contains(&r)),
        "rate {r2:?} on\n{second}"
    );
    for screen in [&first, &second] {
        assert!(
            screen.contains("eqtrack monitor: run `t-flight-mon`"),
            "{screen}"
        );
        for label in [
            "round trip",
            "p50",
            "p99",
            "max",
            "misses",
            "safe mode",
            "last command",
        ] {
            assert!(screen.contains(label), "{label} missing on\n{screen}");
        }
    }
    // the time and the Lyapunov value move
    let l = |s: &str| field(s, "│Lyapunov L").and_then(|x| x.parse::<f64>().ok());
    let (l1, l2) = (l(&first), l(&second));
    assert!(
        l1.is_some() && l2.is_some() && l1 != l2,
        "L {l1:?} -> {l2:?}"
    );
    assert!(t_of(&second) > t_of(&first), "{first}\n{second}");
    t.cmd(&["send-keys", "-t", "mon", "q"]);
    assert_eq!(
        wait_file(Path::new(&rc), Duration::from_secs(5)).as_deref(),
        Some("0"),
        "the monitor did not quit with 0 on q"
    );

    // a second monitor exits by itself when the run ends
    let rc2 = d.join("monitor2.rc");
    let monitor = format!(
        "{} monitor --name t-flight-mon --wait 30; echo $? > {rc2}",
        bin("plant_sim").display()
    );
    t.cmd(&[
        "new-session",
        "-d",
        "-s",
        "mon2",
        "-x",
        "120",
        "-y",
        "32",
        &monitor,
    ]);
    assert!(plant.wait_timeout(Duration::from_secs(30)).is_some());
    // it notices the end on its next look at the run's status; under CI's CPU hog on every
    // core, tmux and the monitor may take several seconds to get there (5 s was once short)
    assert_eq!(
        wait_file(Path::new(&rc2), Duration::from_secs(30)).as_deref(),
        Some("0"),
        "the monitor did not exit when the run ended"
    );
}

/// A controller started by hand with another law than the scenario's (`controller_node --law
/// gt` against the seed's EqT): its commands name the law (protocol 5), so replay answers each
/// state with it and finds nothing different; with the law bytes rewritten to EqT, replay
/// differs — the recorded law is what makes it pass.
#[test]
fn a_run_answered_by_a_hand_started_controller_with_another_law_replays_bit_for_bit() {
    let _g = serial();
    let d = TempDir::new("flight-law");
    let out = d.join("gt");
    let mut ctl = Proc::start(
        "controller_node",
        &["--name", "t-flight-law", "--law", "gt"],
    );
    lockstep_run("t-flight-law", &out, "2", &["--no-spawn"]);
    ctl.expect_exit(0, Duration::from_secs(10));
    let (records, log) = read_log(&out);
    assert_eq!(log.header.law, "eqt", "the plant's scenario says EqT");
    assert!(
        records
            .iter()
            .filter_map(|r| r.command.as_ref())
            .all(|(c, _)| link::wire::law_from_code(c.law) == Some(eqtrack_controller::Law::Gt)),
        "every command names GT"
    );
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");
    assert!(text.contains("computed by gt"), "{text}");
    // the law bytes rewritten to EqT: replay answers with EqT, and the commands differ
    let path = Path::new(&out).join(LOG_FILE);
    let mut bytes = std::fs::read(&path).unwrap();
    let at = recorder::RECORD_COMMAND_OFFSET + 360;
    for k in 0..records.len() {
        let base = HEADER_BYTES + k * RECORD_BYTES;
        if bytes[base + 9] != 0 {
            bytes[base + at..base + at + 4].copy_from_slice(&1u32.to_le_bytes());
        }
    }
    std::fs::write(&path, bytes).unwrap();
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 1, "{text}");
    assert!(!text.contains(" 0 differ"), "{text}");
}

/// A log written before `controller.error_frame` existed flew the papers' world frame and
/// stored a scenario without the key: it replays as it flew (its fingerprint says world). A
/// run of the default frame replays too, and its stored scenario edited to another frame is
/// refused as not the scenario the run used.
#[test]
fn a_log_from_before_error_frame_replays_as_the_world_frame_it_flew() {
    let _g = serial();
    let d = TempDir::new("flight-frame");
    let circle = std::fs::read_to_string(pair_tests::repo("scenarios/se3_circle.toml")).unwrap();
    let world = d.join("world.toml");
    std::fs::write(
        &world,
        circle.replace("[controller]", "[controller]\nerror_frame = \"world\""),
    )
    .unwrap();
    let out = d.join("world");
    lockstep_run("t-flight-frame", &out, "1", &["--scenario", &world]);
    // the stored scenario as a build from before the key wrote it: no error_frame line
    let stored = Path::new(&out).join("scenario.toml");
    let text = std::fs::read_to_string(&stored).unwrap();
    assert!(text.contains("error_frame = \"world\""), "{text}");
    std::fs::write(&stored, text.replace("error_frame = \"world\"\n", "")).unwrap();
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");

    let file = d.join("reference.toml");
    std::fs::write(&file, &circle).unwrap();
    let out = d.join("reference");
    lockstep_run("t-flight-frame", &out, "1", &["--scenario", &file]);
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 0, "{text}");
    assert!(text.contains(" 0 differ"), "{text}");
    let stored = Path::new(&out).join("scenario.toml");
    std::fs::write(
        &stored,
        circle.replace("[controller]", "[controller]\nerror_frame = \"world\""),
    )
    .unwrap();
    let (code, text) = replay(&[&out]);
    assert_eq!(code, 2, "{text}");
    assert!(text.contains("not the scenario the run used"), "{text}");
}
