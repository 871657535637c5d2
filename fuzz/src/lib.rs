//! A fuzz harness for the project's untrusted input, on stable Rust (no libFuzzer, no
//! nightly): deterministic, seeded, mutation-based.
//!
//! Eight targets ([`Target`]):
//!
//! * **scenario** — TOML text through [`scenario::Scenario::from_toml`] (parser and
//!   validator); an accepted scenario then goes through what the processes do with it: its
//!   fingerprint, step count and law overrides, and, on its group, the controller, the
//!   reference generator and the plant body, and a few closed-loop cycles (bounded, see
//!   `SUBSTEP_BUDGET` in the source). Seeds: [`scenario::BUILTINS`] and three hand-written
//!   scenarios that reach the optional keys.
//! * **wire** — bytes through [`ipc_types::StateMsg::from_bytes`] /
//!   [`ipc_types::CommandMsg::from_bytes`], the decoded message through `check_state` /
//!   `check_command` for a receiver in a given state (and a grid of other receivers), the
//!   identity helpers, and what each side does with an accepted message (the law evaluated on
//!   a state, a command's torque integrated by the plant). Seeds: realistic messages of both
//!   groups from a few cycles of the built-in scenarios' closed loops.
//! * **path** — waypoint-file text through `scenario::waypoints::parse` and `check_legs` on
//!   the group its header names and both path kinds (`stop`, `through`); an accepted path is built, sampled
//!   and handed to the law, and its segments are streamed as plan messages with one wire
//!   field (`shape`, `t0`, `t1`, `start`, `twists`) overwritten, checked by `check_plan` and,
//!   when accepted, evaluated as the controller does. Seeds: the shipped slews and
//!   through-path files with velocity columns.
//! * **recording** — what replay and export read back from a flight recording: a record of a
//!   run with sensors (with its sensor block) through `Record::from_bytes`, its samples
//!   through both groups' estimators as replay steps them, and a `plans.log` entry through
//!   `PlanEntry::from_bytes` and `control_cycle::PlanIntake::take` on a streamed
//!   reference, its pieces handed to the law. Seeds: the first ticks of the two sensor
//!   scenarios, the slews' plan messages.
//! * **serial** — bytes on the processor-in-the-loop line through `eqtrack-serial-wire`'s deframer
//!   and decoder (COBS, CRC, version, postcard); a decoded frame must re-encode to itself.
//!   Seeds: every frame kind, alone and back to back; a third of the cases wrap a mutated
//!   message in a valid envelope so that the message decoder is reached past the CRC.
//! * **shard** — a Monte Carlo shard's bytes (`shard.bin`, and what a Ray task returns)
//!   through `studies::shard::decode_shard` and `merge_encoded`; a decoded shard must
//!   re-encode to itself. Seeds: the shards of a small real study.
//! * **params** — the run-time parameters of a tunable run, three inputs (see
//!   docs/live.md, "Tuning a running pair"): the `params` board ([`ipc_types::ParamMsg`]) through `gains_for`
//!   for a controller answering one state, the accepted gains through
//!   `control_cycle::Responder::retune` and the retuned law on a state (a finite torque); a
//!   `param` request ([`ipc_types::ParamRequest`]) through `link::params::read_request` and
//!   `scenario::tuning::Tuner::get` / `check` (an accepted change's scenario validates again,
//!   builds its controller, resolves to finite numbers, and the running pair takes it); and
//!   `params.log` text through `recorder::params::parse_params` (an accepted file's changes
//!   re-serialized parse back equal). Seeds: the boards of four scenarios before and after
//!   changes made with the tuner, requests for every tunable key, real `params.log` files.
//! * **live** — what a Foxglove client sends the live bridge (`eqtrack-live`): a sequence
//!   of WebSocket text and binary messages through one client session
//!   ([`live::protocol::SessionState::handle`]: the client-message parser, then the
//!   session's subscriptions); every refusal a [`live::protocol::Refusal`], the answer an
//!   error `status` message in valid JSON exactly when something was refused, and the
//!   subscriptions consistent and those of a reference model of the protocol's rules (an
//!   `unsubscribe` of all leaves none). Seeds: the `subscribe` and `unsubscribe` messages
//!   FoxgloveClient and Foxglove's app send, the other ops and binary messages clients send.
//!
//! Each case is one corpus item with 1–8 random mutations (byte-level: bit flips, byte
//! overwrite, insert, delete, truncation, chunk duplication, splicing; TOML: number and string
//! tokens replaced by interesting values, lines deleted, duplicated, swapped or inserted,
//! known keys set, list lengths changed; wire: f64 fields set to NaN, infinities,
//! subnormals, extremes, integer fields to boundary or random values, odd names, wrong
//! lengths; params: a board's numbers and integers the same way, its gain sets scaled,
//! perturbed, crossed or swapped, a request's key and value replaced, a `params.log`'s
//! lines, numbers, strings and fields; live: JSON numbers, strings and values replaced,
//! removed, duplicated, nested deep, long lists, messages duplicated, removed, swapped,
//! inserted or turned binary), or a fully random input. Case `i` of seed `s` draws from ChaCha8 stream `i` of
//! key `s`, so it can be regenerated alone ([`generate`], [`replay`]).
//!
//! The oracle: no panic, and every rejection a typed error. Each case runs under
//! [`std::panic::catch_unwind`] ([`run_case`]); a quiet panic hook records the message and
//! location of panics inside a case. InvalidCounts are counted by kind ([`Report::rejected`]);
//! panics are [`Finding`]s and fail the run ([`Report::passed`]). A few extra assertions turn
//! broken documented properties into panics too: decoding then encoding a message gives the
//! same bytes, `check_*` accepts only messages of the right version, group and sequence,
//! `Controller::compute` never returns a non-finite torque, a fingerprint is never 0.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

mod live_target;
mod mutate;
mod params_target;
mod path_target;
mod recording_target;
mod rng;
mod scenario_target;
mod serial_target;
mod shard_target;
mod wire_target;

use eqtrack_controller::GroupKind;
use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::fmt;
use std::io;
use std::ops::Range;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Once;
use std::time::{Duration, Instant};

/// What is fuzzed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Target {
    /// Scenario TOML: parser, validator, and the builders of an accepted scenario.
    Scenario,
    /// Wire messages: decoder, receiver checks, identities.
    Wire,
    /// Waypoint files and the streamed segments of the paths through them.
    Path,
    /// Flight recordings: records with their sensor blocks, plan entries.
    Recording,
    /// The processor-in-the-loop serial line: frames through the deframer and decoder.
    Serial,
    /// A Monte Carlo shard's bytes: decoder and merge.
    Shard,
    /// Run-time parameters: the `params` board, `param` requests, `params.log`.
    Params,
    /// The live bridge's client messages: parser and session subscriptions.
    Live,
}

impl Target {
    /// Every target.
    pub const ALL: [Target; 8] = [
        Target::Scenario,
        Target::Wire,
        Target::Path,
        Target::Recording,
        Target::Serial,
        Target::Shard,
        Target::Params,
        Target::Live,
    ];

    /// Lower-case name (`"scenario"`, `"wire"`, `"path"`), as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Scenario => "scenario",
            Target::Wire => "wire",
            Target::Path => "path",
            Target::Recording => "recording",
            Target::Serial => "serial",
            Target::Shard => "shard",
            Target::Params => "params",
            Target::Live => "live",
        }
    }
}

impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which message type a wire case's bytes are handed to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MsgKind {
    /// [`ipc_types::StateMsg::from_bytes`] (plant → controller).
    State,
    /// [`ipc_types::CommandMsg::from_bytes`] (controller → plant).
    Command,
}

/// The state of the side receiving a wire message: the arguments of `check_state` /
/// `check_command`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    /// The receiver's group.
    pub group: GroupKind,
    /// States: the last accepted sequence number.
    pub last_seq: Option<u64>,
    /// States: the period the receiver runs with (`None`: any positive period).
    pub period: Option<f64>,
    /// Commands: the sequence number awaited.
    pub awaited: u64,
    /// Commands: the plant's actuator count (0: no vehicle).
    pub actuators: u32,
}

/// One wire case: bytes received, by whom.
#[derive(Debug, Clone, PartialEq)]
pub struct WireCase {
    /// The decoder the bytes go to.
    pub kind: MsgKind,
    /// The receiver's state.
    pub receiver: Receiver,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// Which run-time parameter input a params case's bytes are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamsKind {
    /// A [`ipc_types::ParamMsg`] (the `params` board), its fields in order, little-endian.
    Board,
    /// A [`ipc_types::ParamRequest`] (the `param` service), its fields in order,
    /// little-endian.
    Request,
    /// The text of a `params.log`.
    Log,
}

/// The side reading a params case: the controller of a run of `scenario` answering state
/// `seq` (a board; `fingerprint` is the one it checks the board against), the plant's
/// parameter thread of a run of `scenario` (a request), or replay (a log; `seq` and
/// `fingerprint` unused).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamsReceiver {
    /// The run's scenario (one of the target's seed scenarios).
    pub scenario: &'static str,
    /// A board: the sequence number of the state answered.
    pub seq: u64,
    /// A board: the run's scenario fingerprint, as the receiver knows it.
    pub fingerprint: u64,
}

/// One params case: an input and the side that reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamsCase {
    /// What the bytes are.
    pub kind: ParamsKind,
    /// Who reads them.
    pub receiver: ParamsReceiver,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// One client message of a live case.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LiveMessage {
    /// A text message.
    Text(String),
    /// A binary message.
    Binary(Vec<u8>),
}

/// The client messages a live case's bytes hold: per message a tag byte (bit 0 set:
/// binary), its length (u32, little-endian) and its bytes (a length past the end takes the
/// rest; a text message's invalid UTF-8 is replaced).
pub fn live_messages(bytes: &[u8]) -> Vec<LiveMessage> {
    let mut out = Vec::new();
    let mut rest = bytes;
    while let Some((&tag, after)) = rest.split_first() {
        let len = after
            .get(..4)
            .map_or(0, |l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]) as usize);
        let after = after.get(4..).unwrap_or(&[]);
        let (body, next) = after.split_at(len.min(after.len()));
        out.push(if tag & 1 == 1 {
            LiveMessage::Binary(body.to_vec())
        } else {
            LiveMessage::Text(String::from_utf8_lossy(body).into_owned())
        });
        rest = next;
    }
    out
}

/// One generated input.
#[derive(Debug, Clone, PartialEq)]
pub enum Case {
    /// Scenario TOML (bytes: not necessarily UTF-8; the checker replaces invalid sequences).
    Scenario(Vec<u8>),
    /// A wire message and its receiver.
    Wire(WireCase),
    /// Waypoint-file text (bytes: the checker replaces invalid UTF-8).
    Path(Vec<u8>),
    /// A record of a run with sensors followed by a `plans.log` entry.
    Recording(Vec<u8>),
    /// Bytes on the processor-in-the-loop serial line.
    Serial(Vec<u8>),
    /// A Monte Carlo shard's bytes.
    Shard(Vec<u8>),
    /// A run-time parameter input and its reader.
    Params(ParamsCase),
    /// A live bridge client's messages ([`live_messages`] reads them).
    Live(Vec<u8>),
}

impl Case {
    /// The raw input bytes (TOML text, or the message bytes).
    pub fn bytes(&self) -> &[u8] {
        match self {
            Case::Scenario(b)
            | Case::Path(b)
            | Case::Recording(b)
            | Case::Serial(b)
            | Case::Shard(b)
            | Case::Live(b) => b,
            Case::Wire(w) => &w.bytes,
            Case::Params(p) => &p.bytes,
        }
    }

    /// What besides the bytes defines the case (the wire receiver), for reports.
    pub fn context(&self) -> String {
        match self {
            Case::Scenario(_)
            | Case::Path(_)
            | Case::Recording(_)
            | Case::Serial(_)
            | Case::Shard(_) => String::new(),
            Case::Live(b) => format!("{} client messages", live_messages(b).len()),
            Case::Wire(w) => format!("{:?} message, receiver {:?}", w.kind, w.receiver),
            Case::Params(p) => format!("params {:?}, receiver {:?}", p.kind, p.receiver),
        }
    }
}

/// What the checked code did with one input (when it did not panic).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Accepted all the way.
    Accepted,
    /// Rejected with a typed error; the string names its kind (e.g.
    /// `"ScenarioError::Invalid (plant.inertia)"`, `"check_state: Invalid::NonFinite"`).
    Rejected(String),
}

/// A panic caught while checking one input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Panic {
    /// The panic message.
    pub message: String,
    /// `file:line:column` of the panic.
    pub location: String,
}

/// A panicking case.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// The target.
    pub target: Target,
    /// The run's seed.
    pub seed: u64,
    /// The case index (regenerate it with [`generate`] or `fuzz --seed S --case I`).
    pub case: u64,
    /// The input.
    pub input: Case,
    /// The panic.
    pub panic: Panic,
}

impl Finding {
    /// Writes `<dir>/<target>-seed<S>-case<I>.bin` (the input bytes) and `.txt` (panic,
    /// context, how to replay); returns the `.bin` path.
    pub fn save(&self, dir: &Path) -> io::Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        let stem = format!("{}-seed{}-case{}", self.target, self.seed, self.case);
        let bin = dir.join(format!("{stem}.bin"));
        std::fs::write(&bin, self.input.bytes())?;
        std::fs::write(dir.join(format!("{stem}.txt")), format!("{self}\n"))?;
        Ok(bin)
    }
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "panic at {}: {}",
            self.panic.location, self.panic.message
        )?;
        writeln!(
            f,
            "  case {} of seed {} (replay: fuzz --target {} --seed {} --case {})",
            self.case, self.seed, self.target, self.seed, self.case
        )?;
        let context = self.input.context();
        if !context.is_empty() {
            writeln!(f, "  {context}")?;
        }
        match &self.input {
            Case::Scenario(b) | Case::Path(b) => {
                write!(f, "  input:\n{}", String::from_utf8_lossy(b))
            }
            Case::Wire(w) => write!(f, "  input ({} bytes): {}", w.bytes.len(), hex(&w.bytes)),
            Case::Params(p) if p.kind == ParamsKind::Log => {
                write!(f, "  input:\n{}", String::from_utf8_lossy(&p.bytes))
            }
            Case::Recording(b) | Case::Serial(b) | Case::Shard(b) => {
                write!(f, "  input ({} bytes): {}", b.len(), hex(b))
            }
            Case::Params(p) => write!(f, "  input ({} bytes): {}", p.bytes.len(), hex(&p.bytes)),
            Case::Live(b) => {
                write!(f, "  input ({} bytes):", b.len())?;
                for m in live_messages(b) {
                    match m {
                        LiveMessage::Text(t) => write!(f, "\n    text {t:?}")?,
                        LiveMessage::Binary(b) => write!(f, "\n    binary {}", hex(&b))?,
                    }
                }
                Ok(())
            }
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    const SHOWN: usize = 400;
    let mut s: String = bytes
        .iter()
        .take(SHOWN)
        .map(|b| format!("{b:02x}"))
        .collect();
    if bytes.len() > SHOWN {
        s.push('…');
    }
    s
}

/// Findings kept per run: the first panic at each distinct location, up to this many.
pub const MAX_FINDINGS: usize = 8;

/// The result of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The target.
    pub target: Target,
    /// The seed.
    pub seed: u64,
    /// Cases run.
    pub cases: u64,
    /// Cases accepted all the way.
    pub accepted: u64,
    /// Cases rejected, by the kind of the first typed error.
    pub rejected: BTreeMap<String, u64>,
    /// Cases that panicked (all of them, including those not kept in `panics`).
    pub panic_count: u64,
    /// The first panicking case at each distinct panic location (at most [`MAX_FINDINGS`]).
    pub panics: Vec<Finding>,
    /// Wall time of the run.
    pub elapsed: Duration,
}

impl Report {
    /// Whether no case panicked.
    pub fn passed(&self) -> bool {
        self.panic_count == 0
    }

    /// Cases rejected, all kinds.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }

    /// Throughput.
    pub fn cases_per_second(&self) -> f64 {
        self.cases as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    fn record(&mut self, case: u64, input: impl FnOnce() -> Case, result: Result<Outcome, Panic>) {
        self.cases += 1;
        match result {
            Ok(Outcome::Accepted) => self.accepted += 1,
            Ok(Outcome::Rejected(kind)) => *self.rejected.entry(kind).or_default() += 1,
            Err(panic) => {
                self.panic_count += 1;
                if self.panics.len() < MAX_FINDINGS
                    && !self
                        .panics
                        .iter()
                        .any(|f| f.panic.location == panic.location)
                {
                    self.panics.push(Finding {
                        target: self.target,
                        seed: self.seed,
                        case,
                        input: input(),
                        panic,
                    });
                }
            }
        }
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |n: u64| 100.0 * n as f64 / self.cases.max(1) as f64;
        writeln!(
            f,
            "{}: {} cases in {:.2} s ({:.0} cases/s), seed {}",
            self.target,
            self.cases,
            self.elapsed.as_secs_f64(),
            self.cases_per_second(),
            self.seed
        )?;
        writeln!(
            f,
            "  accepted {:>10}  ({:5.1} %)",
            self.accepted,
            pct(self.accepted)
        )?;
        let rejected = self.rejected_total();
        writeln!(f, "  rejected {:>10}  ({:5.1} %)", rejected, pct(rejected))?;
        let width = self.rejected.keys().map(|k| k.chars().count()).max();
        for (kind, n) in &self.rejected {
            writeln!(
                f,
                "    {kind:<w$}  {n:>10}  ({:5.2} %)",
                pct(*n),
                w = width.unwrap_or(0)
            )?;
        }
        write!(
            f,
            "  panics   {:>10}  ({} distinct location(s) kept)",
            self.panic_count,
            self.panics.len()
        )?;
        for finding in &self.panics {
            write!(f, "\n  {}", finding.to_string().replace('\n', "\n    "))?;
        }
        Ok(())
    }
}

thread_local! {
    /// Whether this thread is inside [`run_case`].
    static CAPTURING: Cell<bool> = const { Cell::new(false) };
    /// The last panic caught on this thread inside [`run_case`].
    static CAUGHT: RefCell<Option<Panic>> = const { RefCell::new(None) };
}

/// Installs, once per process, a panic hook that is quiet on threads inside [`run_case`]
/// (it records the message and location there) and hands every other panic to the hook
/// that was installed before. Installed once rather than swapped per run, so that runs on
/// several threads (the test harness) do not race on the global hook.
fn install_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if CAPTURING.with(Cell::get) {
                let message = payload_text(info.payload());
                let location = info
                    .location()
                    .map_or_else(|| "(unknown)".to_owned(), ToString::to_string);
                CAUGHT.with(|c| *c.borrow_mut() = Some(Panic { message, location }));
            } else {
                previous(info);
            }
        }));
    });
}

/// The text of a panic payload (`panic!` gives a `&str` or a `String`).
fn payload_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(non-string panic payload)".to_owned())
}

/// Runs `check` on `input`, catching a panic: `Err` with the panic's message and location.
/// Generic over the checked function, so any code can be put under the harness.
pub fn run_case<I: ?Sized, F: FnOnce(&I) -> Outcome>(
    input: &I,
    check: F,
) -> Result<Outcome, Panic> {
    install_hook();
    let was = CAPTURING.with(|c| c.replace(true));
    let result = panic::catch_unwind(AssertUnwindSafe(|| check(input)));
    CAPTURING.with(|c| c.set(was));
    result.map_err(|payload| {
        CAUGHT
            .with(|c| c.borrow_mut().take())
            .unwrap_or_else(|| Panic {
                message: payload_text(payload.as_ref()),
                location: "(unknown)".to_owned(),
            })
    })
}

/// The real checks: each target's oracle, by the case's kind.
pub fn check(case: &Case) -> Outcome {
    match case {
        Case::Scenario(bytes) => scenario_target::check(bytes),
        Case::Path(bytes) => path_target::check(bytes),
        Case::Wire(w) => wire_target::check(w),
        Case::Recording(bytes) => recording_target::check(bytes),
        Case::Serial(bytes) => serial_target::check(bytes),
        Case::Shard(bytes) => shard_target::check(bytes),
        Case::Params(p) => params_target::check(p),
        Case::Live(bytes) => live_target::check(bytes),
    }
}

/// The case generator of one target and seed.
pub struct Generator {
    target: Target,
    streams: rng::Streams,
    scenarios: Option<scenario_target::Corpus>,
    paths: Option<path_target::Corpus>,
    wire: Option<wire_target::Corpus>,
    recordings: Option<recording_target::Corpus>,
    serial: Option<serial_target::Corpus>,
    shards: Option<shard_target::Corpus>,
    params: Option<params_target::Corpus>,
    live: Option<live_target::Corpus>,
}

impl Generator {
    /// The generator of `target` seeded with `seed` (builds the seed corpus).
    pub fn new(target: Target, seed: u64) -> Generator {
        Generator {
            target,
            streams: rng::Streams::new(seed),
            scenarios: (target == Target::Scenario).then(scenario_target::Corpus::new),
            paths: (target == Target::Path).then(path_target::Corpus::new),
            wire: (target == Target::Wire).then(wire_target::Corpus::new),
            recordings: (target == Target::Recording).then(recording_target::Corpus::new),
            serial: (target == Target::Serial).then(serial_target::Corpus::new),
            shards: (target == Target::Shard).then(shard_target::Corpus::new),
            params: (target == Target::Params).then(params_target::Corpus::new),
            live: (target == Target::Live).then(live_target::Corpus::new),
        }
    }

    /// Case `case` (depends only on the target, the seed and `case`).
    pub fn case(&self, case: u64) -> Case {
        let mut g = self.streams.case(case);
        if let Some(c) = &self.serial {
            return Case::Serial(c.generate(&mut g));
        }
        if let Some(c) = &self.shards {
            return Case::Shard(c.generate(&mut g));
        }
        if let Some(c) = &self.params {
            return Case::Params(c.generate(&mut g));
        }
        if let Some(c) = &self.live {
            return Case::Live(c.generate(&mut g));
        }
        match (&self.scenarios, &self.wire, &self.paths, &self.recordings) {
            (Some(c), _, _, _) => Case::Scenario(c.generate(&mut g)),
            (_, Some(c), _, _) => Case::Wire(c.generate(&mut g)),
            (_, _, Some(c), _) => Case::Path(c.generate(&mut g)),
            (_, _, _, Some(c)) => Case::Recording(c.generate(&mut g)),
            _ => unreachable!("a generator has the corpus of its target"),
        }
    }

    /// The target.
    pub fn target(&self) -> Target {
        self.target
    }
}

/// Case `case` of `target` with seed `seed`.
pub fn generate(target: Target, seed: u64, case: u64) -> Case {
    Generator::new(target, seed).case(case)
}

/// Regenerates one case and checks it *without* catching panics (the default hook prints
/// it, with a backtrace under `RUST_BACKTRACE=1`): the reproduction of a finding.
pub fn replay(target: Target, seed: u64, case: u64) -> (Case, Outcome) {
    let input = generate(target, seed, case);
    let outcome = check(&input);
    (input, outcome)
}

/// Runs cases `0..cases` of `target` with seed `seed` through the real checks.
pub fn run(target: Target, cases: u64, seed: u64) -> Report {
    run_with(target, seed, 0..cases, check, |_| {})
}

/// Runs cases `cases` of `target` with seed `seed` through `check` (the real one is
/// [`check`]; a test can wrap it to plant a bug), calling `progress` with the number of
/// cases done every 1024 cases and at the end.
pub fn run_with<C, P>(
    target: Target,
    seed: u64,
    cases: Range<u64>,
    check: C,
    mut progress: P,
) -> Report
where
    C: Fn(&Case) -> Outcome,
    P: FnMut(u64),
{
    let start = Instant::now();
    let generator = Generator::new(target, seed);
    let mut report = Report {
        target,
        seed,
        cases: 0,
        accepted: 0,
        rejected: BTreeMap::new(),
        panic_count: 0,
        panics: Vec::new(),
        elapsed: Duration::ZERO,
    };
    for case in cases {
        let input = generator.case(case);
        let result = run_case(&input, &check);
        report.record(case, || input.clone(), result);
        if report.cases.is_multiple_of(1024) {
            progress(report.cases);
        }
    }
    progress(report.cases);
    report.elapsed = start.elapsed();
    report
}

/// Where `fuzz --save` writes findings: `target/fuzz-findings/` of this workspace.
pub fn default_findings_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .join("target")
        .join("fuzz-findings")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panicking_check_is_recorded_with_message_and_location() {
        let caught = run_case(&41u32, |x: &u32| {
            if *x == 41 {
                panic!("planted bug: {x}");
            }
            Outcome::Accepted
        });
        let p = caught.unwrap_err();
        assert_eq!(p.message, "planted bug: 41");
        assert!(p.location.contains("lib.rs"), "{}", p.location);
        // the thread is no longer capturing, and a good check passes through
        assert!(!CAPTURING.with(Cell::get));
        assert_eq!(
            run_case(&1u32, |_| Outcome::Accepted),
            Ok(Outcome::Accepted)
        );
    }

    #[test]
    fn a_planted_bug_in_a_run_fails_the_run_and_keeps_the_input() {
        let planted = |case: &Case| match case {
            Case::Wire(w) if w.bytes.len() == ipc_types::STATE_BYTES + 1 => {
                let v: Vec<u8> = vec![];
                // an out-of-bounds index, the typical decoder bug
                Outcome::Rejected(format!("{}", v[w.bytes.len()]))
            }
            other => check(other),
        };
        let r = run_with(Target::Wire, 9, 0..3000, planted, |_| {});
        assert!(!r.passed());
        assert!(r.panic_count > 0);
        let f = &r.panics[0];
        assert!(f.panic.message.contains("index out of bounds"), "{f}");
        assert_eq!(f.input.bytes().len(), ipc_types::STATE_BYTES + 1);
        assert_eq!(generate(Target::Wire, 9, f.case), f.input);
        assert_eq!(r.cases, 3000);
        assert_eq!(r.accepted + r.rejected_total() + r.panic_count, r.cases);
    }

    #[test]
    fn findings_are_saved() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("findings");
        let f = Finding {
            target: Target::Scenario,
            seed: 1,
            case: 2,
            input: Case::Scenario(b"group = \"so3\"".to_vec()),
            panic: Panic {
                message: "m".to_owned(),
                location: "x.rs:1:1".to_owned(),
            },
        };
        let bin = f.save(&dir).unwrap();
        assert_eq!(std::fs::read(&bin).unwrap(), b"group = \"so3\"");
        let txt = std::fs::read_to_string(bin.with_extension("txt")).unwrap();
        assert!(
            txt.contains("fuzz --target scenario --seed 1 --case 2"),
            "{txt}"
        );
    }
}
