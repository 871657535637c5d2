//! # live — a running pair in Foxglove, as it flies
//!
//! `eqtrack-live` (what `plant_sim live --name RUN` runs) serves run RUN's state, command and
//! status to Foxglove, Lichtblick, PlotJuggler's Foxglove bridge client or any client of the
//! Foxglove WebSocket protocol, while the run flies (docs/live.md).
//!
//! It is a process of its own, and only **reads** the pair's iceoryx2 boards
//! ([`link::watch::PairWatch`]): the plant and the controller never link WebSocket code, and
//! nothing the bridge or its clients do can make the loop wait.
//!
//! * A **poller** thread ([`poller`]) reads the state, command and status boards every
//!   [`POLL_PERIOD`] (a sleep, not a spin), turns each write it has not seen (keyed on its
//!   `seq` and stamp) into one CDR message of the channel's schema (the `channels` crate's,
//!   the MCAP export's), and offers it to every subscribed client's bounded queue with
//!   `try_send`: a full queue drops it for that client, counted. The boards hold the newest
//!   value only, so a state or command the pair replaced before the poller read it is not
//!   shown: the poller counts those too (the gaps in their `seq`) and the bridge reports them.
//! * Each client has a **session** thread (`server.rs`) that writes its queue to its
//!   non-blocking socket through a bounded write buffer, and answers its `subscribe`,
//!   `unsubscribe` and anything else (unknown ops, garbage, binary frames, oversized
//!   messages) without ever panicking ([`protocol::SessionState`]). A connection has
//!   [`HANDSHAKE_DEADLINE`] in all to finish its WebSocket handshake, then is closed.
//! * The protocol's pieces are in [`protocol`]: both subprotocol names
//!   (`foxglove.websocket.v1` and `foxglove.sdk.v1`; another is refused with HTTP 400),
//!   `serverInfo`, `advertise`, `status`, `messageData`.
//!
//! | channel id | topic | schema |
//! |---|---|---|
//! | 1 | `/eqtrack/state` | `eqtrack_msgs/msg/State` |
//! | 2 | `/eqtrack/command` | `eqtrack_msgs/msg/Command` (`received_ns` 0: the plant's to know) |
//! | 3 | `/eqtrack/status` | `eqtrack_msgs/msg/Status` |
//!
//! The bridge waits for the run (up to [`Options::wait`]), follows it, and when the run ends
//! (its plant says so, or its plant's process is gone) tells every client in a `status`
//! message, closes, prints what it sent and dropped, and exits.

#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod poller;
pub mod protocol;
mod server;

use link::{StopFlag, StopSignal};
use poller::{Event, Poller, RunEnd};
use protocol::{ChannelInfo, Level};
use server::Shared;
use std::collections::BTreeMap;
use std::net::{SocketAddr, TcpListener};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

pub use server::{EXTRA_HANDSHAKES, HANDSHAKE_DEADLINE, MAX_CLIENT_MESSAGE, MAX_WRITE_BUFFER};

/// The channels the bridge advertises, in id order: channel id = index + 1.
pub const LIVE_CHANNELS: [channels::Channel; 3] =
    [channels::STATE, channels::COMMAND, channels::STATUS];

/// How often the poller reads the boards (it sleeps in between).
pub const POLL_PERIOD: Duration = Duration::from_micros(500);

/// A client's queue, in messages: about half a second of a 1 kHz run's state and command.
pub const DEFAULT_QUEUE: usize = 1024;

/// States and commands replaced on the boards before the bridge read them are logged at most
/// this often (and only when their count grew).
pub const REPLACED_REPORT_EVERY: Duration = Duration::from_secs(1);

/// The advertised channels: each one's schema text from a message of its own builder.
pub fn channel_infos() -> Vec<ChannelInfo> {
    let group = ipc_types::WireGroup::So3;
    let state = ipc_types::StateMsg::new(group);
    let command = ipc_types::CommandMsg::new(group);
    let status = ipc_types::StatusMsg::new(group, "");
    let examples = [
        channels::state_message(0, &state, 3, 3),
        channels::command_message(0, &command, 0, 3),
        channels::status_message(&status),
    ];
    LIVE_CHANNELS
        .iter()
        .zip(examples)
        .enumerate()
        .map(|(i, (c, msg))| {
            debug_assert_eq!(msg.topic, c.topic);
            ChannelInfo {
                id: i as u32 + 1,
                topic: c.topic,
                schema_name: c.schema,
                schema: msg.schema_text(),
            }
        })
        .collect()
}

/// What the bridge serves, where, and for how long.
#[derive(Debug, Clone)]
pub struct Options {
    /// The run (`plant_sim run --name`).
    pub run: String,
    /// Where to listen.
    pub listen: SocketAddr,
    /// How long to wait for the run to start.
    pub wait: Duration,
    /// Clients served at once; more are refused (HTTP 503).
    pub max_clients: usize,
    /// Each client's queue, in messages.
    pub queue: usize,
    /// Set by SIGINT/SIGTERM.
    pub stop: StopFlag,
}

/// How the bridge ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The run ended ([`RunEnd`]).
    Run(RunEnd),
    /// No live plant published a state within [`Options::wait`].
    NoRun,
    /// SIGINT or SIGTERM.
    Stopped(StopSignal),
}

/// What the bridge did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Report {
    /// How it ended.
    pub outcome: Outcome,
    /// Clients served (handshakes accepted).
    pub clients: u64,
    /// Messages read from the boards and offered to the clients.
    pub offered: u64,
    /// Messages sent, all clients together.
    pub sent: u64,
    /// Messages dropped for clients that did not keep up, all together.
    pub dropped: u64,
    /// States the plant replaced on the board before the bridge read them (never shown):
    /// the gaps in the `seq` of the states read ([`poller::SeqGaps`]).
    pub replaced_states: u64,
    /// Commands replaced on the board before the bridge read them, the same way (a cycle
    /// the controller did not answer is a gap too).
    pub replaced_commands: u64,
}

/// Why the bridge could not serve.
#[derive(Debug)]
pub enum LiveError {
    /// Bad input: the run's name (exit code 2).
    Input(String),
    /// The address cannot be listened on, or the boards cannot be opened (exit code 1).
    Run(String),
}

impl std::fmt::Display for LiveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LiveError::Input(m) | LiveError::Run(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for LiveError {}

/// Lowers the calling thread's scheduling priority below the pair's: SCHED_BATCH (the
/// scheduler does not let its wake-ups preempt other work) at nice 9. Threads started
/// afterwards inherit it, so call it first. A pair at normal priority sharing the bridge's
/// CPUs then wins them (one with `--rt-priority` does anyway). `Err`: the OS's refusal (the
/// bridge then runs as it is).
pub fn yield_to_the_pair() -> Result<(), String> {
    use thread_priority::unix::{
        NormalThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
        thread_native_id,
    };
    use thread_priority::{ThreadPriority, ThreadPriorityValue};
    // thread-priority maps 0..=99 onto nice 19..=-20: 24 is nice 9
    let value = ThreadPriorityValue::try_from(24u8).map_err(|e| e.to_string())?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Batch),
    )
    .map_err(|e| format!("{e:?}"))
}

/// Serves run `opts.run` on `opts.listen` until the run ends, no run comes within
/// `opts.wait`, or a stop signal.
pub fn serve(opts: &Options) -> Result<Report, LiveError> {
    if !ipc_types::valid_run_name(&opts.run) {
        return Err(LiveError::Input(format!(
            "bad run name `{}`: 1 to 64 characters of A-Z, a-z, 0-9, _ and -",
            opts.run
        )));
    }
    let listener = TcpListener::bind(opts.listen)
        .map_err(|e| LiveError::Run(format!("cannot listen on {}: {e}", opts.listen)))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| LiveError::Run(format!("cannot listen on {}: {e}", opts.listen)))?;
    let mut metadata = BTreeMap::new();
    metadata.insert("run".to_owned(), opts.run.clone());
    metadata.insert(
        "eqtrack_version".to_owned(),
        env!("CARGO_PKG_VERSION").to_owned(),
    );
    let shared = Arc::new(Shared::new(
        channel_infos(),
        metadata,
        opts.queue,
        opts.max_clients,
    ));
    let quit = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = mpsc::channel();
    let (end_tx, end_rx) = mpsc::channel();
    let poller = {
        let (run, shared, quit) = (opts.run.clone(), Arc::clone(&shared), Arc::clone(&quit));
        std::thread::Builder::new()
            .name("live-poller".into())
            .spawn(move || poll_boards(&run, &shared, &quit, &ready_tx, &end_tx))
            .map_err(|e| LiveError::Run(format!("cannot start the poller: {e}")))?
    };
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(LiveError::Run(e)),
        Err(_) => return Err(LiveError::Run("the poller failed to start".to_owned())),
    }
    let addr = listener.local_addr().unwrap_or(opts.listen);
    println!(
        "live: serving run `{}` on ws://{addr} (Foxglove: Open connection, Foxglove WebSocket); waiting for the run",
        opts.run
    );
    let outcome = accept_until_end(&listener, opts, &shared, &end_rx);
    // the poller first, so the last word has its final counts
    quit.store(true, Ordering::Release);
    let replaced = poller.join().unwrap_or((0, 0));
    let (level, text) = last_word(opts, outcome, replaced);
    shared.finish(level, text);
    // the sessions send their last word and close; give them a little longer than they take
    let until = Instant::now() + Duration::from_secs(2);
    while shared.sessions.load(Ordering::Acquire) > 0 && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(5));
    }
    Ok(Report {
        outcome,
        clients: shared.served.load(Ordering::Relaxed),
        offered: shared.offered.load(Ordering::Relaxed),
        sent: shared.sent.load(Ordering::Relaxed),
        dropped: shared.dropped.load(Ordering::Relaxed),
        replaced_states: replaced.0,
        replaced_commands: replaced.1,
    })
}

/// What every client is told when the bridge ends: how, and the states and commands
/// replaced on the boards before the bridge read them, if any.
fn last_word(opts: &Options, outcome: Outcome, replaced: (u64, u64)) -> (Level, String) {
    let (level, mut text) = match outcome {
        Outcome::Run(RunEnd::Ended { cycle }) => (
            Level::Info,
            format!("run `{}` ended at cycle {cycle}", opts.run),
        ),
        Outcome::Run(RunEnd::PlantGone { pid }) => (
            Level::Error,
            format!(
                "the plant of run `{}` (pid {pid}) is gone without ending the run",
                opts.run
            ),
        ),
        Outcome::NoRun => (
            Level::Error,
            format!(
                "run `{}` did not start within {:.0} s",
                opts.run,
                opts.wait.as_secs_f64()
            ),
        ),
        Outcome::Stopped(sig) => (Level::Warning, format!("eqtrack-live stopped by {sig}")),
    };
    if replaced != (0, 0) {
        text.push_str(&format!(
            " ({} states and {} commands were replaced on the boards before the bridge read them, and not shown)",
            replaced.0, replaced.1
        ));
    }
    (level, text)
}

/// Accepts clients (a session thread each) until the poller reports the run's end, no run
/// comes in time, or a stop signal.
fn accept_until_end(
    listener: &TcpListener,
    opts: &Options,
    shared: &Arc<Shared>,
    end_rx: &mpsc::Receiver<Option<RunEnd>>,
) -> Outcome {
    let started = Instant::now();
    let mut attached = false;
    // whether the handshakes are full (said once each time they fill)
    let mut full = false;
    loop {
        // a connection takes a client slot (of `max_clients`) when its handshake is
        // answered; until then it is one of at most `max_clients` + EXTRA_HANDSHAKES
        // handshakes, each given HANDSHAKE_DEADLINE in all. When they are full, new
        // connections wait in the listen backlog until one ends.
        if !shared.handshake_room() {
            if !full {
                println!(
                    "live: {} connections in their handshake: the next wait to be accepted (each has {:.0} s)",
                    opts.max_clients + EXTRA_HANDSHAKES,
                    HANDSHAKE_DEADLINE.as_secs_f64()
                );
            }
            full = true;
        } else {
            full = false;
            match listener.accept() {
                Ok((stream, peer)) => {
                    // counted here, before its thread runs: a burst of connections cannot
                    // pass the limit
                    shared.sessions.fetch_add(1, Ordering::AcqRel);
                    shared.handshakes.fetch_add(1, Ordering::AcqRel);
                    let mine = Arc::clone(shared);
                    let spawned = std::thread::Builder::new()
                        .name("live-session".into())
                        .spawn(move || server::session(stream, peer, mine));
                    if let Err(e) = spawned {
                        shared.handshakes.fetch_sub(1, Ordering::AcqRel);
                        shared.sessions.fetch_sub(1, Ordering::AcqRel);
                        eprintln!("live: cannot serve client {peer}: {e}");
                    }
                    continue;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => eprintln!("live: accept: {e}"),
            }
        }
        if let Some(sig) = opts.stop.requested() {
            return Outcome::Stopped(sig);
        }
        match end_rx.try_recv() {
            Ok(Some(end)) => return Outcome::Run(end),
            Ok(None) => attached = true,
            Err(mpsc::TryRecvError::Empty) => {}
            // the poller is gone without a word: it cannot be (it reports before it ends)
            Err(mpsc::TryRecvError::Disconnected) => return Outcome::NoRun,
        }
        if !attached && started.elapsed() > opts.wait {
            return Outcome::NoRun;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The poller thread: opens the boards (says so on `ready`), polls them every
/// [`POLL_PERIOD`], offers each sample, and reports on `end`: `None` when the run is found,
/// then `Some` when it ends. Returns the counts of states and commands replaced on the
/// boards before it read them.
fn poll_boards(
    run: &str,
    shared: &Shared,
    quit: &AtomicBool,
    ready: &mpsc::Sender<Result<(), String>>,
    end: &mpsc::Sender<Option<RunEnd>>,
) -> (u64, u64) {
    let watch = match link::watch::PairWatch::open(run) {
        Ok(w) => {
            let _ = ready.send(Ok(()));
            w
        }
        Err(e) => {
            let _ = ready.send(Err(format!("cannot open run `{run}`'s boards: {e}")));
            return (0, 0);
        }
    };
    let mut poller = Poller::new(watch, link::process_alive);
    let mut events = Vec::new();
    // the counts of states and commands replaced before the poller read them, last logged,
    // and when
    let mut logged = ((0, 0), Instant::now());
    let mut replaced = (0, 0);
    while !quit.load(Ordering::Acquire) {
        poller.poll(Instant::now(), &mut events);
        replaced = (poller.replaced_states(), poller.replaced_commands());
        if replaced != logged.0 && logged.1.elapsed() >= REPLACED_REPORT_EVERY {
            println!(
                "live: {} states and {} commands replaced on the boards before the bridge read them in the last {:.1} s ({} and {} in all)",
                replaced.0 - logged.0.0,
                replaced.1 - logged.0.1,
                logged.1.elapsed().as_secs_f64(),
                replaced.0,
                replaced.1
            );
            logged = (replaced, Instant::now());
        }
        for e in events.drain(..) {
            match e {
                Event::Sample(s) => shared.offer(Arc::new(s)),
                Event::Attached {
                    scenario,
                    group,
                    rate_hz,
                    plant_pid,
                    cycle,
                } => {
                    let text = format!(
                        "run `{run}` found at cycle {cycle}: scenario {scenario}, {group}, {rate_hz:.0} Hz, plant pid {plant_pid}"
                    );
                    println!("live: {text}");
                    let mut m = server::lock(&shared.metadata);
                    m.insert("scenario".into(), scenario);
                    m.insert("group".into(), group.into());
                    m.insert("rate_hz".into(), format!("{rate_hz}"));
                    drop(m);
                    shared.notify(Level::Info, &text);
                    let _ = end.send(None);
                    logged.1 = Instant::now();
                }
                Event::Ended(e) => {
                    let _ = end.send(Some(e));
                    return replaced;
                }
            }
        }
        std::thread::sleep(POLL_PERIOD);
    }
    replaced
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The panels a layout tree names.
    fn panels(node: &serde_json::Value, out: &mut Vec<String>) {
        match node {
            serde_json::Value::String(id) => out.push(id.clone()),
            serde_json::Value::Object(split) => {
                panels(&split["first"], out);
                panels(&split["second"], out);
            }
            other => panic!("not a layout node: {other}"),
        }
    }

    #[test]
    fn the_foxglove_layout_shows_only_fields_the_channels_have() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../docs/foxglove/eqtrack-live.json"
        );
        let layout: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let configs = layout["configById"].as_object().unwrap();
        let mut named = Vec::new();
        panels(&layout["layout"], &mut named);
        named.sort();
        let mut ids: Vec<String> = configs.keys().cloned().collect();
        ids.sort();
        assert_eq!(named, ids, "the layout's tree and its panels differ");
        let infos = channel_infos();
        let field_of = |path: &str| -> (String, String) {
            let (topic, field) = path.split_once('.').unwrap_or((path, ""));
            let field = field.split('[').next().unwrap();
            (topic.to_owned(), field.to_owned())
        };
        let mut plotted = Vec::new();
        for (id, config) in configs {
            if id.starts_with("Plot!") {
                for p in config["paths"].as_array().unwrap() {
                    plotted.push(p["value"].as_str().unwrap().to_owned());
                }
            } else if id.starts_with("RawMessages!") {
                plotted.push(config["topicPath"].as_str().unwrap().to_owned());
            } else {
                panic!("unexpected panel {id}");
            }
        }
        for path in &plotted {
            let (topic, field) = field_of(path);
            let info = infos
                .iter()
                .find(|c| c.topic == topic)
                .unwrap_or_else(|| panic!("{path}: no channel {topic}"));
            assert!(
                field.is_empty()
                    || info
                        .schema
                        .lines()
                        .any(|l| l.ends_with(&format!(" {field}"))),
                "{path}: {topic} has no field {field}"
            );
        }
        for want in [
            "/eqtrack/state.v[0]",
            "/eqtrack/command.tau[0]",
            "/eqtrack/command.lyapunov",
            "/eqtrack/status.rtt_p99_ns",
            "/eqtrack/status",
        ] {
            assert!(
                plotted.iter().any(|p| p == want),
                "the layout does not show {want}"
            );
        }
    }

    #[test]
    fn the_bridge_yields_the_cpu_to_the_pair() {
        // in a thread of its own: the test harness's threads keep their priority
        std::thread::spawn(|| {
            yield_to_the_pair().unwrap();
            let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
            // the fields after the command's closing parenthesis: nice is field 19, the
            // policy field 41 (3: SCHED_BATCH)
            let rest: Vec<&str> = stat
                .rsplit(')')
                .next()
                .unwrap()
                .split_whitespace()
                .collect();
            assert_eq!(rest[19 - 3], "9", "{stat}");
            assert_eq!(rest[41 - 3], "3", "{stat}");
        })
        .join()
        .unwrap();
    }

    #[test]
    fn the_advertised_channels_are_the_exports_state_and_command_and_the_status() {
        let infos = channel_infos();
        let ids: Vec<u32> = infos.iter().map(|c| c.id).collect();
        assert_eq!(ids, [1, 2, 3]);
        assert_eq!(infos[0].schema_name, "eqtrack_msgs/msg/State");
        assert!(infos[0].schema.starts_with("uint64 cycle\nfloat64 t\n"));
        assert!(
            infos[1]
                .schema
                .contains("float64[] tau\nfloat64 lyapunov\n")
        );
        assert!(infos[2].schema.contains("uint64 rtt_p99_ns\n"));
    }
}
