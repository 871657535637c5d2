//! The service manager's notification protocol (systemd's `sd_notify`; docs/pair-on-a-board.md,
//! "Watchdogs"): a process started by a manager that set `NOTIFY_SOCKET` sends `READY=1` once
//! it is ready, and, when `WATCHDOG_USEC` asks for a watchdog, `WATCHDOG=1` at least that
//! often, or the manager takes it for hung, kills it and starts it again.
//!
//! The pings come from the loop itself ([`Notifier::progress`], once per cycle), never from a
//! side thread: a thread that lives on while the loop hangs would keep a hung process alive.
//! A ping is sent at half the manager's period, as `sd_watchdog_enabled(3)` advises. On a
//! cycle where none is due, `progress` compares two integers: no allocation, no system call.
//! The socket is made and connected once, when the notifier is made.
//!
//! Without `NOTIFY_SOCKET` the notifier does nothing, so a process started by hand, by a test
//! or by `plant_sim run` behaves as before.

use std::io;
use std::os::unix::net::{SocketAddr, UnixDatagram};

/// The environment variables the manager sets.
pub const SOCKET_VAR: &str = "NOTIFY_SOCKET";
/// The watchdog's period in µs.
pub const WATCHDOG_USEC_VAR: &str = "WATCHDOG_USEC";
/// The process the watchdog is for (absent: this one).
pub const WATCHDOG_PID_VAR: &str = "WATCHDOG_PID";

/// A bad notification environment, naming the variable.
#[derive(Debug, thiserror::Error)]
pub enum NotifyError {
    /// A variable that does not hold what it must.
    #[error("{var}={value:?}: {why}")]
    Bad {
        /// The variable.
        var: &'static str,
        /// Its value.
        value: String,
        /// What is wrong.
        why: &'static str,
    },
    /// The socket `NOTIFY_SOCKET` names cannot be reached.
    #[error("{SOCKET_VAR}={path:?}: {source}")]
    Socket {
        /// Its value.
        path: String,
        /// Why.
        source: io::Error,
    },
}

/// The watchdog's settings as the manager gave them, before a socket is opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotifyEnv {
    /// `NOTIFY_SOCKET`: a path, or an abstract name after `@`.
    pub socket: Option<String>,
    /// `WATCHDOG_USEC`.
    pub watchdog_usec: Option<String>,
    /// `WATCHDOG_PID`.
    pub watchdog_pid: Option<String>,
}

impl NotifyEnv {
    /// The process's environment.
    pub fn from_process() -> Self {
        let var = |k| std::env::var(k).ok();
        NotifyEnv {
            socket: var(SOCKET_VAR),
            watchdog_usec: var(WATCHDOG_USEC_VAR),
            watchdog_pid: var(WATCHDOG_PID_VAR),
        }
    }

    /// The watchdog's period in ns for process `pid` (`None`: no watchdog asked of it): as
    /// `sd_watchdog_enabled(3)` reads it, `WATCHDOG_PID`, when set, must name `pid`.
    pub fn watchdog_ns(&self, pid: u32) -> Result<Option<u64>, NotifyError> {
        let Some(usec) = &self.watchdog_usec else {
            return Ok(None);
        };
        let bad = |var, value: &str, why| NotifyError::Bad {
            var,
            value: value.to_owned(),
            why,
        };
        if let Some(p) = &self.watchdog_pid {
            let p: u32 = p
                .parse()
                .map_err(|_| bad(WATCHDOG_PID_VAR, p, "not a process id"))?;
            if p != pid {
                return Ok(None);
            }
        }
        let us: u64 = usec
            .parse()
            .map_err(|_| bad(WATCHDOG_USEC_VAR, usec, "not a whole number of µs"))?;
        if us == 0 {
            return Err(bad(WATCHDOG_USEC_VAR, usec, "must be more than 0"));
        }
        us.checked_mul(1000)
            .map(Some)
            .ok_or_else(|| bad(WATCHDOG_USEC_VAR, usec, "too large"))
    }
}

/// Tells the manager that the process is ready and that its loop makes progress.
#[derive(Debug)]
pub struct Notifier {
    socket: Option<UnixDatagram>,
    /// Half the watchdog's period (ns).
    every_ns: Option<u64>,
    /// When the next ping is due (ns, on the caller's monotonic clock; 0: at once).
    next_ns: u64,
    sent: u64,
    failures: u64,
}

impl Notifier {
    /// A notifier that does nothing (no manager).
    pub fn off() -> Self {
        Notifier {
            socket: None,
            every_ns: None,
            next_ns: 0,
            sent: 0,
            failures: 0,
        }
    }

    /// The notifier the process's environment asks for ([`Notifier::new`]).
    pub fn from_process() -> Result<Self, NotifyError> {
        Self::new(&NotifyEnv::from_process(), std::process::id())
    }

    /// The notifier `env` asks for, for process `pid`: none without `NOTIFY_SOCKET`, pings
    /// only with a watchdog for `pid`. The socket is connected here, once.
    pub fn new(env: &NotifyEnv, pid: u32) -> Result<Self, NotifyError> {
        let Some(path) = env.socket.as_deref().filter(|p| !p.is_empty()) else {
            return Ok(Self::off());
        };
        let every_ns = env.watchdog_ns(pid)?.map(|ns| (ns / 2).max(1));
        let socket = connect(path).map_err(|source| NotifyError::Socket {
            path: path.to_owned(),
            source,
        })?;
        Ok(Notifier {
            socket: Some(socket),
            every_ns,
            next_ns: 0,
            sent: 0,
            failures: 0,
        })
    }

    /// Whether a manager listens.
    pub fn active(&self) -> bool {
        self.socket.is_some()
    }

    /// Whether the manager asked for a watchdog.
    pub fn watchdog(&self) -> bool {
        self.socket.is_some() && self.every_ns.is_some()
    }

    /// `READY=1`: start-up is over.
    pub fn ready(&mut self) -> io::Result<()> {
        self.send(b"READY=1")
    }

    /// `STOPPING=1`: the process is leaving on its own.
    pub fn stopping(&mut self) -> io::Result<()> {
        self.send(b"STOPPING=1")
    }

    /// One cycle of the loop at time `now_ns` (the caller's monotonic clock): `WATCHDOG=1`
    /// when one is due. Returns whether it sent one. Allocation-free; a system call only when
    /// a ping is due.
    pub fn progress(&mut self, now_ns: u64) -> io::Result<bool> {
        let Some(every) = self.every_ns else {
            return Ok(false);
        };
        if now_ns < self.next_ns {
            return Ok(false);
        }
        self.next_ns = now_ns.saturating_add(every);
        self.send(b"WATCHDOG=1")?;
        Ok(true)
    }

    /// [`Notifier::progress`] for a loop: the clock `now_ns` is read only when the manager
    /// asked for a watchdog (without one a pass costs one test); a ping that cannot be sent
    /// is counted, and only the first failure is handed to `warn` (a manager that misses the
    /// pings restarts the process, which is its job; the loop goes on).
    pub fn keep_alive(&mut self, now_ns: impl FnOnce() -> u64, warn: impl FnOnce(&io::Error)) {
        if !self.watchdog() {
            return;
        }
        if let Err(e) = self.progress(now_ns()) {
            self.failures += 1;
            if self.failures == 1 {
                warn(&e);
            }
        }
    }

    /// Pings that could not be sent.
    pub fn failures(&self) -> u64 {
        self.failures
    }

    /// The pings sent so far.
    pub fn pings(&self) -> u64 {
        self.sent
    }

    fn send(&mut self, msg: &[u8]) -> io::Result<()> {
        let Some(s) = &self.socket else {
            return Ok(());
        };
        s.send(msg)?;
        self.sent += u64::from(msg == b"WATCHDOG=1");
        Ok(())
    }
}

/// A datagram socket connected to `path` (a filesystem path, or `@name` in the abstract
/// namespace, as `sd_notify(3)` reads `NOTIFY_SOCKET`). Non-blocking: a manager whose queue
/// is full fails the ping (counted) rather than stalling a real-time loop in `send`.
fn connect(path: &str) -> io::Result<UnixDatagram> {
    let socket = UnixDatagram::unbound()?;
    socket.set_nonblocking(true)?;
    match path.strip_prefix('@') {
        Some(name) => {
            use std::os::linux::net::SocketAddrExt;
            socket.connect_addr(&SocketAddr::from_abstract_name(name.as_bytes())?)?;
        }
        None => socket.connect(path)?,
    }
    Ok(socket)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(socket: Option<&str>, usec: Option<&str>, pid: Option<&str>) -> NotifyEnv {
        NotifyEnv {
            socket: socket.map(str::to_owned),
            watchdog_usec: usec.map(str::to_owned),
            watchdog_pid: pid.map(str::to_owned),
        }
    }

    #[test]
    fn the_watchdog_period_is_read_as_sd_watchdog_enabled_reads_it() {
        assert_eq!(env(None, None, None).watchdog_ns(7).unwrap(), None);
        assert_eq!(
            env(None, Some("500000"), None).watchdog_ns(7).unwrap(),
            Some(500_000_000)
        );
        assert_eq!(
            env(None, Some("500000"), Some("7")).watchdog_ns(7).unwrap(),
            Some(500_000_000)
        );
        // for another process: not ours
        assert_eq!(
            env(None, Some("500000"), Some("8")).watchdog_ns(7).unwrap(),
            None
        );
        for (usec, pid, var, says) in [
            ("0", None, WATCHDOG_USEC_VAR, "more than 0"),
            ("-5", None, WATCHDOG_USEC_VAR, "whole number"),
            ("1.5", None, WATCHDOG_USEC_VAR, "whole number"),
            ("", None, WATCHDOG_USEC_VAR, "whole number"),
            ("18446744073709551615", None, WATCHDOG_USEC_VAR, "too large"),
            ("100", Some("x"), WATCHDOG_PID_VAR, "process id"),
        ] {
            let e = env(None, Some(usec), pid).watchdog_ns(7).unwrap_err();
            let text = e.to_string();
            assert!(text.starts_with(var) && text.contains(says), "{text}");
        }
    }

    proptest::proptest! {
        /// Any value of the two variables: no panic; a period exactly when `WATCHDOG_USEC` is
        /// a positive whole number of µs that fits in ns, and `WATCHDOG_PID`, when set, is a
        /// process id (another process's: no watchdog for this one).
        #[test]
        fn any_environment_is_read_or_refused_naming_the_variable(
            usec in "\\PC{0,24}|[0-9]{1,21}",
            pid in proptest::option::of("\\PC{0,8}|[0-9]{1,6}"),
        ) {
            let e = env(None, Some(&usec), pid.as_deref());
            let want_pid = pid.as_deref().map(str::parse::<u32>);
            let got = e.watchdog_ns(7);
            match (usec.parse::<u64>(), want_pid) {
                (_, Some(Err(_))) => {
                    proptest::prop_assert!(got.unwrap_err().to_string().starts_with(WATCHDOG_PID_VAR));
                }
                (_, Some(Ok(p))) if p != 7 => proptest::prop_assert_eq!(got.unwrap(), None),
                (Ok(us), _) if us > 0 && us <= u64::MAX / 1000 => {
                    proptest::prop_assert_eq!(got.unwrap(), Some(us * 1000));
                }
                _ => {
                    proptest::prop_assert!(got.unwrap_err().to_string().starts_with(WATCHDOG_USEC_VAR));
                }
            }
        }
    }

    #[test]
    fn without_a_socket_nothing_is_sent_and_nothing_fails() {
        let mut n = Notifier::new(&env(None, Some("1000"), None), 1).unwrap();
        assert!(!n.active() && !n.watchdog());
        n.ready().unwrap();
        assert!(!n.progress(u64::MAX).unwrap());
        assert_eq!(n.pings(), 0);
        let e = Notifier::new(&env(Some("/nonexistent/notify"), None, None), 1).unwrap_err();
        assert!(e.to_string().starts_with("NOTIFY_SOCKET="), "{e}");
    }

    #[test]
    fn ready_then_a_ping_each_half_period_of_progress() {
        let dir = std::env::temp_dir().join(format!("eqtrack-notify-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("notify");
        let _ = std::fs::remove_file(&path);
        let manager = UnixDatagram::bind(&path).unwrap();
        manager.set_nonblocking(true).unwrap();
        let p = path.to_str().unwrap();
        // a 1 ms watchdog: a ping at least every 0.5 ms
        let mut n = Notifier::new(&env(Some(p), Some("1000"), None), 1).unwrap();
        assert!(n.active() && n.watchdog());
        n.ready().unwrap();
        let sent: Vec<bool> = [0, 100_000, 499_999, 500_000, 700_000, 1_000_000, 1_000_001]
            .iter()
            .map(|t| n.progress(*t).unwrap())
            .collect();
        assert_eq!(sent, [true, false, false, true, false, true, false]);
        assert_eq!(n.pings(), 3);
        n.stopping().unwrap();
        let mut got = vec![];
        let mut buf = [0u8; 64];
        while let Ok(k) = manager.recv(&mut buf) {
            got.push(String::from_utf8_lossy(&buf[..k]).into_owned());
        }
        assert_eq!(
            got,
            [
                "READY=1",
                "WATCHDOG=1",
                "WATCHDOG=1",
                "WATCHDOG=1",
                "STOPPING=1"
            ]
        );
        // no watchdog asked: READY only, progress sends nothing
        let mut quiet = Notifier::new(&env(Some(p), None, None), 1).unwrap();
        quiet.ready().unwrap();
        assert!(!quiet.progress(5).unwrap());
        assert_eq!(
            manager.recv(&mut buf).map(|k| buf[..k].to_vec()).unwrap(),
            b"READY=1"
        );
        // a manager that went away: the loop goes on, the first failure is told once
        drop(manager);
        let mut told = 0;
        for t in [2_000_000, 3_000_000, 4_000_000] {
            n.keep_alive(|| t, |_| told += 1);
        }
        assert_eq!((told, n.failures(), n.pings()), (1, 3, 3));
        // an abstract socket, as systemd names them
        let name = format!("eqtrack-notify-{}", std::process::id());
        use std::os::linux::net::SocketAddrExt;
        let abs =
            UnixDatagram::bind_addr(&SocketAddr::from_abstract_name(name.as_bytes()).unwrap())
                .unwrap();
        let mut n = Notifier::new(&env(Some(&format!("@{name}")), None, None), 1).unwrap();
        n.ready().unwrap();
        assert_eq!(
            abs.recv(&mut buf).map(|k| buf[..k].to_vec()).unwrap(),
            b"READY=1"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
