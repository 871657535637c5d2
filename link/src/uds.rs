//! The Unix-domain-socket baseline: the same messages, byte-encoded, over datagram sockets
//! `/tmp/eqtrack-<run>-{plant,controller}.sock`. It exists to measure iceoryx2 against what
//! most people would write first; it is not the product's transport.

use crate::ipc::{Link, monotonic_ns};
use crate::{CommandMsg, StateMsg};
use std::cell::{Cell, RefCell};
use std::os::fd::AsFd;
use std::os::unix::net::UnixDatagram;
use std::path::PathBuf;
use std::time::Duration;

/// A message that travels as bytes.
pub trait Wire: Copy {
    /// Encodes into `buf`, returning the length.
    fn encode(&self, buf: &mut [u8; 512]) -> usize;
    /// Decodes, `None` for a malformed datagram.
    fn decode(buf: &[u8]) -> Option<Self>;
    /// `(seq, stamp_ns)`.
    fn identity(&self) -> (u64, u64);
    /// Sets the timestamp.
    fn set_stamp(&mut self, ns: u64);
}

impl Wire for StateMsg {
    fn encode(&self, buf: &mut [u8; 512]) -> usize {
        let b = self.to_bytes();
        buf[..b.len()].copy_from_slice(&b);
        b.len()
    }
    fn decode(buf: &[u8]) -> Option<Self> {
        StateMsg::from_bytes(buf)
    }
    fn identity(&self) -> (u64, u64) {
        (self.seq, self.stamp_ns)
    }
    fn set_stamp(&mut self, ns: u64) {
        self.stamp_ns = ns;
    }
}

impl Wire for CommandMsg {
    fn encode(&self, buf: &mut [u8; 512]) -> usize {
        let b = self.to_bytes();
        buf[..b.len()].copy_from_slice(&b);
        b.len()
    }
    fn decode(buf: &[u8]) -> Option<Self> {
        CommandMsg::from_bytes(buf)
    }
    fn identity(&self) -> (u64, u64) {
        (self.seq, self.stamp_ns)
    }
    fn set_stamp(&mut self, ns: u64) {
        self.stamp_ns = ns;
    }
}

/// One side's socket.
pub struct UdsLink<Out, In> {
    sock: UnixDatagram,
    own: PathBuf,
    peer: PathBuf,
    last_sent: RefCell<([u8; 512], usize)>,
    last_in: Cell<(u64, u64)>,
    _types: core::marker::PhantomData<(Out, In)>,
}

/// The socket path of a role in a run.
pub fn socket_path(run: &str, role: &str) -> PathBuf {
    std::env::temp_dir().join(format!("eqtrack-{run}-{role}.sock"))
}

impl<Out: Wire, In: Wire> UdsLink<Out, In> {
    /// Binds this side's socket (`role` is `plant` or `controller`), replacing a stale one.
    pub fn open(run: &str, role: &str) -> Result<Self, String> {
        if !crate::valid_run_name(run) {
            return Err(format!("invalid run name `{run}`"));
        }
        // precise sleeps for this baseline too
        let _ = nix::sys::prctl::set_timerslack(1);
        let other = if role == "plant" {
            "controller"
        } else {
            "plant"
        };
        let own = socket_path(run, role);
        let _ = std::fs::remove_file(&own);
        let sock =
            UnixDatagram::bind(&own).map_err(|e| format!("cannot bind {}: {e}", own.display()))?;
        sock.set_nonblocking(true)
            .map_err(|e| format!("socket: {e}"))?;
        Ok(UdsLink {
            sock,
            own,
            peer: socket_path(run, other),
            last_sent: RefCell::new(([0; 512], 0)),
            last_in: Cell::new((0, 0)),
            _types: core::marker::PhantomData,
        })
    }
}

impl<Out: Wire, In: Wire> Link<Out, In> for UdsLink<Out, In> {
    fn send(&self, msg: Out) -> u64 {
        let mut m = msg;
        let stamp = monotonic_ns();
        m.set_stamp(stamp);
        let mut last = self.last_sent.borrow_mut();
        let len = m.encode(&mut last.0);
        last.1 = len;
        // a peer that is not there yet misses it; `resend` repeats it
        let _ = self.sock.send_to(&last.0[..len], &self.peer);
        stamp
    }

    fn receive(&self) -> Option<In> {
        let mut buf = [0u8; 512];
        while let Ok(n) = self.sock.recv(&mut buf) {
            if let Some(m) = In::decode(&buf[..n])
                && m.identity() != self.last_in.get()
            {
                self.last_in.set(m.identity());
                return Some(m);
            }
        }
        None
    }

    fn notify(&self) {
        // the datagram itself wakes the peer
    }

    fn wait_notified(&self, timeout: Duration) -> bool {
        use nix::poll::{PollFd, PollFlags, ppoll};
        let mut fds = [PollFd::new(self.sock.as_fd(), PollFlags::POLLIN)];
        let ts = nix::sys::time::TimeSpec::from_duration(timeout);
        ppoll(&mut fds, Some(ts), None)
            .map(|n| n > 0)
            .unwrap_or(false)
    }

    fn wait(&self, timeout: Duration) {
        let _ = Link::<Out, In>::wait_notified(self, timeout);
    }

    fn resend(&self) {
        let last = self.last_sent.borrow();
        if last.1 > 0 {
            let _ = self.sock.send_to(&last.0[..last.1], &self.peer);
        }
    }
}

impl<Out, In> Drop for UdsLink<Out, In> {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.own);
    }
}

/// The plant's side of the baseline.
pub type PlantUds = UdsLink<StateMsg, CommandMsg>;
/// The controller's side of the baseline.
pub type ControllerUds = UdsLink<CommandMsg, StateMsg>;
