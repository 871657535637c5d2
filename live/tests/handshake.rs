//! The handshake's deadline, without a run: connections that never finish their WebSocket
//! handshake (idle, or trickling a byte at a time) are closed [`HANDSHAKE_DEADLINE`] after
//! they connected and never shut a real client out: while they wait, a real client is served
//! at once, and when so many wait that new connections are not accepted, a real client is
//! served within the deadline and a little.

use live::{EXTRA_HANDSHAKES, HANDSHAKE_DEADLINE};
use std::io::{BufRead, BufReader, ErrorKind, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// What the deadline is allowed beyond itself: the bridge's accept loop, a loaded machine.
const SLACK: Duration = Duration::from_millis(1500);

/// `eqtrack-live` waiting for a run that never comes, its stdout collected.
struct Bridge {
    child: Child,
    addr: String,
    out: Arc<Mutex<String>>,
}

impl Bridge {
    fn start(args: &[&str]) -> Bridge {
        let mut child = Command::new(env!("CARGO_BIN_EXE_eqtrack-live"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("eqtrack-live runs");
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        stdout.read_line(&mut first).unwrap();
        let addr = first
            .split("ws://")
            .nth(1)
            .and_then(|a| a.split_whitespace().next())
            .unwrap_or_else(|| panic!("no address in {first:?}"))
            .to_owned();
        let out = Arc::new(Mutex::new(first));
        let sink = Arc::clone(&out);
        std::thread::spawn(move || {
            for line in stdout.lines() {
                let Ok(line) = line else { break };
                let mut o = sink.lock().unwrap();
                o.push_str(&line);
                o.push('\n');
            }
        });
        Bridge { child, addr, out }
    }

    fn output(&self) -> String {
        self.out.lock().unwrap().clone()
    }

    /// SIGTERM; it must exit 143.
    fn stop(mut self) -> String {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let until = Instant::now() + Duration::from_secs(10);
        let code = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break s.code();
            }
            assert!(Instant::now() < until, "eqtrack-live ignored SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        };
        std::thread::sleep(Duration::from_millis(100));
        let out = self.output();
        assert_eq!(code, Some(143), "{out}");
        out
    }
}

/// A WebSocket handshake offering `foxglove.sdk.v1`, then the `serverInfo` message; `Err`
/// says why not (`HTTP 503` for a refusal with that status).
fn client(addr: &str) -> Result<WebSocket<TcpStream>, String> {
    let stream = TcpStream::connect(addr).map_err(|e| e.to_string())?;
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut req = format!("ws://{addr}/").into_client_request().unwrap();
    req.headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let (mut ws, _) = tungstenite::client(req, stream).map_err(|e| match e {
        tungstenite::HandshakeError::Failure(tungstenite::Error::Http(r)) => {
            format!("HTTP {}", r.status().as_u16())
        }
        other => other.to_string(),
    })?;
    match ws.read() {
        Ok(Message::Text(t)) if t.as_str().contains(r#""op":"serverInfo""#) => Ok(ws),
        other => Err(format!("no serverInfo: {other:?}")),
    }
}

/// Whether the bridge has closed `s` (end of stream, or a reset), waiting until `until`.
fn closed_by(s: &mut TcpStream, until: Instant) -> bool {
    let mut buf = [0u8; 1024];
    loop {
        let left = until.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return false;
        }
        s.set_read_timeout(Some(left)).unwrap();
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return true,
        }
    }
}

#[test]
fn connections_that_never_finish_their_handshake_are_closed_and_shut_no_one_out() {
    let bridge = Bridge::start(&[
        "--name",
        "t-live-handshake",
        "--listen",
        "127.0.0.1:0",
        "--max-clients",
        "1",
        "--wait",
        "120",
    ]);
    let addr = bridge.addr.clone();

    // 8 idle connections that never send their upgrade request, and one that trickles its
    // request a byte every 0.5 s (each read of it comes well within a per-read timeout)
    let t0 = Instant::now();
    let mut idle: Vec<TcpStream> = (0..8).map(|_| TcpStream::connect(&addr).unwrap()).collect();
    let trickler = {
        let addr = addr.clone();
        std::thread::spawn(move || {
            let mut s = TcpStream::connect(&addr).unwrap();
            let start = Instant::now();
            s.set_read_timeout(Some(Duration::from_millis(500)))
                .unwrap();
            let request = b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n";
            let mut buf = [0u8; 256];
            for b in request {
                if s.write_all(&[*b]).is_err() {
                    return Some(start.elapsed());
                }
                match s.read(&mut buf) {
                    Ok(0) => return Some(start.elapsed()),
                    Ok(_) => return None, // an answer: the deadline did not hold
                    Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                    Err(_) => return Some(start.elapsed()),
                }
            }
            None
        })
    };
    // a real client is served at once, even with --max-clients 1: they hold no client slot
    std::thread::sleep(Duration::from_millis(200));
    let asked = Instant::now();
    let mut ws = client(&addr).unwrap_or_else(|e| {
        panic!(
            "a real client beside 9 unfinished handshakes: {e}\n{}",
            bridge.output()
        )
    });
    assert!(
        asked.elapsed() < SLACK,
        "served after {:?}",
        asked.elapsed()
    );
    // the slot is its own: a second real client is refused (HTTP 503)
    match client(&addr) {
        Err(e) if e == "HTTP 503" => {}
        Err(e) => panic!("a second client with --max-clients 1: {e}"),
        Ok(_) => panic!("a second client with --max-clients 1 was served"),
    }
    ws.close(None).unwrap();
    while ws.read().is_ok() {}
    drop(ws);

    // the idle connections are closed at the deadline, not before and not much after
    for s in &mut idle {
        assert!(
            closed_by(s, t0 + HANDSHAKE_DEADLINE + SLACK),
            "an idle connection still open {:?} after it connected\n{}",
            t0.elapsed(),
            bridge.output()
        );
    }
    assert!(
        t0.elapsed() >= HANDSHAKE_DEADLINE - Duration::from_millis(100),
        "closed before the deadline: {:?}",
        t0.elapsed()
    );
    let trickled = trickler.join().unwrap();
    assert!(
        trickled.is_some_and(|t| t < HANDSHAKE_DEADLINE + SLACK),
        "the trickling connection was not closed at the deadline: {trickled:?}\n{}",
        bridge.output()
    );

    // so many unfinished handshakes that the next connection waits to be accepted: a real
    // client is served when the first of them is closed, within the deadline and a little
    let waiting = 1 + EXTRA_HANDSHAKES; // --max-clients 1, plus the extra ones
    let t1 = Instant::now();
    let mut idle: Vec<TcpStream> = (0..waiting)
        .map(|_| TcpStream::connect(&addr).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    let served = client(&addr).unwrap_or_else(|e| {
        panic!(
            "a real client behind {waiting} unfinished handshakes: {e}\n{}",
            bridge.output()
        )
    });
    let after = t1.elapsed();
    println!("served {after:?} after {waiting} idle connections took every handshake's place");
    assert!(
        after < HANDSHAKE_DEADLINE + SLACK,
        "a real client served only {after:?} after the idle connections came\n{}",
        bridge.output()
    );
    assert!(
        after >= HANDSHAKE_DEADLINE - Duration::from_millis(300),
        "served after {after:?}: the handshakes' limit did not hold"
    );
    for s in &mut idle {
        assert!(closed_by(s, t1 + HANDSHAKE_DEADLINE + SLACK));
    }
    drop(served);

    let out = bridge.stop();
    let timed_out = out
        .matches("no WebSocket handshake within 5 s; closed")
        .count();
    assert!(
        timed_out > 8 + waiting,
        "{timed_out} handshakes timed out\n{out}"
    );
    assert!(
        out.contains("refused (HTTP 503): 1 clients already"),
        "{out}"
    );
    assert!(
        out.contains(&format!(
            "{waiting} connections in their handshake: the next wait to be accepted"
        )),
        "{out}"
    );
}
