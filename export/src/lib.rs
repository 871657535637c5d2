//! Offline export of a flight recording (`messages.log`; docs/architecture.md, "The flight recorder")
//! to MCAP, the log format Foxglove, PlotJuggler and Rerun open directly
//! (docs/architecture.md, "Exporting a run to MCAP").
//!
//! Every record becomes up to seven messages, one per channel, all stamped with the cycle's
//! sample time `t_k` in ns (`log_time` = `publish_time`) and the cycle index as `sequence`:
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/eqtrack/state` | `eqtrack_msgs/msg/State` | the state message the plant published |
//! | `/eqtrack/command` | `eqtrack_msgs/msg/Command` | the command that answered it, if one came in time |
//! | `/eqtrack/cycle` | `eqtrack_msgs/msg/Cycle` | the plant's decision and timing |
//! | `/eqtrack/terms` | `eqtrack_msgs/msg/Terms` | the disturbance-rejection terms, when the run has them |
//! | `/eqtrack/actuators` | `eqtrack_msgs/msg/Actuators` | a vehicle's allocation: status, demand, achieved and accounted wrenches, actuator commands |
//! | `/eqtrack/sensors` | `eqtrack_msgs/msg/Sensors` | the tick's sensor samples and the true state, in a run with sensors |
//! | `/eqtrack/estimate` | `eqtrack_msgs/msg/Estimate` | what the estimator published (the state's `Q̂`, `V̂`) and said, in a run with sensors |
//! | `/eqtrack/plan` | `eqtrack_msgs/msg/Plan` | each plan message of a streamed run (`plans.log`), at the cycle the controller took it |
//!
//! Messages use the `ros2msg` schema encoding and the `cdr` message encoding (little-endian
//! XCDR1, as ROS 2 writes it), which Foxglove, PlotJuggler's built-in ROS parser and Rerun
//! decode without plugins. One list of fields per message ([`Message`]) gives both the schema
//! text and the encoding, so the two cannot disagree. The log's header goes into an MCAP
//! metadata record `eqtrack`, and the run's `scenario.toml` (when it is beside the log) into
//! an attachment.
//!
//! This crate is never a dependency of a control process: `plant_sim export` runs its binary,
//! `eqtrack-export`.

#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

mod channels;

pub use channels::messages;
use ipc_types::WireGroup;
use recorder::{Header, LogReader, PlanEntry, Record, read_plans};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

/// One field's value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `uint8`.
    U8(u8),
    /// `uint32`.
    U32(u32),
    /// `uint64`.
    U64(u64),
    /// `float64`.
    F64(f64),
    /// `bool`.
    Bool(bool),
    /// `string`.
    Str(String),
    /// `float64[]` (an unbounded sequence).
    F64s(Vec<f64>),
    /// `uint32[]` (an unbounded sequence).
    U32s(Vec<u32>),
}

impl Value {
    /// The field's type in a `.msg` definition.
    fn ros_type(&self) -> &'static str {
        match self {
            Value::U8(_) => "uint8",
            Value::U32(_) => "uint32",
            Value::U64(_) => "uint64",
            Value::F64(_) => "float64",
            Value::Bool(_) => "bool",
            Value::Str(_) => "string",
            Value::F64s(_) => "float64[]",
            Value::U32s(_) => "uint32[]",
        }
    }

    /// The value as JSON: non-finite numbers as the strings `"NaN"`, `"inf"`, `"-inf"`
    /// (JSON has no such numbers).
    fn json(&self) -> serde_json::Value {
        let num = |x: f64| {
            if x.is_nan() {
                serde_json::Value::from("NaN")
            } else if x.is_infinite() {
                serde_json::Value::from(if x > 0.0 { "inf" } else { "-inf" })
            } else {
                serde_json::Value::from(x)
            }
        };
        match self {
            Value::U8(x) => (*x).into(),
            Value::U32(x) => (*x).into(),
            Value::U64(x) => (*x).into(),
            Value::F64(x) => num(*x),
            Value::Bool(x) => (*x).into(),
            Value::Str(x) => x.clone().into(),
            Value::F64s(xs) => xs.iter().map(|x| num(*x)).collect(),
            Value::U32s(xs) => xs.clone().into(),
        }
    }
}

/// One message of one channel: its schema name, topic and fields, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// `eqtrack_msgs/msg/<Name>`.
    pub schema: &'static str,
    /// The channel's topic.
    pub topic: &'static str,
    /// Name and value of each field, in the schema's order.
    pub fields: Vec<(&'static str, Value)>,
}

impl Message {
    /// The `.msg` definition (`ros2msg` schema text): one `type name` line per field.
    pub fn schema_text(&self) -> String {
        let mut text = String::new();
        for (name, value) in &self.fields {
            text.push_str(value.ros_type());
            text.push(' ');
            text.push_str(name);
            text.push('\n');
        }
        text
    }

    /// The CDR encoding (little-endian XCDR1 with its 4-byte encapsulation header; every
    /// primitive aligned to its size from the end of the header).
    pub fn cdr(&self) -> Vec<u8> {
        let mut out = vec![0x00, 0x01, 0x00, 0x00];
        let align = |out: &mut Vec<u8>, n: usize| {
            while !(out.len() - 4).is_multiple_of(n) {
                out.push(0);
            }
        };
        for (_, value) in &self.fields {
            match value {
                Value::U8(x) => out.push(*x),
                Value::Bool(x) => out.push(u8::from(*x)),
                Value::U32(x) => {
                    align(&mut out, 4);
                    out.extend_from_slice(&x.to_le_bytes());
                }
                Value::U64(x) => {
                    align(&mut out, 8);
                    out.extend_from_slice(&x.to_le_bytes());
                }
                Value::F64(x) => {
                    align(&mut out, 8);
                    out.extend_from_slice(&x.to_le_bytes());
                }
                Value::Str(s) => {
                    align(&mut out, 4);
                    out.extend_from_slice(&(s.len() as u32 + 1).to_le_bytes());
                    out.extend_from_slice(s.as_bytes());
                    out.push(0);
                }
                Value::F64s(xs) => {
                    align(&mut out, 4);
                    out.extend_from_slice(&(xs.len() as u32).to_le_bytes());
                    if !xs.is_empty() {
                        align(&mut out, 8);
                    }
                    for x in xs {
                        out.extend_from_slice(&x.to_le_bytes());
                    }
                }
                Value::U32s(xs) => {
                    align(&mut out, 4);
                    out.extend_from_slice(&(xs.len() as u32).to_le_bytes());
                    for x in xs {
                        out.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
        }
        out
    }

    /// The fields as a JSON object.
    pub fn json_fields(&self) -> serde_json::Value {
        serde_json::Value::Object(
            self.fields
                .iter()
                .map(|(n, v)| ((*n).to_owned(), v.json()))
                .collect(),
        )
    }
}

/// The message of a recorded plan message: `cycle` is the cycle the controller took it in
/// (the first whose command names it), or, if no command names it, the cycle after the one
/// the recorder had reached when it saw it (`taken` false). Each piece's geometry follows its
/// times and shape, for a group with `n`×`n` configurations and `m`-vectors: `start`, its
/// pose at `t0` (n² entries, row-major), and `twists`, 5·m entries (`ξ` and four zero twists
/// for a stop piece, `v_1 … v_5` for a through piece; docs/wire.md, "`PlanMsg` (3 176 bytes): a window of path segments from a planner").
pub fn plan_message(e: &PlanEntry, cycle: u64, taken: bool, n: usize, m: usize) -> Message {
    let msg = &e.msg;
    let used = msg.used();
    let twists = used
        .iter()
        .flat_map(|w| (0..5).flat_map(move |k| w.twist(k, m).iter().copied()))
        .collect();
    Message {
        schema: "eqtrack_msgs/msg/Plan",
        topic: "/eqtrack/plan",
        fields: vec![
            ("cycle", Value::U64(cycle)),
            ("taken", Value::Bool(taken)),
            ("planner_pid", Value::U32(msg.planner_pid)),
            ("seq", Value::U64(msg.seq)),
            ("stamp_ns", Value::U64(msg.stamp_ns)),
            ("first_index", Value::U32(msg.first_index)),
            ("t0", Value::F64s(used.iter().map(|w| w.t0).collect())),
            ("t1", Value::F64s(used.iter().map(|w| w.t1).collect())),
            ("shape", Value::U32s(used.iter().map(|w| w.shape).collect())),
            (
                "start",
                Value::F64s(
                    used.iter()
                        .flat_map(|w| w.start[..n * n].to_vec())
                        .collect(),
                ),
            ),
            ("twists", Value::F64s(twists)),
        ],
    }
}

/// The sample time of a record in ns (`log_time` and `publish_time`): `t_k` rounded, never
/// negative.
pub fn log_time(r: &Record) -> u64 {
    let t = r.state.t;
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

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
        for msg in messages(&r, dims.0, dims.1, terms) {
            emit(f, done, time, r.cycle, &msg)?;
        }
        last_time = time;
        done.records += 1;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_every_field_from_the_end_of_the_header() {
        let msg = Message {
            schema: "eqtrack_msgs/msg/T",
            topic: "/t",
            fields: vec![
                ("a", Value::U8(7)),
                ("b", Value::U64(1)),
                ("c", Value::Str("ab".to_owned())),
                ("d", Value::F64s(vec![2.0])),
                ("e", Value::Bool(true)),
            ],
        };
        let b = msg.cdr();
        assert_eq!(&b[..4], &[0, 1, 0, 0]);
        assert_eq!(b[4], 7);
        // u64 at offset 8 of the body (12 in the buffer)
        assert_eq!(&b[5..12], &[0; 7]);
        assert_eq!(u64::from_le_bytes(b[12..20].try_into().unwrap()), 1);
        // string: length 3 (with the NUL) at body offset 16, then "ab\0"
        assert_eq!(u32::from_le_bytes(b[20..24].try_into().unwrap()), 3);
        assert_eq!(&b[24..27], b"ab\0");
        // sequence: length at body offset 24 (aligned 4), element at 32 (aligned 8)
        assert_eq!(b[27], 0);
        assert_eq!(u32::from_le_bytes(b[28..32].try_into().unwrap()), 1);
        assert_eq!(f64::from_le_bytes(b[36..44].try_into().unwrap()), 2.0);
        assert_eq!(b[44], 1);
        assert_eq!(
            msg.schema_text(),
            "uint8 a\nuint64 b\nstring c\nfloat64[] d\nbool e\n"
        );
    }
}
