//! The flight recorder (docs/architecture.md, "The flight recorder"): everything about a run's
//! recording, in one bounded set of modules that the rest of `plant_sim` uses only through
//! [`Recorder`], [`Header`], [`Record`], [`SensorRecord`] and [`monitor::status_sink`]:
//!
//! * [`format`]: the versioned file formats — `messages.log` (header, fixed-size records,
//!   sensor blocks) and `plans.log` (a streamed run's plan messages);
//! * [`writer`]: the loop's side ([`Recorder::push`], allocation-free) and the writer thread;
//! * [`reader`]: reading a recording back (cut-short files up to their last whole record);
//! * [`replay`]: `plant_sim replay`, the controller and the estimator over the recorded
//!   inputs, bit for bit, or a what-if;
//! * [`monitor`]: the live status board and `plant_sim monitor`.
//!
//! The export to MCAP reads recordings through [`reader`] but lives in the `export` crate,
//! so no control process links the `mcap` crate.

pub mod format;
pub mod monitor;
pub mod reader;
pub mod replay;
pub mod writer;

pub use format::{
    FORMAT_VERSION, HEADER_BYTES, Header, LOG_FILE, PLANS_FILE, PidOrdinals, PlanEntry,
    RECORD_BYTES, RECORD_COMMAND_OFFSET, RECORD_STATE_OFFSET, Record, SENSOR_BYTES, SensorRecord,
    torque_byte_offset,
};
pub use reader::{LogReader, read_plans};
pub use writer::{
    PlanSource, PlanSourceFactory, Recorder, RecordingReport, SinkFactory, StatusSink,
};
