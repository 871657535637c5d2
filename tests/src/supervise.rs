//! A stand-in for systemd's supervision of a `Type=notify` service with a watchdog
//! (docs/pair-on-a-board.md, "Watchdogs"), for the tests: the test machines run no systemd
//! (their process 1 is not one), so this speaks the manager's side of the `sd_notify`
//! protocol itself. It binds the socket `NOTIFY_SOCKET` names, starts the process with
//! `WATCHDOG_USEC`, arms the watchdog at `READY=1`, and, as systemd does with
//! `Restart=on-watchdog`, kills a process whose `WATCHDOG=1` pings stop for the watchdog's
//! period and starts it again after the restart delay. A process that exits on its own is
//! not started again.
//!
//! systemd sends `SIGABRT` first (`WatchdogSignal=`) and `SIGKILL` after `TimeoutAbortSec=`;
//! a process stopped with `SIGSTOP` takes neither until it is killed, so the stand-in sends
//! `SIGKILL` at once.

use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the stand-in saw, each time in seconds since it started the first process.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Supervision {
    /// When each start of the process said `READY=1`.
    pub ready: Vec<f64>,
    /// `WATCHDOG=1` pings received.
    pub pings: u64,
    /// When the watchdog ran out and the process was killed.
    pub watchdog_kills: Vec<f64>,
    /// When the process was started again.
    pub restarts: Vec<f64>,
    /// The exit codes of the starts that exited on their own.
    pub exits: Vec<Option<i32>>,
}

/// A process under the stand-in's supervision; stopping it kills the process it runs.
pub struct Supervisor {
    stop: Arc<AtomicBool>,
    pid: Arc<AtomicU32>,
    started: Instant,
    thread: Option<JoinHandle<Supervision>>,
    log: PathBuf,
}

impl Supervisor {
    /// Starts `program` with `args` under supervision: a watchdog of `watchdog` and a
    /// restart delay of `restart`. Its output goes to `dir/supervised.log`; the socket is
    /// `dir/notify`.
    pub fn start(
        program: &Path,
        args: &[&str],
        dir: &Path,
        watchdog: Duration,
        restart: Duration,
    ) -> Supervisor {
        std::fs::create_dir_all(dir).unwrap();
        let path = dir.join("notify");
        let _ = std::fs::remove_file(&path);
        let socket = UnixDatagram::bind(&path).expect("the notification socket");
        socket
            .set_read_timeout(Some(Duration::from_millis(5)))
            .unwrap();
        let log = dir.join("supervised.log");
        let stop = Arc::new(AtomicBool::new(false));
        let pid = Arc::new(AtomicU32::new(0));
        let started = Instant::now();
        let spawn = {
            let (program, log, path) = (program.to_owned(), log.clone(), path.clone());
            let args: Vec<String> = args.iter().map(|a| (*a).to_owned()).collect();
            move || -> Child {
                let out = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(&log)
                    .unwrap();
                Command::new(&program)
                    .args(&args)
                    .env("NOTIFY_SOCKET", &path)
                    .env("WATCHDOG_USEC", watchdog.as_micros().to_string())
                    .stdin(Stdio::null())
                    .stdout(out.try_clone().unwrap())
                    .stderr(out)
                    .spawn()
                    .expect("the supervised program starts")
            }
        };
        let thread = {
            let (stop, pid) = (stop.clone(), pid.clone());
            std::thread::spawn(move || {
                supervise(&socket, &spawn, (watchdog, restart), &stop, &pid, started)
            })
        };
        Supervisor {
            stop,
            pid,
            started,
            thread: Some(thread),
            log,
        }
    }

    /// The process id of the process it runs now (0: none yet).
    pub fn pid(&self) -> u32 {
        self.pid.load(Ordering::SeqCst)
    }

    /// Seconds since the first start.
    pub fn elapsed(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Sends `sig` (`STOP`, `CONT`, …) to the process it runs now.
    pub fn signal(&self, sig: &str) {
        let _ = Command::new("kill")
            .args([&format!("-{sig}"), &self.pid().to_string()])
            .status();
    }

    /// What the supervised process wrote.
    pub fn output(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Waits for the process to exit on its own (at most `timeout`), then stops supervising
    /// (killing it if it still runs) and returns what the stand-in saw.
    pub fn finish(mut self, timeout: Duration) -> Supervision {
        let until = Instant::now() + timeout;
        let thread = self.thread.take().unwrap();
        while !thread.is_finished() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(10));
        }
        self.stop.store(true, Ordering::SeqCst);
        thread.join().unwrap()
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The stand-in's loop: start, read notifications, kill on a silent watchdog, restart.
fn supervise(
    socket: &UnixDatagram,
    spawn: &dyn Fn() -> Child,
    (watchdog, restart): (Duration, Duration),
    stop: &AtomicBool,
    pid: &AtomicU32,
    started: Instant,
) -> Supervision {
    let mut seen = Supervision::default();
    let since = |at: Instant| at.duration_since(started).as_secs_f64();
    let mut child = spawn();
    pid.store(child.id(), Ordering::SeqCst);
    // the watchdog runs from READY=1 on
    let mut armed: Option<Instant> = None;
    let mut buf = [0u8; 256];
    loop {
        if stop.load(Ordering::SeqCst) {
            let _ = child.kill();
            let _ = child.wait();
            return seen;
        }
        if let Ok(k) = socket.recv(&mut buf) {
            for line in String::from_utf8_lossy(&buf[..k]).lines() {
                match line {
                    "READY=1" => {
                        seen.ready.push(since(Instant::now()));
                        armed = Some(Instant::now());
                    }
                    "WATCHDOG=1" => {
                        seen.pings += 1;
                        if armed.is_some() {
                            armed = Some(Instant::now());
                        }
                    }
                    _ => {}
                }
            }
        }
        if let Ok(Some(status)) = child.try_wait() {
            seen.exits.push(status.code());
            return seen;
        }
        if armed.is_some_and(|last| last.elapsed() > watchdog) {
            seen.watchdog_kills.push(since(Instant::now()));
            let _ = child.kill();
            let _ = child.wait();
            armed = None;
            std::thread::sleep(restart);
            child = spawn();
            pid.store(child.id(), Ordering::SeqCst);
            seen.restarts.push(since(Instant::now()));
        }
    }
}
