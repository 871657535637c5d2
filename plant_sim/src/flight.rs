//! The flight recorder: `messages.log`, every cycle of a `plant_sim run` as it happened
//! (docs/architecture.md, "The flight recorder").
//!
//! A small fixed header ([`Header`], [`HEADER_BYTES`]) is followed by fixed-size records
//! ([`Record`], [`RECORD_BYTES`]), all little-endian: the state message the plant published
//! for tick k, the command that answered it (if one came in time), the plant's decision
//! (fresh, held, safe mode), the torque applied and the monotonic stamps. A log cut short
//! (a SIGKILL) is read up to its last whole record.
//!
//! The loop's thread only copies a [`Record`] into a preallocated bounded channel
//! ([`Recorder::push`]: `try_send`, no allocation, no formatting, no system call: nobody
//! waits on the channel, so nobody is woken). A writer thread polls the channel, encodes the
//! records and appends them to the file, flushing after each pass; it also feeds the run's
//! live status to a [`StatusSink`] (the monitor's board). When the run ends, for any
//! reason the loop notices (its end, SIGINT, SIGTERM), [`Recorder::finish`] drains it.

use crate::SimError;
use ipc_types::{
    COMMAND_BYTES, CommandMsg, MAX_M, NAME_BYTES, STATE_BYTES, StateMsg, padded_bytes, padded_str,
};
use link::Decision;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::Duration;

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"EQTRKLOG";
/// The format version this build writes and reads (3: the records hold the state and command
/// messages of protocol 5, whose command names the law that computed it: 760 bytes. 2: the
/// messages of protocols 3 and 4, 752 bytes; 1: before protocol 3. Other versions are
/// refused, naming both).
pub const FORMAT_VERSION: u32 = 3;
/// Bytes of the header.
pub const HEADER_BYTES: usize = 192;
/// Where a record's state message starts.
pub const RECORD_STATE_OFFSET: usize = 80;
/// Where a record's command message starts.
pub const RECORD_COMMAND_OFFSET: usize = RECORD_STATE_OFFSET + STATE_BYTES;
/// Bytes of a record.
pub const RECORD_BYTES: usize = RECORD_COMMAND_OFFSET + COMMAND_BYTES;
/// The file name in a run's output directory.
pub const LOG_FILE: &str = "messages.log";

/// Where, inside a record, the recorded command's torque entry `axis` starts (8 bytes,
/// little-endian f64): the command's layout is docs/wire.md's.
pub fn torque_byte_offset(axis: usize) -> usize {
    // version, group (u32 each), seq, state_received_ns, stamp_ns, compute_ns (u64 each)
    RECORD_COMMAND_OFFSET + 8 + 32 + 8 * axis
}

/// What a log says about its run.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The group's wire code (`ipc_types::group_code`).
    pub group: u32,
    /// The control period the plant ran at (s).
    pub control_period: f64,
    /// Real time: the rate (Hz); lockstep: 0.
    pub rate_hz: f64,
    /// `true`: real time; `false`: lockstep.
    pub realtime: bool,
    /// `true`: event wake-up; `false`: busy polling.
    pub event_wake: bool,
    /// Consecutive misses that start safe mode.
    pub miss_limit: u32,
    /// The scenario's fingerprint (`Scenario::fingerprint`), as loaded.
    pub fingerprint: u64,
    /// The run name.
    pub run: String,
    /// The scenario's name.
    pub scenario: String,
    /// The scenario's law (as the plant loaded it).
    pub law: String,
    /// The plant's process id.
    pub plant_pid: u32,
}

impl Header {
    /// The header's bytes.
    pub fn to_bytes(&self) -> [u8; HEADER_BYTES] {
        let mut b = [0u8; HEADER_BYTES];
        b[0..8].copy_from_slice(&MAGIC);
        put(&mut b, 8, &FORMAT_VERSION.to_le_bytes());
        put(&mut b, 12, &(HEADER_BYTES as u32).to_le_bytes());
        put(&mut b, 16, &(RECORD_BYTES as u32).to_le_bytes());
        put(&mut b, 20, &self.group.to_le_bytes());
        put(&mut b, 24, &self.control_period.to_le_bytes());
        put(&mut b, 32, &self.rate_hz.to_le_bytes());
        b[40] = u8::from(self.realtime);
        b[41] = u8::from(self.event_wake);
        put(&mut b, 44, &self.miss_limit.to_le_bytes());
        put(&mut b, 48, &self.fingerprint.to_le_bytes());
        put(&mut b, 56, &padded_bytes::<64>(&self.run));
        put(&mut b, 120, &padded_bytes::<NAME_BYTES>(&self.scenario));
        put(&mut b, 152, &padded_bytes::<16>(&self.law));
        put(&mut b, 168, &self.plant_pid.to_le_bytes());
        b
    }

    /// Reads a header; names what is wrong with one that is not ours.
    pub fn from_bytes(b: &[u8]) -> Result<Header, String> {
        if b.len() < 20 || b[0..8] != MAGIC {
            return Err(
                "not an eqtrack flight recording (its first bytes are not `EQTRKLOG`)".into(),
            );
        }
        let version = u32_at(b, 8);
        if version != FORMAT_VERSION {
            return Err(format!(
                "format version {version}; this build reads version {FORMAT_VERSION}"
            ));
        }
        let (hb, rb) = (u32_at(b, 12) as usize, u32_at(b, 16) as usize);
        if hb != HEADER_BYTES || rb != RECORD_BYTES || b.len() < HEADER_BYTES {
            return Err(format!(
                "header of {hb} bytes and records of {rb} bytes; version {FORMAT_VERSION} has {HEADER_BYTES} and {RECORD_BYTES}"
            ));
        }
        Ok(Header {
            group: u32_at(b, 20),
            control_period: f64_at(b, 24),
            rate_hz: f64_at(b, 32),
            realtime: b[40] != 0,
            event_wake: b[41] != 0,
            miss_limit: u32_at(b, 44),
            fingerprint: u64_at(b, 48),
            run: text::<64>(b, 56),
            scenario: text::<NAME_BYTES>(b, 120),
            law: text::<16>(b, 152),
            plant_pid: u32_at(b, 168),
        })
    }
}

/// One cycle as the plant saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// The tick k.
    pub cycle: u64,
    /// What the plant applied.
    pub decision: Decision,
    /// Consecutive deadline misses up to and including this tick.
    pub misses_in_row: u32,
    /// The tick's deadline (CLOCK_MONOTONIC ns; lockstep: its nominal time).
    pub deadline_ns: u64,
    /// The torque applied over `[t_k, t_{k+1})` (after saturation; m entries, then zeros).
    pub applied: [f64; MAX_M],
    /// The state published for tick k, with its publication stamp.
    pub state: StateMsg,
    /// The command for tick k and when it was received (CLOCK_MONOTONIC ns), if it came
    /// in time.
    pub command: Option<(CommandMsg, u64)>,
}

impl Record {
    /// The record's bytes.
    pub fn to_bytes(&self) -> [u8; RECORD_BYTES] {
        let mut b = [0u8; RECORD_BYTES];
        put(&mut b, 0, &self.cycle.to_le_bytes());
        b[8] = self.decision.code();
        b[9] = u8::from(self.command.is_some());
        put(&mut b, 12, &self.misses_in_row.to_le_bytes());
        put(&mut b, 16, &self.deadline_ns.to_le_bytes());
        put(&mut b, 24, &self.command.map_or(0, |c| c.1).to_le_bytes());
        for (i, x) in self.applied.iter().enumerate() {
            put(&mut b, 32 + 8 * i, &x.to_le_bytes());
        }
        put(&mut b, RECORD_STATE_OFFSET, &self.state.to_bytes());
        if let Some((c, _)) = &self.command {
            put(&mut b, RECORD_COMMAND_OFFSET, &c.to_bytes());
        }
        b
    }

    /// Reads a record.
    pub fn from_bytes(b: &[u8; RECORD_BYTES]) -> Result<Record, String> {
        let decision = match b[8] {
            0 => Decision::Fresh,
            1 => Decision::Held,
            2 => Decision::Safe,
            d => return Err(format!("decision code {d} (expected 0, 1 or 2)")),
        };
        let state = StateMsg::from_bytes(&b[RECORD_STATE_OFFSET..RECORD_COMMAND_OFFSET])
            .map_err(|e| format!("state message: {e}"))?;
        let command = match b[9] {
            0 => None,
            _ => Some((
                CommandMsg::from_bytes(&b[RECORD_COMMAND_OFFSET..])
                    .map_err(|e| format!("command message: {e}"))?,
                u64_at(b, 24),
            )),
        };
        Ok(Record {
            cycle: u64_at(b, 0),
            decision,
            misses_in_row: u32_at(b, 12),
            deadline_ns: u64_at(b, 16),
            applied: std::array::from_fn(|i| f64_at(b, 32 + 8 * i)),
            state,
            command,
        })
    }
}

fn put(b: &mut [u8], at: usize, bytes: &[u8]) {
    b[at..at + bytes.len()].copy_from_slice(bytes);
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or([0; 4]))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap_or([0; 8]))
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_bits(u64_at(b, at))
}

/// The NUL-padded text in the `N` bytes at `at`.
fn text<const N: usize>(b: &[u8], at: usize) -> String {
    let bytes: [u8; N] = b[at..at + N].try_into().unwrap_or([0; N]);
    padded_str(&bytes).to_owned()
}

/// A log opened for reading: its header, then [`LogReader::next_record`] until `None`.
pub struct LogReader {
    input: BufReader<File>,
    path: PathBuf,
    /// The header.
    pub header: Header,
    /// Whole records in the file.
    pub records: u64,
    /// Bytes after the last whole record (a recording cut short mid-record).
    pub trailing_bytes: u64,
    read: u64,
}

impl LogReader {
    /// Opens `path` and reads its header.
    pub fn open(path: &Path) -> Result<LogReader, SimError> {
        let bad = |what: String| SimError::Input(format!("{}: {what}", path.display()));
        let file = File::open(path).map_err(|e| bad(format!("cannot open: {e}")))?;
        let len = file
            .metadata()
            .map_err(|e| bad(format!("cannot read its size: {e}")))?
            .len();
        let mut input = BufReader::with_capacity(1 << 16, file);
        let mut head = [0u8; HEADER_BYTES];
        input.read_exact(&mut head).map_err(|_| {
            bad(format!(
                "{len} bytes: shorter than the {HEADER_BYTES}-byte header of a flight recording"
            ))
        })?;
        let header = Header::from_bytes(&head).map_err(bad)?;
        let body = len.saturating_sub(HEADER_BYTES as u64);
        Ok(LogReader {
            input,
            path: path.to_owned(),
            header,
            records: body / RECORD_BYTES as u64,
            trailing_bytes: body % RECORD_BYTES as u64,
            read: 0,
        })
    }

    /// The next whole record, `None` after the last one.
    pub fn next_record(&mut self) -> Result<Option<Record>, SimError> {
        if self.read == self.records {
            return Ok(None);
        }
        let mut b = [0u8; RECORD_BYTES];
        let at = self.read;
        self.input
            .read_exact(&mut b)
            .map_err(|e| SimError::Run(format!("{}: record {at}: {e}", self.path.display())))?;
        self.read += 1;
        Record::from_bytes(&b)
            .map(Some)
            .map_err(|e| SimError::Input(format!("{}: record {at}: {e}", self.path.display())))
    }
}

/// What the writer thread did.
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct RecordingReport {
    /// The log's path.
    pub path: String,
    /// Records written.
    pub records: u64,
    /// Records the loop could not hand over (the channel was full: the disk did not keep
    /// up). Replay shows them as gaps.
    pub dropped: u64,
    /// Why the file stopped being written, if it did (a full disk): the records before it
    /// are in the file, and the live status went on.
    pub error: Option<String>,
}

/// Where the writer thread sends the run's live figures (the monitor's board), besides the
/// file. Made and called on the writer thread only.
pub trait StatusSink {
    /// A record, in cycle order (for the sink's own statistics).
    fn record(&mut self, r: &Record);
    /// Called after each pass over the channel (about every millisecond).
    fn tick(&mut self);
    /// The run ended.
    fn end(&mut self);
}

/// Makes a [`StatusSink`] on the writer thread (`None`: none after all).
pub type SinkFactory = Box<dyn FnOnce() -> Option<Box<dyn StatusSink>> + Send>;

/// The loop's end of the recorder.
pub struct Recorder {
    tx: Option<SyncSender<Record>>,
    dropped: u64,
    thread: Option<JoinHandle<(u64, Option<String>)>>,
    path: PathBuf,
}

/// How long the writer sleeps between passes over the channel.
const POLL: Duration = Duration::from_millis(1);

impl Recorder {
    /// Creates `dir/messages.log`, writes the header and starts the writer thread. The
    /// channel holds `capacity` records; the file and `sink` get them.
    pub fn start(
        dir: &Path,
        header: &Header,
        capacity: usize,
        sink: Option<SinkFactory>,
    ) -> Result<Recorder, SimError> {
        let path = dir.join(LOG_FILE);
        let file = File::create(&path)
            .map_err(|e| SimError::Run(format!("cannot create {}: {e}", path.display())))?;
        let mut w = BufWriter::with_capacity(1 << 16, file);
        w.write_all(&header.to_bytes())
            .and_then(|_| w.flush())
            .map_err(|e| SimError::Run(format!("{}: {e}", path.display())))?;
        let out = Some(w);
        let (tx, rx) = sync_channel::<Record>(capacity.max(1));
        let shown = path.display().to_string();
        let thread = std::thread::Builder::new()
            .name("recorder".to_owned())
            .spawn(move || {
                let mut sink = sink.and_then(|make| make());
                let (written, error) = write_loop(&rx, out, sink.as_deref_mut());
                if let Some(s) = sink.as_deref_mut() {
                    s.end();
                }
                (written, error.map(|e| format!("{shown}: {e}")))
            })
            .map_err(|e| SimError::Run(format!("cannot start the recorder thread: {e}")))?;
        Ok(Recorder {
            tx: Some(tx),
            dropped: 0,
            thread: Some(thread),
            path,
        })
    }

    /// Hands one record to the writer: a copy into the preallocated channel, nothing else
    /// (a full channel drops it and counts the drop).
    pub fn push(&mut self, r: &Record) {
        if let Some(tx) = &self.tx {
            match tx.try_send(*r) {
                Ok(()) => {}
                Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                    self.dropped += 1
                }
            }
        }
    }

    /// Closes the channel, lets the writer drain it, flush and sync the file.
    pub fn finish(mut self) -> Result<RecordingReport, SimError> {
        self.tx = None;
        let (records, error) = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => return Err(SimError::Run("the recorder thread panicked".into())),
            None => (0, None),
        };
        Ok(RecordingReport {
            path: self.path.display().to_string(),
            records,
            dropped: self.dropped,
            error,
        })
    }
}

impl Drop for Recorder {
    /// A run that ends on an error still gets its log: close the channel and let the writer
    /// drain it.
    fn drop(&mut self) {
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The writer thread: drain, encode, append, flush; sleep; until the loop closes the
/// channel. A file that cannot be written any more (a full disk) is given up, and the
/// channel is still drained for the live status. Returns the records written and the error
/// that stopped the file, if any.
fn write_loop(
    rx: &Receiver<Record>,
    mut out: Option<BufWriter<File>>,
    mut sink: Option<&mut (dyn StatusSink + 'static)>,
) -> (u64, Option<std::io::Error>) {
    let mut written = 0u64;
    let mut error = None;
    let mut give_up = |out: &mut Option<BufWriter<File>>, e: std::io::Error| {
        *out = None;
        error.get_or_insert(e);
    };
    loop {
        let mut got = false;
        let closed = loop {
            match rx.try_recv() {
                Ok(r) => {
                    got = true;
                    if let Some(w) = out.as_mut() {
                        match w.write_all(&r.to_bytes()) {
                            Ok(()) => written += 1,
                            Err(e) => give_up(&mut out, e),
                        }
                    }
                    if let Some(s) = sink.as_deref_mut() {
                        s.record(&r);
                    }
                }
                Err(TryRecvError::Empty) => break false,
                Err(TryRecvError::Disconnected) => break true,
            }
        };
        // whole records only: BufWriter writes its buffer out before a record that does
        // not fit, so the file always ends on a record boundary between passes
        if got && let Some(Err(e)) = out.as_mut().map(BufWriter::flush) {
            give_up(&mut out, e);
        }
        if let Some(s) = sink.as_deref_mut() {
            s.tick();
        }
        if closed {
            if let Some(mut w) = out.take()
                && let Err(e) = w.flush().and_then(|_| w.get_ref().sync_all())
            {
                give_up(&mut out, e);
            }
            return (written, error);
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller::GroupKind;

    fn record(k: u64, with_command: bool) -> Record {
        let mut state = StateMsg::new(GroupKind::Se3);
        state.seq = k;
        state.t = k as f64 * 0.001;
        state.v = [0.1, -0.2, 0.3, 1e-300, f64::MIN_POSITIVE, -0.0];
        state.stamp_ns = 1_000 + k;
        let mut cmd = CommandMsg::new(GroupKind::Se3);
        cmd.seq = k;
        cmd.tau = [1.0, -2.0, 3.5, 0.25, -0.125, 7.0];
        cmd.lyapunov = 0.5;
        Record {
            cycle: k,
            decision: if with_command {
                Decision::Fresh
            } else {
                Decision::Safe
            },
            misses_in_row: if with_command { 0 } else { 4 },
            deadline_ns: 5_000 + k,
            applied: [0.5; MAX_M],
            state,
            command: with_command.then_some((cmd, 4_000 + k)),
        }
    }

    #[test]
    fn records_and_headers_round_trip_bit_for_bit() {
        for r in [record(7, true), record(8, false)] {
            let back = Record::from_bytes(&r.to_bytes()).unwrap();
            assert_eq!(back.to_bytes(), r.to_bytes());
            assert_eq!(back.command.is_some(), r.command.is_some());
        }
        let h = Header {
            group: 2,
            control_period: 0.001,
            rate_hz: 1000.0,
            realtime: true,
            event_wake: false,
            miss_limit: 3,
            fingerprint: 0xdead_beef,
            run: "board-7".into(),
            scenario: "se3_circle".into(),
            law: "eqt".into(),
            plant_pid: 42,
        };
        assert_eq!(Header::from_bytes(&h.to_bytes()).unwrap(), h);
        let mut bad = h.to_bytes();
        bad[8] = 9;
        assert!(Header::from_bytes(&bad).unwrap_err().contains("version 9"));
        assert!(Header::from_bytes(b"not a log at all, no").is_err());
    }

    #[test]
    fn the_torque_offset_points_at_the_commands_torque() {
        let r = record(3, true);
        let b = r.to_bytes();
        for axis in 0..MAX_M {
            let at = torque_byte_offset(axis);
            assert_eq!(
                f64_at(&b, at),
                r.command.unwrap().0.tau[axis],
                "axis {axis}"
            );
        }
    }

    #[test]
    fn the_writer_drains_everything_and_a_cut_log_reads_to_its_last_whole_record() {
        let dir = std::env::temp_dir().join(format!("eqtrack-flight-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let h = Header {
            group: 2,
            control_period: 0.001,
            rate_hz: 0.0,
            realtime: false,
            event_wake: true,
            miss_limit: 3,
            fingerprint: 1,
            run: "x".into(),
            scenario: "y".into(),
            law: "eqt".into(),
            plant_pid: 1,
        };
        // a small channel: the loop outpaces the writer, pushes are dropped and counted
        let mut rec = Recorder::start(&dir, &h, 4, None).unwrap();
        let mut pushed = 0;
        for k in 0..2000 {
            rec.push(&record(k, k % 3 != 0));
            pushed += 1;
            if k % 50 == 0 {
                std::thread::sleep(Duration::from_millis(3));
            }
        }
        let report = rec.finish().unwrap();
        assert_eq!(report.records + report.dropped, pushed);
        assert!(report.records >= 40, "{report:?}");
        let path = dir.join(LOG_FILE);
        let mut log = LogReader::open(&path).unwrap();
        assert_eq!(log.header, h);
        assert_eq!((log.records, log.trailing_bytes), (report.records, 0));
        let mut last = None;
        while let Some(r) = log.next_record().unwrap() {
            assert!(last.is_none_or(|l| r.cycle > l), "cycles increase");
            assert_eq!(r.to_bytes(), record(r.cycle, r.cycle % 3 != 0).to_bytes());
            last = Some(r.cycle);
        }
        // cut mid-record, as after a SIGKILL
        let len = std::fs::metadata(&path).unwrap().len();
        let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        f.set_len(len - 100).unwrap();
        let log = LogReader::open(&path).unwrap();
        assert_eq!(log.records, report.records - 1);
        assert_eq!(log.trailing_bytes, RECORD_BYTES as u64 - 100);
        // shorter than a header, or not a log: errors that name the file, no panic
        for len in [0, 10, HEADER_BYTES as u64 - 1] {
            f.set_len(len).unwrap();
            let e = LogReader::open(&path).err().unwrap().to_string();
            assert!(e.contains("messages.log") && e.contains("header"), "{e}");
        }
        std::fs::write(&path, [b'x'; 300]).unwrap();
        let e = LogReader::open(&path).err().unwrap().to_string();
        assert!(e.contains("not an eqtrack flight recording"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
