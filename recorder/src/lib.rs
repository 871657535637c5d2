//! The flight recorder's files (docs/architecture.md, "The flight recorder"): what a run's
//! `messages.log` and `plans.log` hold, how the plant's loop hands records over without
//! allocating, and how a recording is read back.
//!
//! * [`mod@format`]: the versioned file formats — `messages.log` (header, fixed-size records,
//!   sensor blocks) and `plans.log` (a streamed run's plan messages);
//! * [`writer`]: the loop's side ([`Recorder::push`], allocation-free) and the writer thread;
//! * [`reader`]: reading a recording back (cut-short files up to their last whole record).
//!
//! A recording written and read back (the loop's side is [`Recorder::push`]; the writer
//! thread does the rest):
//!
//! ```
//! use ipc_types::{Decision, StateMsg, WireGroup, MAX_M};
//! use recorder::{Header, LogReader, Record, Recorder, LOG_FILE};
//!
//! let tmp = tempfile::tempdir()?;
//! let dir = tmp.path();
//! let header = Header {
//!     group: WireGroup::So3.code(), control_period: 0.01, rate_hz: 0.0, realtime: false,
//!     event_wake: true, miss_limit: 3, fingerprint: 7, run: "doc".into(),
//!     scenario: "seed".into(), law: "eqt".into(), plant_pid: 1, sensors: false,
//! };
//! let mut rec = Recorder::start(&dir, &header, 64, None, None)?;
//! for k in 0..100 {
//!     let mut state = StateMsg::new(WireGroup::So3);
//!     state.seq = k;
//!     rec.push(&Record {
//!         cycle: k, decision: Decision::Fresh, misses_in_row: 0, deadline_ns: 0,
//!         applied: [0.0; MAX_M], state, command: None, sensors: None,
//!     });
//! }
//! assert_eq!(rec.finish()?.records, 100);
//! let mut log = LogReader::open(&dir.join(LOG_FILE))?;
//! assert_eq!((log.records, log.header.scenario.as_str()), (100, "seed"));
//! assert_eq!(log.next_record()?.map(|r| r.state.seq), Some(0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! It knows the wire contract (`ipc_types`) and nothing else of the project: the plant, the
//! offline tools (replay, monitor) and the MCAP export all build on it, and none of them is
//! needed to read a log.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub mod format;
pub mod params;
pub mod reader;
pub mod writer;

pub use format::{
    FORMAT_VERSION, HEADER_BYTES, Header, LOG_FILE, MAX_DIRECTIONS, PLANS_FILE, PidOrdinals,
    PlanEntry, RECORD_BYTES, RECORD_COMMAND_OFFSET, RECORD_STATE_OFFSET, Record, SENSOR_BYTES,
    Samples, SensorRecord, torque_byte_offset,
};
pub use params::{PARAMS_FILE, ParamChange, append_param, create_params, read_params};
pub use reader::{LogReader, read_plans};
pub use writer::{
    PlanSource, PlanSourceFactory, Recorder, RecordingReport, SinkFactory, StatusSink,
};

/// What went wrong with a recording.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum RecorderError {
    /// The file is not a recording this build reads (not ours, another version, cut inside
    /// its header, a bad record): the input is at fault.
    #[error("{0}")]
    Input(String),
    /// The file could not be created or written, or the writer thread failed.
    #[error("{0}")]
    Io(String),
}
