//! The messages of one flight-recorder record, one per channel: state, cycle, command,
//! terms, for a vehicle actuators, and for a run with sensors, sensors and estimate.

use crate::{Message, Value};
use ipc_types::{CommandMsg, StateMsg, WireLaw};
use recorder::{Record, SensorRecord};

/// The decision names of the cycle channel, by code.
const DECISIONS: [&str; 3] = ["fresh", "held", "safe_mode"];

/// The messages of one record, for a group with `n`×`n` configurations and `m`-vectors;
/// `terms`: whether the run has disturbance-rejection terms.
pub fn messages(r: &Record, n: usize, m: usize, terms: bool) -> Vec<Message> {
    let mut out = vec![state_message(r, n, m), cycle_message(r, m)];
    if let Some((c, received)) = &r.command {
        out.push(command_message(r.cycle, c, *received, m));
        if terms {
            out.push(Message {
                schema: "eqtrack_msgs/msg/Terms",
                topic: "/eqtrack/terms",
                fields: vec![
                    ("cycle", Value::U64(r.cycle)),
                    ("observer", Value::F64s(c.observer[..m].to_vec())),
                    ("integral", Value::F64s(c.integral[..m].to_vec())),
                ],
            });
        }
        if c.actuators > 0 {
            out.push(actuators_message(r.cycle, c, m));
        }
    }
    if let Some(x) = &r.sensors {
        out.push(sensors_message(r.cycle, x, n, m));
        out.push(estimate_message(r.cycle, &r.state, x, n, m));
    }
    out
}

/// The state channel: the state message the plant published.
fn state_message(r: &Record, n: usize, m: usize) -> Message {
    let s: &StateMsg = &r.state;
    Message {
        schema: "eqtrack_msgs/msg/State",
        topic: "/eqtrack/state",
        fields: vec![
            ("cycle", Value::U64(r.cycle)),
            ("t", Value::F64(s.t)),
            ("control_period", Value::F64(s.control_period)),
            ("stamp_ns", Value::U64(s.stamp_ns)),
            ("group", Value::U32(s.group)),
            ("flags", Value::U32(s.flags)),
            ("q", Value::F64s(s.q[..n * n].to_vec())),
            ("v", Value::F64s(s.v[..m].to_vec())),
            ("applied_before", Value::F64s(s.applied[..m].to_vec())),
        ],
    }
}

/// The cycle channel: the plant's decision, its misses and deadline, the applied torque.
fn cycle_message(r: &Record, m: usize) -> Message {
    let code = r.decision.code();
    Message {
        schema: "eqtrack_msgs/msg/Cycle",
        topic: "/eqtrack/cycle",
        fields: vec![
            ("cycle", Value::U64(r.cycle)),
            ("decision", Value::U8(code)),
            (
                "decision_name",
                Value::Str(DECISIONS.get(code as usize).unwrap_or(&"?").to_string()),
            ),
            ("misses_in_row", Value::U32(r.misses_in_row)),
            ("deadline_ns", Value::U64(r.deadline_ns)),
            ("has_command", Value::Bool(r.command.is_some())),
            ("received_ns", Value::U64(r.command.map_or(0, |c| c.1))),
            ("applied", Value::F64s(r.applied[..m].to_vec())),
        ],
    }
}

/// The command channel: the controller's command, received at `received` (ns).
fn command_message(cycle: u64, c: &CommandMsg, received: u64, m: usize) -> Message {
    Message {
        schema: "eqtrack_msgs/msg/Command",
        topic: "/eqtrack/command",
        fields: vec![
            ("cycle", Value::U64(cycle)),
            ("seq", Value::U64(c.seq)),
            ("state_received_ns", Value::U64(c.state_received_ns)),
            ("stamp_ns", Value::U64(c.stamp_ns)),
            ("compute_ns", Value::U64(c.compute_ns)),
            ("received_ns", Value::U64(received)),
            ("tau", Value::F64s(c.tau[..m].to_vec())),
            ("lyapunov", Value::F64(c.lyapunov)),
            ("heap_allocations", Value::U64(c.heap_allocations)),
            ("flags", Value::U32(c.flags)),
            (
                "law",
                Value::Str(
                    WireLaw::from_code(c.law)
                        .map_or("", |l| l.name())
                        .to_owned(),
                ),
            ),
        ],
    }
}

/// The actuators channel of a vehicle's command: the allocator's status, the demand, what
/// its answer achieves, what the law counts as applied, and the actuator commands.
fn actuators_message(cycle: u64, c: &CommandMsg, m: usize) -> Message {
    let count = (c.actuators as usize).min(ipc_types::MAX_ACTUATORS);
    Message {
        schema: "eqtrack_msgs/msg/Actuators",
        topic: "/eqtrack/actuators",
        fields: vec![
            ("cycle", Value::U64(cycle)),
            ("alloc_status", Value::U32(c.alloc_status)),
            ("demand", Value::F64s(c.demand[..m].to_vec())),
            ("achieved", Value::F64s(c.achieved[..m].to_vec())),
            ("accounted", Value::F64s(c.accounted[..m].to_vec())),
            ("u_cmd", Value::F64s(c.u_cmd[..count].to_vec())),
        ],
    }
}

/// The sensors channel: the tick's samples and the true state they were drawn from.
fn sensors_message(cycle: u64, x: &SensorRecord, n: usize, m: usize) -> Message {
    let sm = &x.samples;
    Message {
        schema: "eqtrack_msgs/msg/Sensors",
        topic: "/eqtrack/sensors",
        fields: vec![
            ("cycle", Value::U64(cycle)),
            ("gyro", Value::F64s(sm.gyro.as_slice().to_vec())),
            (
                "directions",
                Value::F64s(
                    sm.directions[..sm.count.min(sm.directions.len())]
                        .iter()
                        .flat_map(|d| d.as_slice().to_vec())
                        .collect(),
                ),
            ),
            (
                "accel",
                Value::F64s(sm.accel.iter().flat_map(|a| a.iter().copied()).collect()),
            ),
            (
                "position",
                Value::F64s(sm.position.iter().flat_map(|p| p.iter().copied()).collect()),
            ),
            ("true_bias", Value::F64s(sm.bias.as_slice().to_vec())),
            ("true_q", Value::F64s(x.q_true[..n * n].to_vec())),
            ("true_v", Value::F64s(x.v_true[..m].to_vec())),
        ],
    }
}

/// The estimate channel: the estimate the state message carried, and the filter's figures.
fn estimate_message(cycle: u64, s: &StateMsg, x: &SensorRecord, n: usize, m: usize) -> Message {
    Message {
        schema: "eqtrack_msgs/msg/Estimate",
        topic: "/eqtrack/estimate",
        fields: vec![
            ("cycle", Value::U64(cycle)),
            ("q_hat", Value::F64s(s.q[..n * n].to_vec())),
            ("v_hat", Value::F64s(s.v[..m].to_vec())),
            ("bias_hat", Value::F64s(x.bias_hat.to_vec())),
            ("estimate_error", Value::F64(x.estimate_error)),
            (
                "covariance",
                Value::F64s(x.covariance.map_or(Vec::new(), |c| c.to_vec())),
            ),
            ("nees", Value::F64(x.nees.unwrap_or(f64::NAN))),
        ],
    }
}
