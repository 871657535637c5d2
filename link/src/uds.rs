//! The Unix-domain-socket baseline: the same messages, byte-encoded, over datagram sockets
//! `/tmp/eqtrack-<run>-{plant,controller}.sock`. It exists to measure iceoryx2 against what
//! most people would write first; it is not the product's transport.

use crate::transport::{Message, Transport};
use crate::{LinkError, Role, check_run_name, clock};
use std::os::fd::AsFd;
use std::os::unix::net::UnixDatagram;
use std::path::PathBuf;
use std::time::Duration;

/// The socket path of `role` in run `run`.
pub fn socket_path(run: &str, role: Role) -> PathBuf {
    std::env::temp_dir().join(format!("eqtrack-{run}-{role}.sock"))
}

/// One side's socket.
pub struct Uds<Out, In> {
    sock: UnixDatagram,
    own: PathBuf,
    peer: PathBuf,
    /// The last message sent, and whether the peer has not received it yet (no socket there).
    last: ([u8; crate::transport::MAX_ENCODED], usize),
    undelivered: bool,
    last_in: (u64, u64),
    _types: core::marker::PhantomData<(Out, In)>,
}

impl<Out: Message, In: Message> Uds<Out, In> {
    /// Binds `role`'s socket of run `run`, replacing a stale one.
    pub fn open(run: &str, role: Role) -> Result<Self, LinkError> {
        check_run_name(run)?;
        clock::precise_sleeps();
        let own = socket_path(run, role);
        let _ = std::fs::remove_file(&own);
        let io = |source| LinkError::Io {
            path: own.clone(),
            source,
        };
        let sock = UnixDatagram::bind(&own).map_err(io)?;
        sock.set_nonblocking(true).map_err(io)?;
        Ok(Uds {
            sock,
            peer: socket_path(run, role.peer()),
            own,
            last: ([0; crate::transport::MAX_ENCODED], 0),
            undelivered: false,
            last_in: (0, 0),
            _types: core::marker::PhantomData,
        })
    }

    /// Sends the last message; remembers whether the peer's socket was there.
    fn deliver(&mut self) -> Result<(), LinkError> {
        match self.sock.send_to(&self.last.0[..self.last.1], &self.peer) {
            Ok(_) => self.undelivered = false,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound
                        | std::io::ErrorKind::ConnectionRefused
                        | std::io::ErrorKind::WouldBlock
                ) =>
            {
                // no peer yet (or its queue is full): delivered again on the next receive
                self.undelivered = true;
            }
            Err(source) => {
                return Err(LinkError::Io {
                    path: self.peer.clone(),
                    source,
                });
            }
        }
        Ok(())
    }
}

impl<Out: Message, In: Message> Transport<Out, In> for Uds<Out, In> {
    fn send(&mut self, msg: &Out, _wake_peer: bool) -> Result<u64, LinkError> {
        let mut m = *msg;
        let stamp = clock::monotonic_ns();
        m.set_stamp(stamp);
        self.last.1 = m.encode(&mut self.last.0);
        self.deliver()?;
        Ok(stamp)
    }

    fn receive(&mut self) -> Option<In> {
        if self.undelivered {
            let _ = self.deliver();
        }
        let mut buf = [0u8; crate::transport::MAX_ENCODED];
        while let Ok(n) = self.sock.recv(&mut buf) {
            if let Ok(m) = In::decode(&buf[..n])
                && m.write_id() != self.last_in
            {
                self.last_in = m.write_id();
                return Some(m);
            }
        }
        None
    }

    fn wait(&mut self, timeout: Duration) {
        use nix::poll::{PollFd, PollFlags, ppoll};
        let mut fds = [PollFd::new(self.sock.as_fd(), PollFlags::POLLIN)];
        let ts = nix::sys::time::TimeSpec::from_duration(timeout);
        let _ = ppoll(&mut fds, Some(ts), None);
    }
}

impl<Out, In> Drop for Uds<Out, In> {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.own);
    }
}
