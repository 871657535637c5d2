//! What both binaries share about being a process: the exit codes, and stopping cleanly on
//! SIGINT or SIGTERM (docs/architecture.md, "Stopping a run").

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How a process ends; the one mapping to exit codes of both binaries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Done (0).
    Done,
    /// The work could not be done: set-up failure, time-out, peer lost (1).
    Failed,
    /// Bad input or a configuration mismatch between the two processes (2).
    BadInput,
    /// Stopped by a signal: 128 + its number (SIGINT 130, SIGTERM 143).
    Signal(StopSignal),
}

impl Exit {
    /// The exit code.
    pub fn code(self) -> u8 {
        match self {
            Exit::Done => 0,
            Exit::Failed => 1,
            Exit::BadInput => 2,
            Exit::Signal(s) => 128 + s.number() as u8,
        }
    }
}

impl From<Exit> for std::process::ExitCode {
    fn from(e: Exit) -> Self {
        std::process::ExitCode::from(e.code())
    }
}

/// The signals that ask a process to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopSignal {
    /// Ctrl-C in a terminal.
    Int,
    /// What systemd and `kill` send.
    Term,
}

impl StopSignal {
    /// The signal's number.
    pub fn number(self) -> i32 {
        match self {
            StopSignal::Int => signal_hook::consts::SIGINT,
            StopSignal::Term => signal_hook::consts::SIGTERM,
        }
    }

    /// `SIGINT` or `SIGTERM`.
    pub fn name(self) -> &'static str {
        match self {
            StopSignal::Int => "SIGINT",
            StopSignal::Term => "SIGTERM",
        }
    }
}

impl std::fmt::Display for StopSignal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Set when SIGINT or SIGTERM arrives: loops poll it and stop at their next step instead of
/// dying mid-write. Cloning shares the flag. Polling is one atomic load (no allocation).
#[derive(Debug, Clone)]
pub struct StopFlag(Arc<AtomicUsize>);

impl StopFlag {
    /// Installs the handlers (once per process is enough; every call shares one flag).
    pub fn install() -> std::io::Result<StopFlag> {
        static FLAG: std::sync::OnceLock<Arc<AtomicUsize>> = std::sync::OnceLock::new();
        let flag = FLAG.get_or_init(|| Arc::new(AtomicUsize::new(0)));
        for sig in [StopSignal::Int, StopSignal::Term] {
            signal_hook::flag::register_usize(
                sig.number(),
                Arc::clone(flag),
                sig.number() as usize,
            )?;
        }
        Ok(StopFlag(Arc::clone(flag)))
    }

    /// A flag no signal sets (for library callers that stop otherwise).
    pub fn never() -> StopFlag {
        StopFlag(Arc::new(AtomicUsize::new(0)))
    }

    /// The signal that asked to stop, if one did.
    pub fn requested(&self) -> Option<StopSignal> {
        match self.0.load(Ordering::Relaxed) as i32 {
            0 => None,
            n if n == StopSignal::Term.number() => Some(StopSignal::Term),
            _ => Some(StopSignal::Int),
        }
    }
}

/// Whether the process `pid` exists: `kill(pid, 0)`, no allocation. 0 (unknown) and ids that
/// do not fit a pid count as alive; a stopped (SIGSTOP) process is alive; one that exited and
/// was reaped is not.
pub fn process_alive(pid: u32) -> bool {
    use nix::errno::Errno;
    use nix::sys::signal::kill;
    use nix::unistd::Pid;
    match i32::try_from(pid) {
        Ok(p) if p > 0 => !matches!(kill(Pid::from_raw(p), None), Err(Errno::ESRCH)),
        _ => true,
    }
}

/// Sends stop signal `sig` to process `pid` (a child this process started, to pass on a
/// SIGINT/SIGTERM it was sent); false if it could not be sent (no such process).
pub fn signal_process(pid: u32, sig: StopSignal) -> bool {
    use nix::sys::signal::{Signal, kill};
    use nix::unistd::Pid;
    let signal = match sig {
        StopSignal::Int => Signal::SIGINT,
        StopSignal::Term => Signal::SIGTERM,
    };
    match i32::try_from(pid) {
        Ok(p) if p > 0 => kill(Pid::from_raw(p), signal).is_ok(),
        _ => false,
    }
}

/// Writes one line (`args` and a newline) to standard error in a single write, formatted
/// first into a 1 KiB buffer on the stack (a longer line is cut). Two processes that share a
/// pipe (a plant and the controller it spawned) then never interleave within a line, which
/// `eprintln!` allows: it writes each piece of its format separately. No allocation, so the
/// control loops may log.
pub fn log_line(args: std::fmt::Arguments) {
    use std::io::Write;
    struct Buf {
        bytes: [u8; 1024],
        len: usize,
    }
    impl std::fmt::Write for Buf {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            // keep what fits, cut at a character boundary; one byte is kept for the newline
            let room = self.bytes.len() - 1 - self.len;
            let mut n = s.len().min(room);
            while !s.is_char_boundary(n) {
                n -= 1;
            }
            self.bytes[self.len..self.len + n].copy_from_slice(&s.as_bytes()[..n]);
            self.len += n;
            Ok(())
        }
    }
    let mut buf = Buf {
        bytes: [0; 1024],
        len: 0,
    };
    let _ = std::fmt::Write::write_fmt(&mut buf, args);
    buf.bytes[buf.len] = b'\n';
    let _ = std::io::stderr().write_all(&buf.bytes[..=buf.len]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_follow_the_shell_convention() {
        assert_eq!(Exit::Done.code(), 0);
        assert_eq!(Exit::Failed.code(), 1);
        assert_eq!(Exit::BadInput.code(), 2);
        assert_eq!(Exit::Signal(StopSignal::Int).code(), 130);
        assert_eq!(Exit::Signal(StopSignal::Term).code(), 143);
    }

    #[test]
    fn a_signal_sets_the_flag() {
        let flag = StopFlag::install().unwrap();
        assert_eq!(flag.requested(), None);
        nix::sys::signal::raise(nix::sys::signal::Signal::SIGTERM).unwrap();
        assert_eq!(flag.requested(), Some(StopSignal::Term));
        assert_eq!(StopFlag::never().requested(), None);
    }

    #[test]
    fn liveness_of_a_process() {
        assert!(process_alive(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!process_alive(pid), "a reaped child is gone");
        assert!(process_alive(0), "unknown counts as alive");
    }

    #[test]
    fn a_stop_signal_is_passed_on_to_a_child() {
        use std::os::unix::process::ExitStatusExt;
        let mut child = std::process::Command::new("sleep")
            .arg("10")
            .spawn()
            .unwrap();
        assert!(signal_process(child.id(), StopSignal::Term));
        assert_eq!(child.wait().unwrap().signal(), Some(15));
        assert!(
            !signal_process(child.id(), StopSignal::Int),
            "a reaped child"
        );
        assert!(!signal_process(0, StopSignal::Int));
    }
}
