//! The WebSocket side: the listener, one session thread per client, and the hub through
//! which the poller offers each sample to the clients that subscribed to its channel.
//!
//! Nothing here can hold up the poller: it offers a sample with `try_send` to each
//! subscribed client's bounded queue and, when the queue is full, counts the sample as
//! dropped for that client. A session thread writes its queue to its socket, which is
//! non-blocking after the handshake; tungstenite's write buffer is bounded too
//! (`max_write_buffer_size`), and a write that does not fit is another drop. So a client
//! that stops reading costs at most its queue and its write buffer, whatever it does.
//!
//! A connection has [`HANDSHAKE_DEADLINE`] from its acceptance to finish its WebSocket
//! handshake, however slowly its bytes come; then it is closed. Until its handshake is done it
//! does not count against `--max-clients` (a slot is taken when the handshake is answered,
//! and refused with HTTP 503 if none is free), and at most `--max-clients` +
//! [`EXTRA_HANDSHAKES`] connections are in their handshake at once (more wait in the listen
//! backlog until one ends): idle or trickling connections cannot shut real clients out for
//! longer than the deadline.

use crate::poller::Sample;
use crate::protocol::{
    self, ChannelInfo, Incoming, Level, SessionState, choose_subprotocol, message_data,
};
use std::collections::BTreeMap;
use std::io::{self, ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::http::{HeaderValue, StatusCode};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Error as WsError, Message as WsMessage, WebSocket};

/// The largest message or frame a client may send (the bridge expects only small JSON).
pub const MAX_CLIENT_MESSAGE: usize = 64 * 1024;
/// tungstenite's write buffer: written out past this many bytes, and never larger than
/// [`MAX_WRITE_BUFFER`] (a frame that would not fit is dropped).
const WRITE_BUFFER: usize = 16 * 1024;
/// The write buffer's bound per client.
pub const MAX_WRITE_BUFFER: usize = 256 * 1024;
/// The kernel's send buffer of a client's socket (`SO_SNDBUF`; Linux doubles it for its own
/// bookkeeping). Fixed, so the kernel does not grow it to `tcp_wmem`'s maximum (4 MiB here)
/// for a client that does not read: that client's messages are dropped within a second or
/// two, rather than after many seconds of ever staler data queued in the kernel.
pub const SOCKET_SEND_BUFFER: usize = 256 * 1024;
/// A connection must finish its WebSocket handshake within this of its acceptance (the
/// whole handshake, not each read), or it is closed.
pub const HANDSHAKE_DEADLINE: Duration = Duration::from_secs(5);
/// Connections in their handshake at once: at most `--max-clients` plus this many; more
/// wait in the listen backlog (not accepted) until one ends.
pub const EXTRA_HANDSHAKES: usize = 16;
/// A session thread wakes this often: it writes what was queued since, and reads its client.
/// The messages reach the client up to this late, in one write instead of one each.
const SESSION_TICK: Duration = Duration::from_millis(10);
/// At the end, how long a session tries to hand its last messages and the close over.
const CLOSE_GRACE: Duration = Duration::from_secs(1);
/// A session reads at most this many client messages per tick.
const READS_PER_TICK: usize = 64;
/// Drops are logged (and told to the client) at most this often per client.
const DROP_REPORT_EVERY: Duration = Duration::from_secs(1);

/// What a client's queue carries.
#[derive(Debug, Clone)]
pub(crate) enum Item {
    /// A message of a channel.
    Sample(Arc<Sample>),
    /// A `status` message's level and text.
    Notice(Level, Arc<str>),
}

/// A connected client as the hub sees it.
struct Client {
    /// Its session's number.
    id: u64,
    tx: SyncSender<Item>,
    /// Bit `channel id` set: subscribed.
    mask: Arc<AtomicU32>,
    /// Samples dropped for it.
    dropped: Arc<AtomicU64>,
}

/// What the poller, the listener and the sessions share.
pub(crate) struct Shared {
    clients: Mutex<Vec<Client>>,
    /// serverInfo's metadata: the run, and once found its scenario, group and rate.
    pub(crate) metadata: Mutex<BTreeMap<String, String>>,
    /// Set once: the last word to every client, then the sessions close.
    end: Mutex<Option<(Level, String)>>,
    ending: AtomicBool,
    pub(crate) channels: Vec<ChannelInfo>,
    pub(crate) session_id: String,
    pub(crate) queue: usize,
    /// Clients past their handshake at once, at most.
    pub(crate) max_clients: usize,
    /// Session threads (in their handshake or serving).
    pub(crate) sessions: AtomicUsize,
    /// Connections in their handshake.
    pub(crate) handshakes: AtomicUsize,
    /// Clients past their handshake ([`ClientSlot`]s taken).
    open: AtomicUsize,
    pub(crate) served: AtomicU64,
    pub(crate) sent: AtomicU64,
    pub(crate) dropped: AtomicU64,
    pub(crate) offered: AtomicU64,
}

pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl Shared {
    pub(crate) fn new(
        channels: Vec<ChannelInfo>,
        metadata: BTreeMap<String, String>,
        queue: usize,
        max_clients: usize,
    ) -> Shared {
        let unix_ms = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_millis());
        Shared {
            clients: Mutex::new(Vec::new()),
            metadata: Mutex::new(metadata),
            end: Mutex::new(None),
            ending: AtomicBool::new(false),
            channels,
            session_id: format!("{}-{unix_ms}", std::process::id()),
            queue: queue.max(1),
            max_clients,
            sessions: AtomicUsize::new(0),
            handshakes: AtomicUsize::new(0),
            open: AtomicUsize::new(0),
            served: AtomicU64::new(0),
            sent: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            offered: AtomicU64::new(0),
        }
    }

    /// Whether another connection may start its handshake.
    pub(crate) fn handshake_room(&self) -> bool {
        self.handshakes.load(Ordering::Acquire) < self.max_clients + EXTRA_HANDSHAKES
    }

    /// Offers `sample` to every client subscribed to its channel: never blocks; a full
    /// queue drops it for that client (counted).
    pub(crate) fn offer(&self, sample: Arc<Sample>) {
        self.offered.fetch_add(1, Ordering::Relaxed);
        let bit = 1u32 << (sample.channel + 1);
        lock(&self.clients).retain(|c| {
            if c.mask.load(Ordering::Relaxed) & bit == 0 {
                return true;
            }
            match c.tx.try_send(Item::Sample(Arc::clone(&sample))) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    c.dropped.fetch_add(1, Ordering::Relaxed);
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            }
        });
    }

    /// A `status` message to every client (not queued for a client whose queue is full).
    pub(crate) fn notify(&self, level: Level, text: &str) {
        let text: Arc<str> = Arc::from(text);
        lock(&self.clients).retain(|c| {
            !matches!(
                c.tx.try_send(Item::Notice(level, Arc::clone(&text))),
                Err(TrySendError::Disconnected(_))
            )
        });
    }

    /// The last word: every session sends it, closes, and ends.
    pub(crate) fn finish(&self, level: Level, text: String) {
        lock(&self.end).get_or_insert((level, text));
        self.ending.store(true, Ordering::Release);
    }

    fn end_notice(&self) -> Option<(Level, String)> {
        if !self.ending.load(Ordering::Acquire) {
            return None;
        }
        lock(&self.end).clone()
    }
}

/// The handshake's answer: the client's first subprotocol of ours, or HTTP 400.
#[allow(clippy::result_large_err)] // tungstenite's callback type
fn negotiate(req: &Request, mut resp: Response) -> Result<(Response, &'static str), ErrorResponse> {
    let offered = req
        .headers()
        .get_all("Sec-WebSocket-Protocol")
        .iter()
        .filter_map(|v| v.to_str().ok());
    match choose_subprotocol(offered) {
        Some(p) => {
            resp.headers_mut()
                .insert("Sec-WebSocket-Protocol", HeaderValue::from_static(p));
            Ok((resp, p))
        }
        None => Err(refusal(
            StatusCode::BAD_REQUEST,
            format!(
                "eqtrack-live speaks the Foxglove WebSocket protocol: offer the subprotocol {} or {}\n",
                protocol::SUBPROTOCOLS[0],
                protocol::SUBPROTOCOLS[1]
            ),
        )),
    }
}

/// An HTTP refusal of a handshake, with `body` as plain text.
fn refusal(status: StatusCode, body: String) -> ErrorResponse {
    let len = HeaderValue::from_str(&body.len().to_string());
    let mut refusal = ErrorResponse::new(Some(body));
    *refusal.status_mut() = status;
    let h = refusal.headers_mut();
    h.insert("Content-Type", HeaderValue::from_static("text/plain"));
    h.insert("Connection", HeaderValue::from_static("close"));
    if let Ok(len) = len {
        h.insert("Content-Length", len);
    }
    refusal
}

fn ws_config() -> WebSocketConfig {
    WebSocketConfig::default()
        .read_buffer_size(4096)
        .write_buffer_size(WRITE_BUFFER)
        .max_write_buffer_size(MAX_WRITE_BUFFER)
        .max_message_size(Some(MAX_CLIENT_MESSAGE))
        .max_frame_size(Some(MAX_CLIENT_MESSAGE))
}

/// A client's socket, with a deadline while its handshake lasts: a read or write then waits
/// at most until the deadline, and fails (`TimedOut`) once it has passed, so the handshake
/// as a whole takes at most [`HANDSHAKE_DEADLINE`] however slowly the client's bytes come.
/// Without a deadline (after the handshake) it is the socket itself.
struct Conn {
    stream: TcpStream,
    deadline: Option<Instant>,
}

impl Conn {
    /// The time left before the deadline (`None`: no deadline), or `TimedOut`.
    fn left(&self) -> io::Result<Option<Duration>> {
        let Some(until) = self.deadline else {
            return Ok(None);
        };
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::Error::new(
                ErrorKind::TimedOut,
                "the handshake's deadline passed",
            ));
        }
        Ok(Some(left))
    }

    /// A would-block (the socket's timeout) during the handshake is the deadline.
    fn timed_out<T>(&self, r: io::Result<T>) -> io::Result<T> {
        match r {
            Err(e) if self.deadline.is_some() && e.kind() == ErrorKind::WouldBlock => Err(
                io::Error::new(ErrorKind::TimedOut, "the handshake's deadline passed"),
            ),
            r => r,
        }
    }
}

impl Read for Conn {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if let Some(left) = self.left()? {
            self.stream.set_read_timeout(Some(left))?;
        }
        let r = self.stream.read(buf);
        self.timed_out(r)
    }
}

impl Write for Conn {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if let Some(left) = self.left()? {
            self.stream.set_write_timeout(Some(left))?;
        }
        let r = self.stream.write(buf);
        self.timed_out(r)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.stream.flush()
    }
}

/// A client's place among the `max_clients`: taken when its handshake is answered, given
/// back when dropped.
struct ClientSlot(Arc<Shared>);

impl ClientSlot {
    /// A free slot, if there is one.
    fn take(shared: &Arc<Shared>) -> Option<ClientSlot> {
        shared
            .open
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n < shared.max_clients).then_some(n + 1)
            })
            .ok()
            .map(|_| ClientSlot(Arc::clone(shared)))
    }
}

impl Drop for ClientSlot {
    fn drop(&mut self) {
        self.0.open.fetch_sub(1, Ordering::AcqRel);
    }
}

/// One client, from its handshake to its end (a thread of its own). The listener counted
/// it in `shared.sessions` and `shared.handshakes` before starting it; it counts itself out.
pub(crate) fn session(stream: TcpStream, peer: SocketAddr, shared: Arc<Shared>) {
    let opened = Session::open(stream, peer, &shared);
    shared.handshakes.fetch_sub(1, Ordering::AcqRel);
    if let Some(mut s) = opened {
        s.run();
        lock(&shared.clients).retain(|c| c.id != s.id);
        shared.sent.fetch_add(s.sent, Ordering::Relaxed);
        let dropped = s.dropped.load(Ordering::Relaxed);
        shared.dropped.fetch_add(dropped, Ordering::Relaxed);
        println!(
            "live: client {peer} left after {:.1} s: {} messages sent, {dropped} dropped{}",
            s.since.elapsed().as_secs_f64(),
            s.sent,
            s.gone
                .as_deref()
                .map_or(String::new(), |w| format!(" ({w})"))
        );
    }
    shared.sessions.fetch_sub(1, Ordering::AcqRel);
}

/// The WebSocket handshake of a client just accepted, within [`HANDSHAKE_DEADLINE`] of now:
/// the socket, the subprotocol chosen and the client's slot; `None` (logged) if the client is
/// refused (no subprotocol of ours: HTTP 400; no free slot: HTTP 503), leaves, or does not
/// finish in time (its connection is then closed).
fn handshake(
    stream: TcpStream,
    peer: SocketAddr,
    shared: &Arc<Shared>,
) -> Option<(WebSocket<Conn>, &'static str, ClientSlot)> {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_nodelay(true);
    let conn = Conn {
        stream,
        deadline: Some(Instant::now() + HANDSHAKE_DEADLINE),
    };
    let mut chosen = "";
    let mut slot = None;
    // tungstenite's callback type: its error is an HTTP response
    #[allow(clippy::result_large_err)]
    let callback = |req: &Request, resp: Response| {
        let (resp, p) = negotiate(req, resp)?;
        chosen = p;
        slot = ClientSlot::take(shared);
        if slot.is_some() {
            Ok(resp)
        } else {
            Err(refusal(
                StatusCode::SERVICE_UNAVAILABLE,
                format!(
                    "eqtrack-live serves at most {} clients at once\n",
                    shared.max_clients
                ),
            ))
        }
    };
    let ws = match tungstenite::accept_hdr_with_config(conn, callback, Some(ws_config())) {
        Ok(ws) => ws,
        Err(tungstenite::HandshakeError::Failure(WsError::Http(r))) => {
            let code = r.status().as_u16();
            if r.status() == StatusCode::SERVICE_UNAVAILABLE {
                println!(
                    "live: client {peer} refused (HTTP {code}): {} clients already",
                    shared.max_clients
                );
            } else {
                println!(
                    "live: client {peer} refused (HTTP {code}): no subprotocol of ours offered"
                );
            }
            return None;
        }
        Err(tungstenite::HandshakeError::Failure(WsError::Io(e)))
            if e.kind() == ErrorKind::TimedOut =>
        {
            println!(
                "live: client {peer}: no WebSocket handshake within {:.0} s; closed",
                HANDSHAKE_DEADLINE.as_secs_f64()
            );
            return None;
        }
        Err(e) => {
            println!("live: client {peer}: no WebSocket handshake ({e})");
            return None;
        }
    };
    Some((ws, chosen, slot?))
}

/// A session's state.
struct Session {
    id: u64,
    ws: WebSocket<Conn>,
    peer: SocketAddr,
    shared: Arc<Shared>,
    rx: Receiver<Item>,
    mask: Arc<AtomicU32>,
    dropped: Arc<AtomicU64>,
    /// Its subscriptions, and how it answers its client.
    state: SessionState,
    /// Its place among the `max_clients`.
    _slot: ClientSlot,
    sent: u64,
    since: Instant,
    /// Drops reported so far, and when.
    reported: (u64, Instant),
    /// Why the client is gone, once it is.
    gone: Option<String>,
}

impl Session {
    /// The handshake (within [`HANDSHAKE_DEADLINE`] of now), `serverInfo` and
    /// `advertise`; `None` (logged) if the client is refused, leaves, or does not finish its
    /// handshake in time (its connection is then closed).
    fn open(stream: TcpStream, peer: SocketAddr, shared: &Arc<Shared>) -> Option<Session> {
        let (mut ws, chosen, slot) = handshake(stream, peer, shared)?;
        ws.get_mut().deadline = None;
        if ws.get_mut().stream.set_nonblocking(true).is_err() {
            return None;
        }
        let sndbuf = nix::sys::socket::sockopt::SndBuf;
        if let Err(e) =
            nix::sys::socket::setsockopt(&ws.get_ref().stream, sndbuf, &SOCKET_SEND_BUFFER)
        {
            println!("live: client {peer}: cannot bound its socket's send buffer ({e})");
        }
        let (tx, rx) = sync_channel(shared.queue);
        let mask = Arc::new(AtomicU32::new(0));
        let dropped = Arc::new(AtomicU64::new(0));
        let metadata = lock(&shared.metadata).clone();
        let id = shared.served.fetch_add(1, Ordering::Relaxed);
        // registered before the greeting, so no notice between the two is missed
        lock(&shared.clients).push(Client {
            id,
            tx,
            mask: Arc::clone(&mask),
            dropped: Arc::clone(&dropped),
        });
        println!("live: client {peer} connected ({chosen})");
        let mut s = Session {
            id,
            ws,
            peer,
            shared: Arc::clone(shared),
            rx,
            mask,
            dropped,
            state: SessionState::new(&shared.channels),
            _slot: slot,
            sent: 0,
            since: Instant::now(),
            reported: (0, Instant::now()),
            gone: None,
        };
        s.text(protocol::server_info(
            "eqtrack-live",
            &metadata,
            &shared.session_id,
        ));
        s.text(protocol::advertise(&shared.channels));
        if !metadata.contains_key("scenario") {
            let run = metadata.get("run").cloned().unwrap_or_default();
            s.text(protocol::status(
                Level::Info,
                &format!("waiting for run `{run}` to start"),
            ));
        }
        Some(s)
    }

    /// Until the client leaves or the bridge ends.
    fn run(&mut self) {
        while self.gone.is_none() {
            if let Some((level, text)) = self.shared.end_notice() {
                self.close(level, &text);
                return;
            }
            // what was queued since the last tick, as one batch and one flush: the thread
            // wakes once a tick, not once a message, and so does the client
            for _ in 0..self.shared.queue {
                match self.rx.try_recv() {
                    Ok(item) => self.write_item(item),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return,
                }
            }
            self.flush();
            self.read();
            self.report_drops(false);
            std::thread::sleep(SESSION_TICK);
        }
    }

    /// Writes a queued item (a sample of a channel it no longer subscribes to is skipped).
    fn write_item(&mut self, item: Item) {
        match item {
            Item::Sample(s) => {
                let Some(sub) = self
                    .state
                    .subscriptions()
                    .subscription_of(s.channel as u32 + 1)
                else {
                    return;
                };
                let frame = message_data(sub, s.log_time, &s.cdr);
                if self.write(WsMessage::binary(frame)) {
                    self.sent += 1;
                } else {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
            Item::Notice(level, text) => self.text(protocol::status(level, &text)),
        }
    }

    fn text(&mut self, text: String) {
        self.write(WsMessage::text(text));
    }

    /// Hands a message to tungstenite: true if it took it (written or buffered); false if
    /// its write buffer is full (the message is dropped) or the client is gone.
    fn write(&mut self, msg: WsMessage) -> bool {
        if self.gone.is_some() {
            return false;
        }
        match self.ws.write(msg) {
            Ok(()) => true,
            // buffered; the socket will take it later
            Err(WsError::Io(e)) if e.kind() == ErrorKind::WouldBlock => true,
            Err(WsError::WriteBufferFull(_)) => false,
            Err(e) => {
                self.gone = Some(format!("write: {e}"));
                false
            }
        }
    }

    fn flush(&mut self) {
        if self.gone.is_some() {
            return;
        }
        match self.ws.flush() {
            Ok(()) => {}
            Err(WsError::Io(e)) if e.kind() == ErrorKind::WouldBlock => {}
            Err(e) => self.gone = Some(format!("write: {e}")),
        }
    }

    /// Reads and answers what the client sent, until nothing is left to read (at most
    /// [`READS_PER_TICK`] messages: a client that floods the bridge still gets its data).
    fn read(&mut self) {
        for _ in 0..READS_PER_TICK {
            if self.gone.is_some() {
                return;
            }
            match self.ws.read() {
                Ok(WsMessage::Text(t)) => self.answer(Incoming::Text(t.as_str())),
                Ok(WsMessage::Binary(b)) => self.answer(Incoming::Binary(&b)),
                Ok(WsMessage::Close(_)) => {
                    // tungstenite queued the close's answer: hand it over
                    let _ = self.ws.flush();
                    self.gone = Some("it closed the connection".into());
                }
                Ok(_) => {}
                Err(WsError::Io(e)) if e.kind() == ErrorKind::WouldBlock => return,
                Err(WsError::Capacity(e)) => {
                    self.gone = Some(format!("it sent too much: {e}"));
                    let _ = self.ws.close(Some(tungstenite::protocol::CloseFrame {
                        code: tungstenite::protocol::frame::coding::CloseCode::Size,
                        reason: "messages to eqtrack-live are at most 64 KiB".into(),
                    }));
                    let _ = self.ws.flush();
                }
                Err(WsError::ConnectionClosed | WsError::AlreadyClosed) => {
                    self.gone = Some("it closed the connection".into());
                }
                Err(e) => self.gone = Some(format!("read: {e}")),
            }
        }
    }

    /// Answers one client message ([`SessionState::handle`]): its subscriptions change as it
    /// asks, and a problem is told back in a `status` message.
    fn answer(&mut self, msg: Incoming<'_>) {
        let answer = self.state.handle(msg);
        self.mask
            .store(self.state.subscriptions().mask(), Ordering::Relaxed);
        if let Some(reply) = answer.reply {
            self.text(reply);
        }
    }

    /// At most once per [`DROP_REPORT_EVERY`] (or now, with `now`): the drops since the last
    /// report, logged and told to the client.
    fn report_drops(&mut self, now: bool) {
        let total = self.dropped.load(Ordering::Relaxed);
        let (before, at) = self.reported;
        if total == before || (!now && at.elapsed() < DROP_REPORT_EVERY) {
            return;
        }
        let text = format!(
            "{} messages dropped for this client in the last {:.1} s ({total} in all): it reads slower than the run",
            total - before,
            at.elapsed().as_secs_f64()
        );
        println!("live: client {}: {text}", self.peer);
        self.text(protocol::status(Level::Warning, &text));
        self.reported = (total, Instant::now());
    }

    /// The end: what is queued, the last word, the close; given at most [`CLOSE_GRACE`].
    fn close(&mut self, level: Level, text: &str) {
        while let Ok(item) = self.rx.try_recv() {
            self.write_item(item);
        }
        self.report_drops(true);
        self.text(protocol::status(level, text));
        let until = Instant::now() + CLOSE_GRACE;
        let _ = self.ws.close(None);
        while self.gone.is_none() && Instant::now() < until {
            match self.ws.flush() {
                Ok(()) => {}
                Err(WsError::Io(e)) if e.kind() == ErrorKind::WouldBlock => {}
                Err(_) => break,
            }
            match self.ws.read() {
                Err(WsError::Io(e)) if e.kind() == ErrorKind::WouldBlock => {
                    std::thread::sleep(SESSION_TICK);
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        self.gone.get_or_insert_with(|| "the bridge closed".into());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(channel: usize, cycle: u64) -> Arc<Sample> {
        Arc::new(Sample {
            channel,
            cycle,
            log_time: cycle * 1_000_000,
            cdr: vec![0, 1, 0, 0],
        })
    }

    #[test]
    fn a_full_queue_drops_for_that_client_only_and_a_gone_client_is_forgotten() {
        let shared = Shared::new(crate::channel_infos(), BTreeMap::new(), 2, 8);
        let mut clients = Vec::new();
        for id in 0..2 {
            let (tx, rx) = sync_channel(shared.queue);
            let mask = Arc::new(AtomicU32::new(0b0010)); // channel 1: states
            let dropped = Arc::new(AtomicU64::new(0));
            lock(&shared.clients).push(Client {
                id,
                tx,
                mask,
                dropped: Arc::clone(&dropped),
            });
            clients.push((rx, dropped));
        }
        for k in 0..5 {
            shared.offer(sample(0, k));
            // the second client reads as it comes; the first never does
            while let Ok(Item::Sample(s)) = clients[1].0.try_recv() {
                assert_eq!(s.cycle, k);
            }
        }
        // a command: nobody subscribed, nobody gets it
        shared.offer(sample(1, 5));
        assert_eq!(
            clients[0].1.load(Ordering::Relaxed),
            3,
            "5 offered, 2 queued"
        );
        assert_eq!(clients[1].1.load(Ordering::Relaxed), 0);
        assert!(clients[1].0.try_recv().is_err());
        assert_eq!(shared.offered.load(Ordering::Relaxed), 6);
        // the first client leaves: the next offer forgets it
        let (rx, _) = clients.remove(0);
        drop(rx);
        shared.offer(sample(0, 6));
        assert_eq!(lock(&shared.clients).len(), 1);
        assert_eq!(lock(&shared.clients)[0].id, 1);
    }

    #[test]
    fn the_end_is_said_once_with_the_first_word() {
        let shared = Shared::new(crate::channel_infos(), BTreeMap::new(), 4, 8);
        assert!(shared.end_notice().is_none());
        shared.finish(Level::Info, "run `x` ended at cycle 9".into());
        shared.finish(Level::Warning, "stopped".into());
        assert_eq!(
            shared.end_notice(),
            Some((Level::Info, "run `x` ended at cycle 9".to_owned()))
        );
    }
}
