//! Offline export of a flight recording (`messages.log`; docs/architecture.md, "The flight recorder")
//! to MCAP, the log format Foxglove, PlotJuggler and Rerun open directly
//! (docs/architecture.md, "Exporting a run to MCAP").
//!
//! Every record becomes up to nine messages, one per channel, all stamped with the cycle's
//! sample time `t_k` in ns (`log_time` = `publish_time`) and the cycle index as `sequence`:
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/eqtrack/state` | `eqtrack_msgs/msg/State` | the state message the plant published |
//! | `/eqtrack/command` | `eqtrack_msgs/msg/Command` | the command that answered it, if one came in time |
//! | `/eqtrack/cycle` | `eqtrack_msgs/msg/Cycle` | the plant's decision and timing |
//! | `/eqtrack/terms` | `eqtrack_msgs/msg/Terms` | the disturbance-rejection terms, when the run has them |
//! | `/eqtrack/actuators` | `eqtrack_msgs/msg/Actuators` | a vehicle's allocation: status, demand, achieved and accounted wrenches, actuator commands |
//! | `/eqtrack/detection` | `eqtrack_msgs/msg/Detection` | the failure detector's last test and what it found, when the controller runs it |
//! | `/eqtrack/failsafe` | `eqtrack_msgs/msg/Failsafe` | the failsafe manager's action, cause and raised causes, when the controller runs it |
//! | `/eqtrack/sensors` | `eqtrack_msgs/msg/Sensors` | the tick's sensor samples and the true state, in a run with sensors |
//! | `/eqtrack/estimate` | `eqtrack_msgs/msg/Estimate` | what the estimator published (the state's `Q̂`, `V̂`) and said, in a run with sensors |
//! | `/eqtrack/plan` | `eqtrack_msgs/msg/Plan` | each plan message of a streamed run (`plans.log`), at the cycle the controller took it |
//!
//! Messages use the `ros2msg` schema encoding and the `cdr` message encoding (little-endian
//! XCDR1, as ROS 2 writes it), which Foxglove, PlotJuggler's built-in ROS parser and Rerun
//! decode without plugins. One list of fields per message ([`Message`]) gives both the schema
//! text and the encoding, so the two cannot disagree. The channels are the `channels` crate's,
//! which the live Foxglove bridge (`live`) shows a running pair with: a topic carries the same
//! fields in both. The log's header goes into an MCAP
//! metadata record `eqtrack`, and the run's `scenario.toml` (when it is beside the log) into
//! an attachment.
//!
//! This crate is never a dependency of a control process: `plant_sim export` runs its binary,
//! `eqtrack-export`.

#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub use channels::{Message, Value, log_time, messages, plan_message};
use ipc_types::WireGroup;
use recorder::{Header, LogReader, PlanEntry, read_plans};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

/// Export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// MCAP (`run.mcap`).
    Mcap,
    /// One JSON object per message (`run.jsonl`): the same messages, for checks.
    Jsonl,
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// Records read (whole ones).
    pub records: u64,
    /// Messages written, per topic.
    pub messages: BTreeMap<&'static str, u64>,
    /// Bytes after the last whole record (a recording cut short): not exported.
    pub trailing_bytes: u64,
}

/// Why an export failed.
#[derive(Debug)]
pub enum ExportError {
    /// The log cannot be read.
    Input(String),
    /// The output cannot be written.
    Output(String),
}

impl std::fmt::Display for ExportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExportError::Input(m) | ExportError::Output(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for ExportError {}

/// The cycle in which the controller first named each plan message `(planner pid, seq)`.
type TakenAt = HashMap<(u32, u64), u64>;

/// What one pass over the log finds first: whether any recorded command carries a non-zero
/// disturbance-rejection term, and the cycle in which the controller first named each plan
/// message `(planner pid, seq)` as the last it had taken.
fn survey(log: &Path) -> Result<(bool, TakenAt), ExportError> {
    let mut reader = LogReader::open(log).map_err(|e| ExportError::Input(e.to_string()))?;
    let (mut terms, mut taken) = (false, HashMap::new());
    while let Some(r) = reader
        .next_record()
        .map_err(|e| ExportError::Input(e.to_string()))?
    {
        if let Some((c, _)) = &r.command {
            terms |= c.observer.iter().chain(&c.integral).any(|x| *x != 0.0);
            if c.flags & ipc_types::flags::STREAMED != 0 && c.plans_received > 0 {
                taken.entry((c.plan_pid, c.plan_seq)).or_insert(r.cycle);
            }
        }
    }
    Ok((terms, taken))
}

/// Every message of the export in order: before each record's own messages, the plan
/// messages taken in (or seen by) its cycle, all at its time. `f(log_time, sequence,
/// message)`.
fn walk(
    log: &Path,
    reader: &mut LogReader,
    dims: (usize, usize),
    done: &mut Exported,
    f: &mut dyn FnMut(u64, u64, &Message) -> Result<(), ExportError>,
) -> Result<(), ExportError> {
    let (terms, taken) = survey(log)?;
    let plans = match log.parent() {
        Some(dir) => read_plans(dir).map_err(|e| ExportError::Input(e.to_string()))?,
        None => Vec::new(),
    };
    let mut plans: Vec<(u64, bool, &PlanEntry)> = plans
        .iter()
        .map(|e| match taken.get(&(e.msg.planner_pid, e.msg.seq)) {
            Some(k) => (*k, true, e),
            None => (e.seen_after.wrapping_add(1), false, e),
        })
        .collect();
    plans.sort_by_key(|p| p.0);
    let mut next_plan = 0;
    // run-time parameter changes (`params.log`), each at the record of its cycle
    let params = match log.parent() {
        Some(dir) => recorder::read_params(dir).map_err(|e| ExportError::Input(e.to_string()))?,
        None => Vec::new(),
    };
    let mut next_param = 0;
    let mut last_time = 0;
    let emit = |f: &mut dyn FnMut(u64, u64, &Message) -> Result<(), ExportError>,
                done: &mut Exported,
                time: u64,
                seq: u64,
                msg: &Message| {
        *done.messages.entry(msg.topic).or_default() += 1;
        f(time, seq, msg)
    };
    while let Some(r) = reader
        .next_record()
        .map_err(|e| ExportError::Input(e.to_string()))?
    {
        let time = log_time(&r);
        while let Some((k, taken, e)) = plans.get(next_plan).filter(|p| p.0 <= r.cycle) {
            emit(
                f,
                done,
                time,
                *k,
                &plan_message(e, *k, *taken, dims.0, dims.1),
            )?;
            next_plan += 1;
        }
        while let Some(c) = params.get(next_param).filter(|c| c.cycle <= r.cycle) {
            emit(f, done, time, c.cycle, &channels::param_message(c))?;
            next_param += 1;
        }
        for msg in messages(&r, dims.0, dims.1, terms) {
            emit(f, done, time, r.cycle, &msg)?;
        }
        last_time = time;
        done.records += 1;
    }
    for c in &params[next_param..] {
        emit(f, done, last_time, c.cycle, &channels::param_message(c))?;
    }
    for (k, taken, e) in &plans[next_plan..] {
        emit(
            f,
            done,
            last_time,
            *k,
            &plan_message(e, *k, *taken, dims.0, dims.1),
        )?;
    }
    Ok(())
}

/// The header as an MCAP metadata map.
fn metadata(h: &Header, records: u64) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    let group = WireGroup::from_code(h.group).map_or("unknown", |g| g.name());
    for (k, v) in [
        ("run", h.run.clone()),
        ("scenario", h.scenario.clone()),
        ("law", h.law.clone()),
        ("group", group.to_owned()),
        ("control_period_s", h.control_period.to_string()),
        ("rate_hz", h.rate_hz.to_string()),
        (
            "mode",
            if h.realtime { "real time" } else { "lockstep" }.to_owned(),
        ),
        ("fingerprint", format!("{:016x}", h.fingerprint)),
        ("plant_pid", h.plant_pid.to_string()),
        ("records", records.to_string()),
        (
            "flight_recorder_format",
            recorder::FORMAT_VERSION.to_string(),
        ),
    ] {
        m.insert(k.to_owned(), v);
    }
    m
}

/// Exports `log` (a `messages.log`) to `out` in `format`; `compress`: zstd chunks (needs the
/// `zstd` feature). `scenario.toml` beside the log, when there, is attached.
pub fn export(
    log: &Path,
    out: &Path,
    format: Format,
    compress: bool,
) -> Result<Exported, ExportError> {
    let mut reader = LogReader::open(log).map_err(|e| ExportError::Input(e.to_string()))?;
    let (n, m) = WireGroup::from_code(reader.header.group)
        .map(|g| g.dims())
        .ok_or_else(|| {
            ExportError::Input(format!(
                "{}: unknown group code {}",
                log.display(),
                reader.header.group
            ))
        })?;
    // refused before the output file is created
    let compression = match format {
        Format::Mcap => compression(compress)?,
        Format::Jsonl => None,
    };
    let file = std::fs::File::create(out)
        .map_err(|e| ExportError::Output(format!("cannot create {}: {e}", out.display())))?;
    let out_err = |e: &dyn std::fmt::Display| {
        ExportError::Output(format!("cannot write {}: {e}", out.display()))
    };
    let mut done = Exported {
        records: 0,
        messages: BTreeMap::new(),
        trailing_bytes: reader.trailing_bytes,
    };
    let mut writer = BufWriter::with_capacity(1 << 20, file);
    match format {
        Format::Jsonl => {
            walk(
                log,
                &mut reader,
                (n, m),
                &mut done,
                &mut |time, seq, msg| {
                    let line = serde_json::json!({
                        "topic": msg.topic,
                        "schema": msg.schema,
                        "log_time": time,
                        "sequence": seq,
                        "fields": msg.json_fields(),
                    });
                    writeln!(writer, "{line}").map_err(|e| out_err(&e))
                },
            )?;
            writer.flush().map_err(|e| out_err(&e))?;
        }
        Format::Mcap => {
            write_mcap(&mut reader, log, writer, (n, m), compression, &mut done)?;
        }
    }
    Ok(done)
}

/// The chunks' compression: zstd with `compress`, which needs the `zstd` feature.
fn compression(compress: bool) -> Result<Option<mcap::Compression>, ExportError> {
    if !compress {
        return Ok(None);
    }
    #[cfg(feature = "zstd")]
    {
        Ok(Some(mcap::Compression::Zstd))
    }
    #[cfg(not(feature = "zstd"))]
    {
        Err(ExportError::Input(
            "--compress needs eqtrack-export built with the `zstd` feature (cargo build -p export --features zstd)".to_owned(),
        ))
    }
}

fn write_mcap<W: Write + Seek>(
    reader: &mut LogReader,
    log: &Path,
    sink: W,
    dims: (usize, usize),
    compression: Option<mcap::Compression>,
    done: &mut Exported,
) -> Result<(), ExportError> {
    let mcap_err = |e: mcap::McapError| ExportError::Output(format!("MCAP: {e}"));
    let mut w = mcap::WriteOptions::new()
        .compression(compression)
        .profile("ros2")
        .create(sink)
        .map_err(mcap_err)?;
    // channels are made on first use, from the first message's fields
    let mut channels: BTreeMap<&'static str, u16> = BTreeMap::new();
    let header = reader.header.clone();
    walk(log, reader, dims, done, &mut |time, seq, msg| {
        let id = match channels.get(msg.topic) {
            Some(id) => *id,
            None => {
                let schema = w
                    .add_schema(msg.schema, "ros2msg", msg.schema_text().as_bytes())
                    .map_err(mcap_err)?;
                let id = w
                    .add_channel(schema, msg.topic, "cdr", &BTreeMap::new())
                    .map_err(mcap_err)?;
                channels.insert(msg.topic, id);
                id
            }
        };
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: id,
                sequence: seq as u32,
                log_time: time,
                publish_time: time,
            },
            &msg.cdr(),
        )
        .map_err(mcap_err)
    })?;
    w.write_metadata(&mcap::records::Metadata {
        name: "eqtrack".to_owned(),
        metadata: metadata(&header, done.records),
    })
    .map_err(mcap_err)?;
    if let Some(dir) = log.parent() {
        let scenario = dir.join("scenario.toml");
        if let Ok(data) = std::fs::read(&scenario) {
            w.attach(&mcap::Attachment {
                log_time: 0,
                create_time: 0,
                name: "scenario.toml".to_owned(),
                media_type: "application/toml".to_owned(),
                data: std::borrow::Cow::Owned(data),
            })
            .map_err(mcap_err)?;
        }
    }
    w.finish().map_err(mcap_err)?;
    Ok(())
}
