//! The channels a run is shown on, written once: each channel's topic, its schema (a ROS 2
//! `.msg` definition, `ros2msg`) and the CDR encoding of its messages, built from the wire's
//! messages and the flight recorder's records.
//!
//! Two programs show a run with them, so a topic means the same fields in both: the offline
//! MCAP export (`export`, docs/architecture.md, "Exporting a run to MCAP") and the live
//! Foxglove bridge (`live`, docs/live.md). Neither the plant nor the controller links this
//! crate; it knows the wire (`ipc_types`) and the recorder's records (`recorder`), nothing
//! else of ours, and no MCAP or network code.
//!
//! | topic | schema | built by | export | live |
//! |---|---|---|---|---|
//! | `/eqtrack/state` | `eqtrack_msgs/msg/State` | [`state_message`] | yes | yes |
//! | `/eqtrack/cycle` | `eqtrack_msgs/msg/Cycle` | [`messages`] (a record) | yes | |
//! | `/eqtrack/command` | `eqtrack_msgs/msg/Command` | [`command_message`] | yes | yes |
//! | `/eqtrack/terms` | `eqtrack_msgs/msg/Terms` | [`messages`] | yes | |
//! | `/eqtrack/actuators` | `eqtrack_msgs/msg/Actuators` | [`messages`] | yes | |
//! | `/eqtrack/detection` | `eqtrack_msgs/msg/Detection` | [`messages`] (a controller running the failure detector) | yes | |
//! | `/eqtrack/failsafe` | `eqtrack_msgs/msg/Failsafe` | [`messages`] (a controller running the failsafe manager) | yes | |
//! | `/eqtrack/sensors` | `eqtrack_msgs/msg/Sensors` | [`messages`] | yes | |
//! | `/eqtrack/estimate` | `eqtrack_msgs/msg/Estimate` | [`messages`] | yes | |
//! | `/eqtrack/plan` | `eqtrack_msgs/msg/Plan` | [`plan_message`] | yes | |
//! | `/eqtrack/status` | `eqtrack_msgs/msg/Status` | [`status_message`] | | yes |
//! | `/eqtrack/params` | `eqtrack_msgs/msg/Param` | [`param_message`] (`params.log`) | yes | |
//!
//! One list of fields per message ([`Message`]) gives both the schema text and the encoding,
//! so the two cannot disagree.

#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

mod params;
mod record;

pub use params::param_message;
pub use record::{
    command_message, log_time, messages, plan_message, state_message, status_message, time_ns,
};

/// A channel's topic and schema name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Channel {
    /// The topic.
    pub topic: &'static str,
    /// `eqtrack_msgs/msg/<Name>`.
    pub schema: &'static str,
}

/// The state the plant published.
pub const STATE: Channel = Channel {
    topic: "/eqtrack/state",
    schema: "eqtrack_msgs/msg/State",
};
/// The plant's decision and timing of a recorded cycle.
pub const CYCLE: Channel = Channel {
    topic: "/eqtrack/cycle",
    schema: "eqtrack_msgs/msg/Cycle",
};
/// The controller's command.
pub const COMMAND: Channel = Channel {
    topic: "/eqtrack/command",
    schema: "eqtrack_msgs/msg/Command",
};
/// The disturbance-rejection terms of a command.
pub const TERMS: Channel = Channel {
    topic: "/eqtrack/terms",
    schema: "eqtrack_msgs/msg/Terms",
};
/// A vehicle's allocation.
pub const ACTUATORS: Channel = Channel {
    topic: "/eqtrack/actuators",
    schema: "eqtrack_msgs/msg/Actuators",
};
/// The failure detector's last test and what it found.
pub const DETECTION: Channel = Channel {
    topic: "/eqtrack/detection",
    schema: "eqtrack_msgs/msg/Detection",
};
/// The failsafe manager's state after a command's tick.
pub const FAILSAFE: Channel = Channel {
    topic: "/eqtrack/failsafe",
    schema: "eqtrack_msgs/msg/Failsafe",
};
/// A tick's sensor samples and the true state.
pub const SENSORS: Channel = Channel {
    topic: "/eqtrack/sensors",
    schema: "eqtrack_msgs/msg/Sensors",
};
/// What the estimator published and said.
pub const ESTIMATE: Channel = Channel {
    topic: "/eqtrack/estimate",
    schema: "eqtrack_msgs/msg/Estimate",
};
/// A plan message of a streamed run.
pub const PLAN: Channel = Channel {
    topic: "/eqtrack/plan",
    schema: "eqtrack_msgs/msg/Plan",
};
/// A running pair's live figures (the status board).
pub const STATUS: Channel = Channel {
    topic: "/eqtrack/status",
    schema: "eqtrack_msgs/msg/Status",
};

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
    pub fn ros_type(&self) -> &'static str {
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
    pub fn json(&self) -> serde_json::Value {
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
    /// An empty message of `channel`.
    fn of(channel: Channel, fields: Vec<(&'static str, Value)>) -> Message {
        Message {
            schema: channel.schema,
            topic: channel.topic,
            fields,
        }
    }

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

    #[test]
    fn json_spells_non_finite_numbers_as_strings() {
        let msg = Message::of(
            STATE,
            vec![("x", Value::F64s(vec![f64::NAN, f64::INFINITY, -1.5]))],
        );
        assert_eq!(msg.json_fields().to_string(), r#"{"x":["NaN","inf",-1.5]}"#);
    }
}
