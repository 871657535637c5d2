//! Helpers for driving the real `plant_sim` and `controller_node` binaries.
//!
//! The binaries are the ones `cargo test --workspace` builds into the same target directory
//! as this test; [`bin`] builds them that way first when this `cargo test` did not ([`build`]),
//! so `cargo test -p pair_tests` works on a fresh clone. Processes are killed and reaped when their handle drops, so a failing test leaves
//! no process behind.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

// The repository's pages with code (the README, the getting-started guide, the firmware
// guide) are doc-tested here, not in `eqtrack-controller`: a published crate holds only its
// own files. (Doc tests see this crate's dev-dependencies: eqtrack-controller, nalgebra.)

/// The guide "Using eqtrack in your firmware" (docs/firmware.md), compiled and run as doc
/// tests.
#[cfg(doctest)]
#[doc = include_str!("../../docs/firmware.md")]
pub struct FirmwareGuideDoctests;

/// The repository's README's code blocks, compiled and run as doc tests.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct ReadmeDoctests;

/// The getting-started guide's code blocks (the whole loop on SO(3)), compiled and run as doc
/// tests.
#[cfg(doctest)]
#[doc = include_str!("../../docs/getting-started.md")]
pub struct GettingStartedDoctests;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub mod build;
pub mod supervise;

static SERIAL: Mutex<()> = Mutex::new(());

/// Serialises the tests of a binary: real-time runs must not compete for the two cores.
pub fn serial() -> MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

/// The path of a workspace binary, built next to this test as `cargo test --workspace` builds
/// it (with the test-only flags; [`build`] builds it first when this `cargo test` has not).
pub fn bin(name: &str) -> PathBuf {
    build::ensure();
    let path = build::profile_dir().join(name);
    assert!(
        path.is_file(),
        "{} is missing: not a binary of this workspace (cargo test --workspace --no-run built the others)",
        path.display()
    );
    path
}

/// A running process whose stdout and stderr are collected line by line.
pub struct Proc {
    child: Option<Child>,
    lines: Arc<Mutex<Vec<String>>>,
    stdout: Arc<Mutex<Vec<String>>>,
    readers: Vec<std::thread::JoinHandle<()>>,
    /// The exit status, once waited for.
    pub status: Option<ExitStatus>,
}

impl Proc {
    /// Starts `bin(name)` with `args`.
    pub fn start(name: &str, args: &[&str]) -> Proc {
        Proc::start_path(&bin(name), args)
    }

    /// Starts the executable at `path` with `args`.
    pub fn start_path(path: &Path, args: &[&str]) -> Proc {
        let name = path.display();
        let mut child = Command::new(path)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        let lines = Arc::new(Mutex::new(Vec::new()));
        let stdout = Arc::new(Mutex::new(Vec::new()));
        let mut readers = Vec::new();
        let out = child
            .stdout
            .take()
            .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>);
        let err = child
            .stderr
            .take()
            .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>);
        for (stream, is_stdout) in [(out, true), (err, false)] {
            let Some(stream) = stream else { continue };
            let sink = Arc::clone(&lines);
            let own = Arc::clone(&stdout);
            readers.push(std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    if is_stdout {
                        own.lock()
                            .unwrap_or_else(|p| p.into_inner())
                            .push(line.clone());
                    }
                    sink.lock().unwrap_or_else(|p| p.into_inner()).push(line);
                }
            }));
        }
        Proc {
            child: Some(child),
            lines,
            stdout,
            readers,
            status: None,
        }
    }

    /// The lines printed on standard output so far.
    pub fn stdout_lines(&self) -> Vec<String> {
        self.stdout
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }

    /// Sends a signal (SIGINT, SIGTERM, SIGSTOP, SIGCONT...) to the process.
    pub fn signal(&self, sig: &str) {
        if let Some(c) = &self.child {
            let _ = Command::new("kill")
                .args([&format!("-{sig}"), &c.id().to_string()])
                .status();
        }
    }

    /// The process id.
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// Everything printed so far.
    pub fn output(&self) -> String {
        self.lines
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .join("\n")
    }

    /// Waits until a printed line contains `needle`; false after `timeout`.
    pub fn wait_for_line(&self, needle: &str, timeout: Duration) -> bool {
        let until = Instant::now() + timeout;
        while Instant::now() < until {
            if self
                .lines
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .iter()
                .any(|l| l.contains(needle))
            {
                return true;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        false
    }

    /// Waits for exit up to `timeout`; the status, or `None` if still running.
    pub fn wait_timeout(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let until = Instant::now() + timeout;
        let child = self.child.as_mut()?;
        loop {
            if let Ok(Some(s)) = child.try_wait() {
                self.status = Some(s);
                self.child = None;
                for r in self.readers.drain(..) {
                    let _ = r.join();
                }
                return Some(s);
            }
            if Instant::now() > until {
                return None;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Waits for exit up to `timeout` and asserts that the exit code is `code` (the panic
    /// shows the status and the output); returns the output.
    #[track_caller]
    pub fn expect_exit(&mut self, code: i32, timeout: Duration) -> String {
        let status = self.wait_timeout(timeout);
        let out = self.output();
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(code),
            "exit status {status:?} (None: still running after {timeout:?}):\n{out}"
        );
        out
    }

    /// SIGKILL, then reap (a zombie's iceoryx2 node would never look dead).
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            self.status = c.wait().ok();
        }
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Runs a binary to completion (at most `timeout`), returning its exit code and output.
pub fn run(name: &str, args: &[&str], timeout: Duration) -> (i32, String) {
    let mut p = Proc::start(name, args);
    let status = p.wait_timeout(timeout);
    let out = p.output();
    match status {
        Some(s) => (s.code().unwrap_or(-1), out),
        None => panic!("{name} {args:?} did not finish within {timeout:?}; output:\n{out}"),
    }
}

/// Flies scenario `file` with `plant_sim sim` and with the lockstep pair (run `t-<name>`)
/// into `d`, asserts the two `trajectory.csv` are identical byte for byte, and returns the
/// two output directories `(sim, pair)`.
pub fn sim_equals_lockstep(d: &TempDir, name: &str, file: &str) -> (String, String) {
    let long = Duration::from_secs(120);
    let (sim, pair) = (
        d.join(&format!("{name}-sim")),
        d.join(&format!("{name}-pair")),
    );
    let (code, out) = run(
        "plant_sim",
        &["sim", "--scenario", file, "--out", &sim],
        long,
    );
    assert_eq!(code, 0, "{out}");
    let run_name = format!("t-{name}");
    let args = [
        "run",
        "--scenario",
        file,
        "--mode",
        "lockstep",
        "--name",
        &run_name,
        "--out",
        &pair,
    ];
    let (code, out) = run("plant_sim", &args, long);
    assert_eq!(code, 0, "{out}");
    let a = std::fs::read(format!("{sim}/trajectory.csv")).unwrap();
    let b = std::fs::read(format!("{pair}/trajectory.csv")).unwrap();
    assert!(
        a == b,
        "{name}: the lockstep pair differs from the simulation"
    );
    (sim, pair)
}

/// The cycles a run writing to `out` has in its flight recording so far (`messages.log`'s
/// whole records; 0 before the file exists). The writer flushes after each pass, about every
/// millisecond, so this follows the plant's progress, whatever the wall clock says.
pub fn recorded_cycles(out: &str) -> u64 {
    use std::io::Read;
    let path = Path::new(out).join("messages.log");
    let mut head = [0u8; 20];
    let Ok(mut f) = std::fs::File::open(&path) else {
        return 0;
    };
    let (Ok(meta), Ok(())) = (f.metadata(), f.read_exact(&mut head)) else {
        return 0;
    };
    let at = |i: usize| {
        u64::from(u32::from_le_bytes([
            head[i],
            head[i + 1],
            head[i + 2],
            head[i + 3],
        ]))
    };
    let (header, record) = (at(12), at(16));
    if record == 0 {
        return 0;
    }
    meta.len().saturating_sub(header) / record
}

/// Waits until the run writing to `out` has recorded at least `cycles` cycles
/// ([`recorded_cycles`]); panics after `timeout` (generous: a loaded machine is slow), with
/// the count reached.
pub fn wait_for_cycles(out: &str, cycles: u64, timeout: Duration) {
    let until = Instant::now() + timeout;
    loop {
        let n = recorded_cycles(out);
        if n >= cycles {
            return;
        }
        assert!(
            Instant::now() < until,
            "{out}: {n} cycles recorded after {timeout:?}, waited for {cycles}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Waits until `done()` holds; false after `timeout`.
pub fn wait_until(timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
    let until = Instant::now() + timeout;
    while !done() {
        if Instant::now() > until {
            return false;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    true
}

/// The settings a test of real-time behaviour gives both processes of its pair: SCHED_FIFO
/// at priority 80 (`plant_sim run` passes them to the controller it starts; give them to a
/// controller started by hand too). Normal-priority work on every core (another build, a CPU
/// hog) then cannot take the pair's CPU, so what the test asserts about deadlines holds on a
/// loaded machine as on an idle one. `None`, after printing `SKIPPED: <test>: ...` with the
/// OS's refusal, where the OS refuses SCHED_FIFO: the test then returns without asserting.
pub fn realtime_priority(test: &str) -> Option<[&'static str; 2]> {
    let probe = Command::new("chrt").args(["-f", "80", "true"]).output();
    match probe {
        Ok(out) if out.status.success() => Some(["--rt-priority", "80"]),
        Ok(out) => {
            skipped(&format!(
                "{test}: SCHED_FIFO refused ({})",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
            None
        }
        Err(e) => {
            skipped(&format!("{test}: cannot try SCHED_FIFO (chrt: {e})"));
            None
        }
    }
}

/// Prints `SKIPPED: <what>` on the process's standard error, past the test harness's output
/// capture (which takes only the print macros), so a skip shows in every run's log.
pub fn skipped(what: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIPPED: {what}");
}

/// One busy loop at normal priority on every core while it lives (`yes` into /dev/null):
/// what another build or any CPU-heavy work does to the machine. Killed and reaped on drop.
pub struct CpuHog(Vec<Child>);

impl CpuHog {
    /// Starts one `yes` per core.
    pub fn start() -> CpuHog {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        CpuHog(
            (0..cores)
                .map(|_| {
                    Command::new("yes")
                        .stdout(Stdio::null())
                        .stderr(Stdio::null())
                        .spawn()
                        .expect("yes")
                })
                .collect(),
        )
    }
}

impl Drop for CpuHog {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// The path of `path` relative to the repository's root.
pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// Reads a CSV file (the project writes plain ones: no quoting) into a header and rows of
/// strings.
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap_or_default()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (header, rows)
}

/// The column `name` of a CSV read by [`read_csv`], as numbers.
pub fn column(header: &[String], rows: &[Vec<String>], name: &str) -> Vec<f64> {
    let j = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    rows.iter()
        .map(|r| {
            r[j].parse()
                .unwrap_or_else(|e| panic!("column {name}: `{}`: {e}", r[j]))
        })
        .collect()
}

/// A CSV file as a header and rows of strings.
pub struct Csv {
    /// Column names.
    pub header: Vec<String>,
    /// Rows.
    pub rows: Vec<Vec<String>>,
}

impl Csv {
    /// Reads a CSV file ([`read_csv`]).
    pub fn read(path: &Path) -> Csv {
        let (header, rows) = read_csv(path);
        Csv { header, rows }
    }

    /// A numeric column ([`fn@column`]).
    pub fn col(&self, name: &str) -> Vec<f64> {
        column(&self.header, &self.rows, name)
    }
}

/// Reads `summary.json`.
pub fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).expect("valid JSON")
}

/// A fresh temporary directory (`tempfile`'s, removed on drop), named after the test.
pub struct TempDir(tempfile::TempDir);

impl TempDir {
    /// Creates `<tmp>/eqtrack-<tag>-XXXXXX`.
    pub fn new(tag: &str) -> TempDir {
        TempDir(
            tempfile::Builder::new()
                .prefix(&format!("eqtrack-{tag}-"))
                .tempdir()
                .expect("temp dir"),
        )
    }

    /// A path inside as a string.
    pub fn join(&self, name: &str) -> String {
        self.0.path().join(name).display().to_string()
    }
}

/// The path of `scenarios/<name>.toml` in the repository.
pub fn scenario(name: &str) -> String {
    format!("{}/../scenarios/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

/// `scenarios/<name>.toml`, loaded (a test's own scenario: it must load).
pub fn load_scenario(name: &str) -> ::scenario::Scenario {
    ::scenario::Scenario::from_file(Path::new(&scenario(name)))
        .unwrap_or_else(|e| panic!("scenarios/{name}.toml: {e}"))
}

/// Runs `plant_sim args...` to completion (generous timeout for a loaded machine): its exit
/// code and output.
pub fn plant(args: &[&str]) -> (i32, String) {
    run("plant_sim", args, Duration::from_secs(300))
}

/// Scenario `name` of `scenarios/` with each `(from, to)` replaced and `extra` appended,
/// written to `dir` beside copies of the scenarios' waypoint files; returns its path.
pub fn variant(dir: &Path, name: &str, edits: &[(&str, &str)], extra: &str) -> String {
    std::fs::create_dir_all(dir).unwrap();
    for entry in std::fs::read_dir(repo("scenarios")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "csv") {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    let mut text = std::fs::read_to_string(repo(&format!("scenarios/{name}.toml"))).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{name} no longer has `{from}`");
        text = text.replacen(from, to, 1);
    }
    text.push_str(extra);
    let file = dir.join(format!("{name}-variant.toml"));
    std::fs::write(&file, text).unwrap();
    file.to_str().unwrap().to_owned()
}

/// A copy of the run in `out` (scenario, waypoints) beside `out`, whose `messages.log` has
/// the command recorded at cycle `k` changed by `edit` (handed the command and its recorded
/// bytes); returns the copy's directory.
pub fn planted_copy(
    out: &str,
    k: usize,
    edit: impl FnOnce(&mut ipc_types::CommandMsg, &[u8]),
) -> String {
    let planted = format!("{out}-planted");
    std::fs::create_dir_all(&planted).unwrap();
    for entry in std::fs::read_dir(out).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_owned();
        if path.is_file() && name != "messages.log" {
            std::fs::copy(&path, Path::new(&planted).join(name)).unwrap();
        }
    }
    let mut log = std::fs::read(format!("{out}/messages.log")).unwrap();
    let header = recorder::Header::from_bytes(&log).unwrap();
    let at = recorder::HEADER_BYTES + k * header.record_bytes() + recorder::RECORD_COMMAND_OFFSET;
    let bytes = log[at..at + ipc_types::COMMAND_BYTES].to_vec();
    let mut cmd = ipc_types::CommandMsg::from_bytes(&bytes).unwrap();
    edit(&mut cmd, &bytes);
    log[at..at + ipc_types::COMMAND_BYTES].copy_from_slice(&cmd.to_bytes());
    std::fs::write(format!("{planted}/messages.log"), log).unwrap();
    planted
}

/// A copy of every file of the run in `out` beside it (`<out>-<tag>`); returns its directory.
pub fn run_copy(out: &str, tag: &str) -> String {
    let copy = format!("{out}-{tag}");
    std::fs::create_dir_all(&copy).unwrap();
    for entry in std::fs::read_dir(out).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, Path::new(&copy).join(path.file_name().unwrap())).unwrap();
        }
    }
    copy
}

/// A copy of the run in `out` beside it (`<out>-<tag>`) whose `messages.log` lacks the
/// commands of `cycles`, as if they had come too late to be recorded; returns its directory.
pub fn without_commands(out: &str, tag: &str, cycles: &[usize]) -> String {
    let copy = run_copy(out, tag);
    let file = format!("{copy}/messages.log");
    let mut log = std::fs::read(&file).unwrap();
    let header = recorder::Header::from_bytes(&log).unwrap();
    for &k in cycles {
        let at = recorder::HEADER_BYTES + k * header.record_bytes();
        assert_eq!(log[at + 9], 1, "cycle {k} has a command");
        log[at + 9] = 0;
        let c = at + recorder::RECORD_COMMAND_OFFSET;
        log[c..c + ipc_types::COMMAND_BYTES].fill(0);
    }
    std::fs::write(file, log).unwrap();
    copy
}
