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
mod tests;
