//! The processor-in-the-loop serial link as the plant's transport (docs/pil.md): each state
//! goes out as a `eqtrack-serial-wire` frame (numbers in `f32`, as the firmware computes), each
//! command frame comes back as a [`CommandMsg`], so the plant's loop, its deadline policy and
//! its outputs are those of the iceoryx2 pair.
//!
//! The handshake: before its first state the plant sends its `Hello` (group, control period,
//! scenario fingerprint and name); the firmware answers its own `Hello`, or `Refused` with the
//! mismatch bits, which reaches the plant as the pair's refusal. A firmware that resets
//! greets again unasked; the transport answers with its `Hello` and the run goes on (the
//! plant has held its last command, then entered safe mode, meanwhile). A frame the CRC (or
//! COBS, or the version) refuses is counted and dropped: the plant sees a missing command.

use crate::LinkError;
use crate::transport::Transport;
use eqtrack_serial_wire::{
    CommandFrame, Deframer, Estimate, Frame, Hello, MAX_ENCODED, Samples, StateFrame, encode,
};
use ipc_types::{CommandMsg, Identity, StateMsg, WireGroup, flags};
use std::io::{self, Read, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Where the firmware is: `tcp:HOST:PORT` (QEMU's UART on a socket) or `serial:PATH` (a
/// board's serial port, such as `/dev/ttyACM0`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SerialTarget {
    /// A TCP socket.
    Tcp(String),
    /// A serial device, set to raw mode at the given baud rate.
    Device(PathBuf, u32),
}

impl std::str::FromStr for SerialTarget {
    type Err = String;
    fn from_str(text: &str) -> Result<SerialTarget, String> {
        if let Some(addr) = text.strip_prefix("tcp:") {
            if addr
                .rsplit_once(':')
                .is_none_or(|(h, p)| h.is_empty() || p.parse::<u16>().is_err())
            {
                return Err(format!("`{text}`: expected tcp:HOST:PORT"));
            }
            return Ok(SerialTarget::Tcp(addr.to_owned()));
        }
        if let Some(rest) = text.strip_prefix("serial:") {
            let (path, baud) = match rest.rsplit_once('@') {
                Some((p, b)) => (
                    p,
                    b.parse::<u32>()
                        .map_err(|_| format!("`{text}`: `{b}` is not a baud rate"))?,
                ),
                None => (rest, 115_200),
            };
            if path.is_empty() {
                return Err(format!("`{text}`: expected serial:PATH[@BAUD]"));
            }
            return Ok(SerialTarget::Device(PathBuf::from(path), baud));
        }
        Err(format!(
            "`{text}`: expected tcp:HOST:PORT or serial:PATH[@BAUD]"
        ))
    }
}

/// A byte stream to the firmware.
pub trait ByteLink: Send {
    /// Writes all of `bytes`.
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what has arrived, without waiting (`Ok(0)`: nothing yet).
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<usize>;
    /// Sleeps until bytes may have arrived or `timeout` passes.
    fn wait_readable(&mut self, timeout: Duration);
}

fn poll_in(fd: std::os::fd::BorrowedFd<'_>, timeout: Duration) {
    use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
    let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
    let mut fds = [PollFd::new(fd, PollFlags::POLLIN)];
    let _ = poll(
        &mut fds,
        PollTimeout::try_from(ms.max(0)).unwrap_or(PollTimeout::ZERO),
    );
}

fn read_nonblocking(r: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    match r.read(buf) {
        Ok(0) => Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            "the firmware closed the link",
        )),
        Ok(n) => Ok(n),
        Err(e)
            if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted =>
        {
            Ok(0)
        }
        Err(e) => Err(e),
    }
}

struct Tcp(std::net::TcpStream);

impl ByteLink for Tcp {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.0.set_nonblocking(false)?;
        let r = Write::write_all(&mut self.0, bytes);
        self.0.set_nonblocking(true)?;
        r
    }
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        read_nonblocking(&mut self.0, buf)
    }
    fn wait_readable(&mut self, timeout: Duration) {
        use std::os::fd::AsFd;
        poll_in(self.0.as_fd(), timeout);
    }
}

struct Device(std::fs::File);

impl ByteLink for Device {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        let mut left = bytes;
        while !left.is_empty() {
            match self.0.write(left) {
                Ok(n) => left = &left[n..],
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_micros(100))
                }
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self.0.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(0),
            Err(e) => Err(e),
        }
    }
    fn wait_readable(&mut self, timeout: Duration) {
        use std::os::fd::AsFd;
        poll_in(self.0.as_fd(), timeout);
    }
}

fn baud(rate: u32) -> Option<nix::sys::termios::BaudRate> {
    use nix::sys::termios::BaudRate::*;
    Some(match rate {
        9600 => B9600,
        19200 => B19200,
        38400 => B38400,
        57600 => B57600,
        115_200 => B115200,
        230_400 => B230400,
        460_800 => B460800,
        921_600 => B921600,
        1_000_000 => B1000000,
        2_000_000 => B2000000,
        _ => return None,
    })
}

/// Opens the byte stream to `target`: a TCP connection (no Nagle delay), or the serial
/// device in raw mode (8N1, no flow control) at its baud rate.
pub fn connect(target: &SerialTarget) -> Result<Box<dyn ByteLink>, LinkError> {
    let fail = |what: String, e: io::Error| LinkError::Serial { what, source: e };
    match target {
        SerialTarget::Tcp(addr) => {
            let s = std::net::TcpStream::connect(addr)
                .map_err(|e| fail(format!("connecting to the firmware at tcp:{addr}"), e))?;
            s.set_nodelay(true)
                .and_then(|_| s.set_nonblocking(true))
                .map_err(|e| fail(format!("setting up tcp:{addr}"), e))?;
            Ok(Box::new(Tcp(s)))
        }
        SerialTarget::Device(path, rate) => {
            use nix::sys::termios::{SetArg, cfmakeraw, cfsetspeed, tcgetattr, tcsetattr};
            use std::os::unix::fs::OpenOptionsExt;
            let shown = path.display().to_string();
            let speed = baud(*rate).ok_or_else(|| {
                fail(
                    format!("serial:{shown}"),
                    io::Error::new(
                        io::ErrorKind::InvalidInput,
                        format!("unsupported baud rate {rate}"),
                    ),
                )
            })?;
            let f = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(nix::libc::O_NOCTTY | nix::libc::O_NONBLOCK)
                .open(path)
                .map_err(|e| fail(format!("opening serial:{shown}"), e))?;
            let mut t = tcgetattr(&f)
                .map_err(|e| fail(format!("reading serial:{shown}'s settings"), e.into()))?;
            cfmakeraw(&mut t);
            cfsetspeed(&mut t, speed)
                .map_err(|e| fail(format!("setting serial:{shown}'s speed"), e.into()))?;
            tcsetattr(&f, SetArg::TCSANOW, &t)
                .map_err(|e| fail(format!("setting serial:{shown} to raw mode"), e.into()))?;
            Ok(Box::new(Device(f)))
        }
    }
}

/// What the link has counted, shared with whoever reports it.
#[derive(Debug, Default)]
pub struct SerialCounts {
    /// Frames the CRC, COBS or the version check refused (corrupted on the line).
    pub corrupt: AtomicU64,
    /// Frames that decoded but were not expected (a command before the handshake, …).
    pub unexpected: AtomicU64,
    /// Times the firmware greeted unasked (it reset) and was greeted back.
    pub resets: AtomicU64,
    /// Commands received.
    pub commands: AtomicU64,
}

/// Test hook: before every frame it sends, the transport writes a burst of noise (0 to 31
/// pseudo-random bytes from this seed, then a zero that ends it): the firmware must drop
/// the bursts and still decode every frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineNoise(pub u64);

/// Test hook: flip one bit of the `n`th frame received (from 1: the firmware's `Hello` is
/// the first, the command of state k the (k + 2)th in a run without losses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CorruptCommand(pub u64);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Greeting {
    None,
    Sent,
    Accepted,
    /// The firmware refused the plant's identity: the run ends, nothing is greeted again.
    Refused,
}

/// The plant's side of the serial link, as a [`Transport`].
pub struct SerialTransport {
    link: Box<dyn ByteLink>,
    deframer: Deframer,
    inbox: std::collections::VecDeque<CommandMsg>,
    greeting: Greeting,
    hello: Option<Hello>,
    group: u32,
    counts: Arc<SerialCounts>,
    corrupt: Option<CorruptCommand>,
    noise: Option<LineNoise>,
    frames_seen: u64,
    out: [u8; MAX_ENCODED],
    error: Option<io::Error>,
    onboard: Option<OnboardSlot>,
    /// The firmware's local origin: the states' positions go out relative to it.
    origin: [f64; 3],
}

/// What the plant and a controller that estimates on board exchange beside the pair's
/// messages: the sensors' samples of the state about to go out, and the estimate the last
/// command came back with (docs/pil.md, "Sensors and vehicles").
#[derive(Debug, Default)]
pub struct Onboard {
    /// The samples for state `seq` (set by the plant before it publishes it).
    pub samples: Option<(u64, Samples)>,
    /// The estimate command `seq` came back with.
    pub estimate: Option<(u64, Estimate)>,
}

/// The plant's and the transport's shared [`Onboard`].
pub type OnboardSlot = Arc<std::sync::Mutex<Onboard>>;

fn hello_of(id: &Identity) -> Hello {
    let mut scenario = heapless::String::<32>::new();
    for c in ipc_types::name_str(&id.scenario).chars() {
        if scenario.push(c).is_err() {
            break;
        }
    }
    Hello {
        group: id.group as u8,
        period: id.period,
        fingerprint: id.fingerprint,
        scenario,
    }
}

fn identity_of(h: &Hello) -> Identity {
    let group = if h.group == 2 {
        WireGroup::Se3
    } else {
        WireGroup::So3
    };
    let mut id = Identity::new(group, h.period, h.fingerprint, &h.scenario);
    id.group = u32::from(h.group);
    id
}

/// `f64`s as the frame's `f32`s (rounded to nearest, as the firmware's inputs are).
fn narrow<const C: usize>(xs: &[f64]) -> heapless::Vec<f32, C> {
    xs.iter().take(C).map(|x| *x as f32).collect()
}

/// The state as a frame: `Q` (n², row-major), `V` and the applied wrench (m), and the
/// reaction wheels' speeds, in `f32`; on SE(3) the position relative to `origin` (the
/// firmware's local origin), the difference formed in `f64` before the cast.
pub fn state_frame(msg: &StateMsg, origin: &[f64; 3]) -> StateFrame {
    let (n, m) = if msg.group == WireGroup::Se3.code() {
        (4, 6)
    } else {
        (3, 3)
    };
    let mut q = [0.0; 16];
    q[..n * n].copy_from_slice(&msg.q[..n * n]);
    if n == 4 {
        for (i, o) in origin.iter().enumerate() {
            q[i * 4 + 3] -= o;
        }
    }
    StateFrame {
        seq: msg.seq,
        t: msg.t,
        q: narrow(&q[..n * n]),
        v: narrow(&msg.v[..m]),
        applied: narrow(&msg.applied[..m]),
        samples: None,
        wheel_speeds: narrow(msg.wheel_speeds()),
    }
}

/// Whether an estimate has the group's lengths (n² and m) and finite numbers.
fn estimate_fits(e: &Estimate, group: u32) -> bool {
    let (n, m) = if group == WireGroup::Se3.code() {
        (4, 6)
    } else {
        (3, 3)
    };
    e.q.len() == n * n
        && e.v.len() == m
        && e.q.iter().chain(&e.v).chain(&e.bias).all(|x| x.is_finite())
}

/// The command frame as the pair's command message of `group` (numbers widened to `f64`);
/// `None` when its vectors are not the group's length.
pub fn command_msg(c: &CommandFrame, group: u32) -> Option<CommandMsg> {
    let (wire, m) = if group == WireGroup::Se3.code() {
        (WireGroup::Se3, 6)
    } else {
        (WireGroup::So3, 3)
    };
    let terms_ok = |n: usize| n == 0 || n == m;
    if c.tau.len() != m || !terms_ok(c.observer.len()) || !terms_ok(c.integral.len()) {
        return None;
    }
    let mut msg = CommandMsg::new(wire);
    msg.seq = c.seq;
    msg.law = eqtrack_controller::Law::ALL
        .get(usize::from(c.law))
        .map_or(u32::MAX, |l| crate::wire::law_code(*l));
    let widen = |out: &mut [f64], xs: &[f32]| {
        for (o, x) in out.iter_mut().zip(xs) {
            *o = f64::from(*x);
        }
    };
    widen(&mut msg.tau, &c.tau);
    widen(&mut msg.observer, &c.observer);
    widen(&mut msg.integral, &c.integral);
    msg.lyapunov = f64::from(c.lyapunov);
    if let Some(a) = &c.allocation {
        let m_ok = |xs: &[f32]| xs.len() == m;
        if !m_ok(&a.demand) || !m_ok(&a.achieved) || !m_ok(&a.accounted) {
            return None;
        }
        msg.actuators = a.u_cmd.len() as u32;
        msg.alloc_status = u32::from(a.status);
        widen(&mut msg.demand, &a.demand);
        widen(&mut msg.achieved, &a.achieved);
        widen(&mut msg.accounted, &a.accounted);
        widen(&mut msg.u_cmd, &a.u_cmd);
    }
    // the detector's cycle as the pair's command carries it; the plant's check of the
    // command refuses values that do not fit (an actuator past the count, an unknown kind)
    if let Some(d) = &c.detection {
        msg.flags |= ipc_types::flags::DETECTING;
        msg.alarms = d.alarms;
        msg.suspect = u32::from(d.suspect);
        msg.statistic = f64::from(d.statistic);
        msg.detected = u32::from(d.detected);
        msg.detected_kind = u32::from(d.kind);
        msg.detected_value = f64::from(d.value);
        msg.detected_refined = u32::from(d.refined);
    }
    // the failsafe manager's word; the plant's check refuses a word it never writes
    if let Some(w) = c.failsafe {
        msg.flags |= ipc_types::flags::SUPERVISED;
        msg.failsafe = w;
    }
    Some(msg)
}

impl SerialTransport {
    /// The transport over `link`; `counts` collects what it counts.
    pub fn new(
        link: Box<dyn ByteLink>,
        counts: Arc<SerialCounts>,
        corrupt: Option<CorruptCommand>,
    ) -> SerialTransport {
        SerialTransport {
            link,
            deframer: Deframer::new(),
            inbox: std::collections::VecDeque::with_capacity(16),
            greeting: Greeting::None,
            hello: None,
            group: 0,
            counts,
            corrupt,
            noise: None,
            frames_seen: 0,
            out: [0; MAX_ENCODED],
            error: None,
            onboard: None,
            origin: [0.0; 3],
        }
    }

    /// The transport of a firmware whose positions are relative to `origin` (its
    /// configuration's local origin): each state's position goes out as `x − origin`.
    pub fn with_origin(mut self, origin: [f64; 3]) -> SerialTransport {
        self.origin = origin;
        self
    }

    /// The transport of a controller that estimates on board: each state goes out with the
    /// samples the plant put in `slot` for it (and without `Q`, `V`), and each command's
    /// estimate is put back there.
    pub fn with_onboard(mut self, slot: Option<OnboardSlot>) -> SerialTransport {
        self.onboard = slot;
        self
    }

    /// The transport with line noise before every frame it sends (a test hook).
    pub fn with_noise(mut self, noise: Option<LineNoise>) -> SerialTransport {
        self.noise = noise;
        self
    }

    fn send_frame(&mut self, frame: &Frame) -> Result<(), LinkError> {
        if let Some(LineNoise(seed)) = &mut self.noise {
            let mut burst = [0u8; 32];
            // xorshift64: the same bursts for the same seed
            let mut next = || {
                *seed ^= *seed << 13;
                *seed ^= *seed >> 7;
                *seed ^= *seed << 17;
                *seed
            };
            let len = (next() % 32) as usize;
            for b in burst.iter_mut().take(len) {
                *b = next() as u8;
            }
            burst[len] = 0;
            self.link
                .write_all(&burst[..=len])
                .map_err(|e| LinkError::Serial {
                    what: "writing line noise to the firmware".to_owned(),
                    source: e,
                })?;
        }
        let n = encode(frame, &mut self.out).map_err(|e| LinkError::Serial {
            what: "encoding a serial frame".to_owned(),
            source: io::Error::new(io::ErrorKind::InvalidData, e.to_string()),
        })?;
        self.link
            .write_all(&self.out[..n])
            .map_err(|e| LinkError::Serial {
                what: "writing to the firmware".to_owned(),
                source: e,
            })
    }

    fn on_frame(&mut self, frame: Frame) {
        match frame {
            Frame::Hello(_) if self.greeting == Greeting::Sent => {
                self.greeting = Greeting::Accepted
            }
            // after a refusal the firmware may still ask to be greeted (for the state that
            // followed the refused Hello): the plant is ending the run, so it is not greeted
            Frame::Hello(_) if self.greeting == Greeting::Refused => {
                self.counts.unexpected.fetch_add(1, Ordering::Relaxed);
            }
            Frame::Hello(_) => {
                // the firmware greets unasked: it has reset; greet it again
                self.counts.resets.fetch_add(1, Ordering::Relaxed);
                if let Some(h) = self.hello.clone() {
                    self.greeting = Greeting::Sent;
                    if self.send_frame(&Frame::Hello(h)).is_err() {
                        self.greeting = Greeting::None;
                    }
                }
            }
            Frame::Refused { mismatch, identity } => {
                self.greeting = Greeting::Refused;
                let id = identity_of(&identity);
                self.inbox
                    .push_back(CommandMsg::refusal(&id, 0, u32::from(mismatch)));
            }
            Frame::Command(c) if self.greeting == Greeting::Accepted => {
                match command_msg(&c, self.group) {
                    Some(msg) if self.inbox.len() < self.inbox.capacity() => {
                        self.counts.commands.fetch_add(1, Ordering::Relaxed);
                        self.inbox.push_back(msg);
                        // the estimate of a command the transport passes on (the plant's
                        // own checks follow; a command they refuse is a missing one, and
                        // the row keeps the last estimate)
                        if let (Some(slot), Some(e)) = (&self.onboard, &c.estimate)
                            && estimate_fits(e, self.group)
                            && let Ok(mut o) = slot.lock()
                        {
                            o.estimate = Some((c.seq, e.clone()));
                        }
                    }
                    _ => {
                        self.counts.unexpected.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            Frame::Command(_) | Frame::State(_) | Frame::Bye => {
                self.counts.unexpected.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

impl Transport<StateMsg, CommandMsg> for SerialTransport {
    fn send(&mut self, msg: &StateMsg, _wake_peer: bool) -> Result<u64, LinkError> {
        let stamp = crate::clock::monotonic_ns();
        if msg.flags & flags::SHUTDOWN != 0 {
            self.send_frame(&Frame::Bye)?;
            return Ok(stamp);
        }
        if self.greeting == Greeting::None {
            let hello = hello_of(&msg.identity());
            self.group = msg.group;
            self.hello = Some(hello.clone());
            self.send_frame(&Frame::Hello(hello))?;
            self.greeting = Greeting::Sent;
        }
        let mut state = state_frame(msg, &self.origin);
        if let Some(slot) = &self.onboard
            && let Ok(o) = slot.lock()
            && let Some((seq, samples)) = &o.samples
            && *seq == msg.seq
        {
            state.samples = Some(samples.clone());
            state.q.clear();
            state.v.clear();
        }
        self.send_frame(&Frame::State(state))?;
        Ok(stamp)
    }

    fn receive(&mut self) -> Option<CommandMsg> {
        let mut buf = [0u8; 512];
        loop {
            let n = match self.link.read_some(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) => {
                    self.error.get_or_insert(e);
                    break;
                }
            };
            for b in &mut buf[..n] {
                let byte = *b;
                if byte == 0 {
                    self.frames_seen += 1;
                }
                // test hook: one flipped bit in the chosen frame (not its closing zero)
                let flipped = match self.corrupt {
                    Some(CorruptCommand(k)) if byte != 0 && self.frames_seen + 1 == k => {
                        self.corrupt = None;
                        byte ^ 0x10
                    }
                    _ => byte,
                };
                match self.deframer.push(flipped) {
                    Some(Ok(frame)) => self.on_frame(frame),
                    Some(Err(_)) => {
                        self.counts.corrupt.fetch_add(1, Ordering::Relaxed);
                    }
                    None => {}
                }
            }
        }
        self.inbox.pop_front()
    }

    fn wait(&mut self, timeout: Duration) {
        self.link.wait_readable(timeout);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse_and_bad_ones_say_what_is_expected() {
        assert_eq!(
            "tcp:127.0.0.1:5555".parse(),
            Ok(SerialTarget::Tcp("127.0.0.1:5555".to_owned()))
        );
        assert_eq!(
            "serial:/dev/ttyACM0".parse(),
            Ok(SerialTarget::Device(PathBuf::from("/dev/ttyACM0"), 115_200))
        );
        assert_eq!(
            "serial:/dev/ttyUSB1@921600".parse(),
            Ok(SerialTarget::Device(PathBuf::from("/dev/ttyUSB1"), 921_600))
        );
        for (bad, says) in [
            ("tcp:localhost", "expected tcp:HOST:PORT"),
            ("tcp::5555", "expected tcp:HOST:PORT"),
            ("tcp:host:99999", "expected tcp:HOST:PORT"),
            ("serial:", "expected serial:PATH[@BAUD]"),
            ("serial:/dev/tty@fast", "`fast` is not a baud rate"),
            (
                "udp:1.2.3.4:5",
                "expected tcp:HOST:PORT or serial:PATH[@BAUD]",
            ),
        ] {
            let e = bad.parse::<SerialTarget>().unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn an_unsupported_baud_rate_or_a_missing_device_is_an_error_naming_it() {
        let e = connect(&SerialTarget::Device(PathBuf::from("/dev/null"), 12_345))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("unsupported baud rate 12345"), "{e}");
        let e = connect(&SerialTarget::Device(
            PathBuf::from("/nonexistent/tty"),
            115_200,
        ))
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("opening serial:/nonexistent/tty"), "{e}");
        let e = connect(&SerialTarget::Tcp("127.0.0.1:1".to_owned()))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("connecting to the firmware at tcp:127.0.0.1:1"),
            "{e}"
        );
    }

    #[test]
    fn a_command_frame_of_the_wrong_length_is_not_a_command() {
        let c = CommandFrame {
            seq: 3,
            law: 0,
            tau: heapless::Vec::from_slice(&[0.5, 0.25, -1.0]).unwrap(),
            lyapunov: 0.125,
            observer: heapless::Vec::new(),
            integral: heapless::Vec::new(),
            estimate: None,
            allocation: None,
            detection: None,
            failsafe: None,
        };
        let msg = command_msg(&c, WireGroup::So3.code()).unwrap();
        assert_eq!(
            (msg.seq, msg.tau[..3].to_vec(), msg.lyapunov),
            (3, vec![0.5, 0.25, -1.0], 0.125)
        );
        assert!(
            command_msg(&c, WireGroup::Se3.code()).is_none(),
            "3 entries on SE(3)"
        );
        let mut short_terms = c.clone();
        short_terms.observer = heapless::Vec::from_slice(&[1.0]).unwrap();
        assert!(command_msg(&short_terms, WireGroup::So3.code()).is_none());
    }
}
