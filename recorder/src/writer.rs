//! The recorder's writer: the loop's thread only copies a [`Record`] into a preallocated
//! bounded channel ([`Recorder::push`]: `try_send`, no allocation, no formatting, no system
//! call: nobody waits on the channel, so nobody is woken). A writer thread polls the channel,
//! encodes the records and appends them to `messages.log`, flushing after each pass; it also
//! feeds the run's live status to a [`StatusSink`] (the monitor's board) and, given a
//! [`PlanSource`], appends every new plan message on the run's plan board to `plans.log`.
//! When the run ends, for any reason the loop notices (its end, SIGINT, SIGTERM),
//! [`Recorder::finish`] drains it.
//!
//! A lockstep run's log depends on the scenario alone: the writer keeps its records in
//! [`Record::lockstep_form`] (nominal times instead of clock readings, ordinals instead of
//! process ids), and a full channel makes the loop wait for the disk instead of dropping a
//! record (lockstep has no deadline to miss).

use super::format::{
    Header, LOG_FILE, PLANS_FILE, PidOrdinals, PlanEntry, RECORD_BYTES, Record, SENSOR_BYTES,
    plans_header,
};
use crate::RecorderError;
use ipc_types::PlanMsg;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::Duration;

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
    /// Plan messages written to `plans.log` (a streamed run).
    #[serde(skip_serializing_if = "is_zero")]
    pub plans: u64,
}

fn is_zero(x: &u64) -> bool {
    *x == 0
}

/// The plan board as the writer thread reads it: the next plan message not seen yet, or
/// `None` (call until `None`).
pub type PlanSource = Box<dyn FnMut() -> Option<PlanMsg>>;

/// Makes a [`PlanSource`] on the writer thread (`None`: no plan board after all).
pub type PlanSourceFactory = Box<dyn FnOnce() -> Option<PlanSource> + Send>;

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
    /// Lockstep: wait for room in the channel instead of dropping a record.
    wait_when_full: bool,
    dropped: u64,
    thread: Option<JoinHandle<Written>>,
    path: PathBuf,
}

/// How long the writer sleeps between passes over the channel.
const POLL: Duration = Duration::from_millis(1);

impl Recorder {
    /// Creates `dir/messages.log`, writes the header and starts the writer thread. The
    /// channel holds `capacity` records; the file and `sink` get them. With `plans`, each
    /// pass also appends the plan board's new messages to `dir/plans.log` (created at the
    /// first).
    pub fn start(
        dir: &Path,
        header: &Header,
        capacity: usize,
        sink: Option<SinkFactory>,
        plans: Option<PlanSourceFactory>,
    ) -> Result<Recorder, RecorderError> {
        let path = dir.join(LOG_FILE);
        let file = File::create(&path)
            .map_err(|e| RecorderError::Io(format!("cannot create {}: {e}", path.display())))?;
        let mut w = BufWriter::with_capacity(1 << 16, file);
        let lockstep = (!header.realtime).then(|| Lockstep {
            period_ns: (header.control_period * 1e9).round() as u64,
            pids: PidOrdinals::default(),
        });
        let mut kept = header.clone();
        if lockstep.is_some() {
            kept.plant_pid = 0;
        }
        w.write_all(&kept.to_bytes())
            .and_then(|_| w.flush())
            .map_err(|e| RecorderError::Io(format!("{}: {e}", path.display())))?;
        let out = Some(w);
        let (tx, rx) = sync_channel::<Record>(capacity.max(1));
        let shown = path.display().to_string();
        let record_bytes = header.record_bytes();
        let plans_path = dir.join(PLANS_FILE);
        let (ready_tx, ready) = sync_channel::<()>(1);
        let thread = std::thread::Builder::new()
            .name("recorder".to_owned())
            .spawn(move || {
                let mut sink = sink.and_then(|make| make());
                let mut plans = plans.and_then(|make| make()).map(|source| Plans {
                    source,
                    path: plans_path,
                    out: None,
                    written: 0,
                    error: None,
                });
                let mut lockstep = lockstep;
                // what is on the plan board before the run starts is kept too
                if let Some(p) = plans.as_mut() {
                    p.poll(None, lockstep.as_mut().map(|l| &mut l.pids));
                }
                let _ = ready_tx.send(());
                let files = Files {
                    out,
                    record_bytes,
                    plans,
                    lockstep,
                };
                let mut w = write_loop(&rx, files, sink.as_deref_mut());
                if let Some(s) = sink.as_deref_mut() {
                    s.end();
                }
                w.error = w.error.map(|e| format!("{shown}: {e}"));
                w
            })
            .map_err(|e| RecorderError::Io(format!("cannot start the recorder thread: {e}")))?;
        // the run starts once the recorder reads its boards: a plan message published
        // before the first state is in the record whatever the planner does next
        let _ = ready.recv_timeout(Duration::from_secs(10));
        Ok(Recorder {
            tx: Some(tx),
            wait_when_full: !header.realtime,
            dropped: 0,
            thread: Some(thread),
            path,
        })
    }

    /// Hands one record to the writer: a copy into the preallocated channel, nothing else
    /// (a full channel drops it and counts the drop; in lockstep it waits for room).
    pub fn push(&mut self, r: &Record) {
        if let Some(tx) = &self.tx {
            if self.wait_when_full {
                if tx.send(*r).is_err() {
                    self.dropped += 1;
                }
                return;
            }
            match tx.try_send(*r) {
                Ok(()) => {}
                Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                    self.dropped += 1
                }
            }
        }
    }

    /// Closes the channel, lets the writer drain it, flush and sync the file.
    pub fn finish(mut self) -> Result<RecordingReport, RecorderError> {
        self.tx = None;
        let w = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(w)) => w,
            Some(Err(_)) => return Err(RecorderError::Io("the recorder thread panicked".into())),
            None => Written::default(),
        };
        Ok(RecordingReport {
            path: self.path.display().to_string(),
            records: w.records,
            dropped: self.dropped,
            error: w.error,
            plans: w.plans,
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

/// What the writer thread wrote.
#[derive(Debug, Default)]
struct Written {
    records: u64,
    plans: u64,
    /// Why a file stopped being written.
    error: Option<String>,
}

/// What a lockstep log replaces clock readings and process ids with.
struct Lockstep {
    period_ns: u64,
    pids: PidOrdinals,
}

/// What the writer thread writes to.
struct Files {
    /// `messages.log` (`None` once it failed).
    out: Option<BufWriter<File>>,
    record_bytes: usize,
    plans: Option<Plans>,
    /// A lockstep run's log ([`Record::lockstep_form`]).
    lockstep: Option<Lockstep>,
}

/// `plans.log` and where its messages come from.
struct Plans {
    source: PlanSource,
    path: PathBuf,
    out: Option<BufWriter<File>>,
    written: u64,
    error: Option<String>,
}

impl Plans {
    /// Appends every new plan message (creating the file at the first), flushed; a lockstep
    /// log's planner pids become their ordinals in `pids`.
    fn poll(&mut self, last_cycle: Option<u64>, mut pids: Option<&mut PidOrdinals>) {
        let mut got = false;
        while let Some(mut msg) = (self.source)() {
            if let Some(p) = pids.as_deref_mut() {
                msg.planner_pid = p.ordinal(msg.planner_pid);
            }
            if self.error.is_some() {
                continue;
            }
            if self.out.is_none() {
                match File::create(&self.path).and_then(|f| {
                    let mut w = BufWriter::new(f);
                    w.write_all(&plans_header()).map(|_| w)
                }) {
                    Ok(w) => self.out = Some(w),
                    Err(e) => {
                        self.error = Some(format!("{}: {e}", self.path.display()));
                        continue;
                    }
                }
            }
            let entry = PlanEntry {
                seen_after: last_cycle.unwrap_or(u64::MAX),
                msg,
            };
            if let Some(w) = self.out.as_mut() {
                match w.write_all(&entry.to_bytes()) {
                    Ok(()) => {
                        self.written += 1;
                        got = true;
                    }
                    Err(e) => {
                        self.error = Some(format!("{}: {e}", self.path.display()));
                        self.out = None;
                    }
                }
            }
        }
        if got && let Some(Err(e)) = self.out.as_mut().map(BufWriter::flush) {
            self.error = Some(format!("{}: {e}", self.path.display()));
            self.out = None;
        }
    }
}

/// The writer thread: poll the plan board, drain, encode, append, flush; sleep; until the
/// loop closes the channel. A file that cannot be written any more (a full disk) is given
/// up, and the channel is still drained for the live status. Returns what it wrote and the
/// error that stopped a file, if any.
fn write_loop(
    rx: &Receiver<Record>,
    files: Files,
    mut sink: Option<&mut (dyn StatusSink + 'static)>,
) -> Written {
    let Files {
        mut out,
        record_bytes,
        mut plans,
        mut lockstep,
    } = files;
    let mut written = 0u64;
    let mut error = None;
    let mut last_cycle = None;
    let mut bytes = [0u8; RECORD_BYTES + SENSOR_BYTES];
    let bytes = &mut bytes[..record_bytes];
    let mut give_up = |out: &mut Option<BufWriter<File>>, e: std::io::Error| {
        *out = None;
        error.get_or_insert(e);
    };
    let end = |written: u64, error: Option<std::io::Error>, plans: Option<Plans>| {
        let (count, plan_error) = plans.map_or((0, None), |p| (p.written, p.error));
        Written {
            records: written,
            plans: count,
            error: error.map(|e| e.to_string()).or(plan_error),
        }
    };
    loop {
        if let Some(p) = plans.as_mut() {
            p.poll(last_cycle, lockstep.as_mut().map(|l| &mut l.pids));
        }
        let mut got = false;
        let closed = loop {
            match rx.try_recv() {
                Ok(r) => {
                    got = true;
                    last_cycle = Some(r.cycle);
                    if let Some(w) = out.as_mut() {
                        match lockstep.as_mut() {
                            Some(l) => r.lockstep_form(l.period_ns, &mut l.pids).write_into(bytes),
                            None => r.write_into(bytes),
                        }
                        match w.write_all(bytes) {
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
            if let Some(p) = plans.as_mut() {
                p.poll(last_cycle, lockstep.as_mut().map(|l| &mut l.pids));
            }
            return end(written, error, plans);
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::super::format::Samples;
    use super::super::format::{HEADER_BYTES, SensorRecord, torque_byte_offset};
    use super::super::reader::{LogReader, read_plans};
    use super::*;
    use ipc_types::Decision;
    use ipc_types::{CommandMsg, MAX_M, StateMsg};
    use nalgebra::Vector3;

    fn f64_at(b: &[u8], at: usize) -> f64 {
        f64::from_le_bytes(b[at..at + 8].try_into().unwrap())
    }

    /// The header of a lockstep run of group `group`.
    fn lockstep_header(group: u32, sensors: bool) -> Header {
        Header {
            group,
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
            sensors,
        }
    }

    fn sensors(k: u64) -> SensorRecord {
        SensorRecord {
            samples: Samples {
                gyro: Vector3::new(0.1, k as f64, f64::NAN),
                directions: [Vector3::new(0.0, 0.0, 1.0); 4],
                count: 2,
                accel: k.is_multiple_of(2).then(|| Vector3::new(0.0, 0.0, 9.81)),
                position: None,
                bias: Vector3::new(1e-3, -2e-3, 0.0),
            },
            q_true: [0.5; 16],
            v_true: [-0.25; 6],
            bias_hat: [1e-3, 0.0, -0.0],
            estimate_error: 0.01,
            covariance: Some([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            nees: None,
        }
    }

    fn record(k: u64, with_command: bool) -> Record {
        let mut state = StateMsg::new(ipc_types::WireGroup::Se3);
        state.seq = k;
        state.t = k as f64 * 0.001;
        state.v = [0.1, -0.2, 0.3, 1e-300, f64::MIN_POSITIVE, -0.0];
        state.stamp_ns = 1_000 + k;
        let mut cmd = CommandMsg::new(ipc_types::WireGroup::Se3);
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
            sensors: None,
        }
    }

    #[test]
    fn records_and_headers_round_trip_bit_for_bit() {
        // the sizes docs/architecture.md's tables give
        assert_eq!(
            (
                RECORD_BYTES,
                SENSOR_BYTES,
                super::super::format::PLAN_ENTRY_BYTES
            ),
            (776, 464, 3192)
        );
        for r in [record(7, true), record(8, false)] {
            let back = Record::from_bytes(&r.to_bytes()).unwrap();
            assert_eq!(back.to_bytes(), r.to_bytes());
            assert_eq!(back.command.is_some(), r.command.is_some());
        }
        // with the sensor block: every bit back, NaN included, and absent parts absent
        for k in [4, 5] {
            let r = Record {
                sensors: Some(sensors(k)),
                ..record(k, true)
            };
            let mut b = vec![0u8; RECORD_BYTES + SENSOR_BYTES];
            r.write_into(&mut b);
            let back = Record::from_bytes(&b).unwrap();
            let mut again = vec![0u8; b.len()];
            back.write_into(&mut again);
            assert_eq!(again, b);
            let got = back.sensors.unwrap();
            assert!(got.samples.gyro[2].is_nan());
            assert_eq!(got.samples.accel.is_some(), k.is_multiple_of(2));
            assert_eq!((got.nees, got.covariance), (None, sensors(k).covariance));
            assert_eq!(got.q_true, [0.5; 16]);
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
            sensors: false,
        };
        assert_eq!(Header::from_bytes(&h.to_bytes()).unwrap(), h);
        let mut bad = h.to_bytes();
        bad[8] = 9;
        assert!(Header::from_bytes(&bad).unwrap_err().contains("version 9"));
        assert!(Header::from_bytes(b"not a log at all, no").is_err());
        let with = Header { sensors: true, ..h };
        assert_eq!(with.record_bytes(), RECORD_BYTES + SENSOR_BYTES);
        assert_eq!(Header::from_bytes(&with.to_bytes()).unwrap(), with);
        // a header whose record size does not match its sensor flag is not ours
        let mut bad = with.to_bytes();
        bad[42] = 0;
        assert!(Header::from_bytes(&bad).unwrap_err().contains("records of"));
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
        // real time: the loop never waits for the disk
        let h = Header {
            realtime: true,
            rate_hz: 1000.0,
            ..lockstep_header(2, false)
        };
        // a small channel: the loop outpaces the writer, pushes are dropped and counted
        let mut rec = Recorder::start(&dir, &h, 4, None, None).unwrap();
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

    #[test]
    fn plan_messages_seen_on_the_board_are_written_to_plans_log_and_read_back() {
        let dir = std::env::temp_dir().join(format!("eqtrack-plans-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let h = lockstep_header(1, true);
        // a board that shows five messages, one per poll, then nothing
        let board: PlanSourceFactory = Box::new(|| {
            let mut next = 0u64;
            Some(Box::new(move || {
                next += 1;
                (next <= 5).then(|| {
                    let mut m = PlanMsg::new(ipc_types::WireGroup::So3);
                    m.seq = next;
                    m.planner_pid = 99;
                    m
                })
            }) as PlanSource)
        });
        let mut rec = Recorder::start(&dir, &h, 64, None, Some(board)).unwrap();
        for k in 0..10 {
            rec.push(&Record {
                sensors: (k != 3).then(|| sensors(k)),
                ..record(k, true)
            });
        }
        let report = rec.finish().unwrap();
        assert_eq!((report.records, report.plans), (10, 5));
        let plans = read_plans(&dir).unwrap();
        let seqs: Vec<u64> = plans.iter().map(|p| p.msg.seq).collect();
        assert_eq!(seqs, [1, 2, 3, 4, 5]);
        // a lockstep log: the planner's pid is its ordinal
        assert!(plans.iter().all(|p| p.msg.planner_pid == 1));
        let mut log = LogReader::open(&dir.join(LOG_FILE)).unwrap();
        assert!(log.header.sensors);
        let mut k = 0;
        while let Some(r) = log.next_record().unwrap() {
            assert_eq!(r.sensors.is_some(), k != 3, "record {k}");
            k += 1;
        }
        assert_eq!(k, 10);
        // a plans.log cut mid-entry reads its whole entries; another version is refused
        let path = dir.join(PLANS_FILE);
        let len = std::fs::metadata(&path).unwrap().len();
        let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        f.set_len(len - 7).unwrap();
        assert_eq!(read_plans(&dir).unwrap().len(), 4);
        let mut b = std::fs::read(&path).unwrap();
        b[8] = 3;
        std::fs::write(&path, b).unwrap();
        let e = read_plans(&dir).unwrap_err().to_string();
        assert!(
            e.contains("format version 3") && e.contains("version 4"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_lockstep_log_keeps_nominal_times_and_pid_ordinals_and_drops_nothing() {
        let dir = std::env::temp_dir().join(format!("eqtrack-lockstep-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let h = lockstep_header(2, false);
        let commanded = |k: u64| {
            let mut r = record(k, true);
            if let Some((c, _)) = r.command.as_mut() {
                c.compute_ns = 300 + k;
                c.state_received_ns = 2_000 + k;
                c.stamp_ns = 3_000 + k;
                // a planner replaced halfway through the run
                c.plan_pid = if k < 1000 { 4242 } else { 777 };
            }
            r.state.plant_pid = 31337;
            r
        };
        // the same small channel as in real time: here the loop waits, and nothing is lost
        let mut rec = Recorder::start(&dir, &h, 4, None, None).unwrap();
        for k in 0..2000 {
            rec.push(&commanded(k));
        }
        let report = rec.finish().unwrap();
        assert_eq!((report.records, report.dropped), (2000, 0));
        let mut log = LogReader::open(&dir.join(LOG_FILE)).unwrap();
        assert_eq!(log.header, Header { plant_pid: 0, ..h });
        let mut k = 0;
        while let Some(r) = log.next_record().unwrap() {
            let t_k = k * 1_000_000; // the tick's nominal time at 1 ms, in ns
            let (c, received) = r.command.unwrap();
            assert_eq!(
                (r.state.stamp_ns, c.state_received_ns, c.stamp_ns, received),
                (t_k, t_k, t_k, t_k),
                "cycle {k}"
            );
            assert_eq!((c.compute_ns, r.state.plant_pid), (0, 0));
            assert_eq!(c.plan_pid, if k < 1000 { 1 } else { 2 }, "cycle {k}");
            // everything else as it came
            let mut want = commanded(k);
            want.state.stamp_ns = t_k;
            want.state.plant_pid = 0;
            want.command = Some((
                CommandMsg {
                    compute_ns: 0,
                    state_received_ns: t_k,
                    stamp_ns: t_k,
                    plan_pid: c.plan_pid,
                    ..want.command.unwrap().0
                },
                t_k,
            ));
            assert_eq!(r.to_bytes(), want.to_bytes(), "cycle {k}");
            k += 1;
        }
        assert_eq!(k, 2000);
        // no process id and no pid ordinal 0 for a real pid
        let mut ids = PidOrdinals::default();
        assert_eq!(
            [
                ids.ordinal(0),
                ids.ordinal(9),
                ids.ordinal(5),
                ids.ordinal(9)
            ],
            [0, 1, 2, 1]
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
