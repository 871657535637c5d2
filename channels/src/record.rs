//! The messages of each channel: from a flight-recorder record (the export: state, cycle,
//! command, terms, for a vehicle actuators, and for a run with sensors, sensors and
//! estimate), from a plan entry, and from the wire's own messages (the live bridge: state,
//! command, status).

use crate::{
    ACTUATORS, COMMAND, CYCLE, DETECTION, ESTIMATE, FAILSAFE, Message, PLAN, SENSORS, STATE,
    STATUS, TERMS, Value,
};
use ipc_types::{CommandMsg, StateMsg, StatusMsg, WireLaw, failsafe_names, name_str};
use recorder::{PlanEntry, Record, SensorRecord};

/// The decision names of the cycle channel, by code.
const DECISIONS: [&str; 3] = ["fresh", "held", "safe_mode"];

/// The messages of one record, for a group with `n`×`n` configurations and `m`-vectors;
/// `terms`: whether the run has disturbance-rejection terms.
pub fn messages(r: &Record, n: usize, m: usize, terms: bool) -> Vec<Message> {
    let mut out = vec![state_message(r.cycle, &r.state, n, m), cycle_message(r, m)];
    if let Some((c, received)) = &r.command {
        out.push(command_message(r.cycle, c, *received, m));
        if terms {
            out.push(Message::of(
                TERMS,
                vec![
                    ("cycle", Value::U64(r.cycle)),
                    ("observer", Value::F64s(c.observer[..m].to_vec())),
                    ("integral", Value::F64s(c.integral[..m].to_vec())),
                ],
            ));
        }
        if c.actuators > 0 {
            out.push(actuators_message(r.cycle, c, m));
        }
        if c.flags & ipc_types::flags::DETECTING != 0 {
            out.push(detection_message(r.cycle, c));
        }
        if c.flags & ipc_types::flags::SUPERVISED != 0 {
            out.push(failsafe_message(r.cycle, c.failsafe));
        }
    }
    if let Some(x) = &r.sensors {
        out.push(sensors_message(r.cycle, x, n, m));
        out.push(estimate_message(r.cycle, &r.state, x, n, m));
    }
    out
}

/// The state channel: state `s` the plant published for cycle `cycle`, for a group with
/// `n`×`n` configurations and `m`-vectors (`n` ≤ 4, `m` ≤ 6).
/// `wheel_speeds` holds the reaction wheels' speeds relative to the body, one per wheel
/// (empty without wheels: the schema is the same for every plant).
pub fn state_message(cycle: u64, s: &StateMsg, n: usize, m: usize) -> Message {
    Message::of(
        STATE,
        vec![
            ("cycle", Value::U64(cycle)),
            ("t", Value::F64(s.t)),
            ("control_period", Value::F64(s.control_period)),
            ("stamp_ns", Value::U64(s.stamp_ns)),
            ("group", Value::U32(s.group)),
            ("flags", Value::U32(s.flags)),
            ("q", Value::F64s(s.q[..n * n].to_vec())),
            ("v", Value::F64s(s.v[..m].to_vec())),
            ("applied_before", Value::F64s(s.applied[..m].to_vec())),
            ("wheel_speeds", Value::F64s(s.wheel_speeds().to_vec())),
        ],
    )
}

/// The cycle channel: the plant's decision, its misses and deadline, the applied torque.
fn cycle_message(r: &Record, m: usize) -> Message {
    let code = r.decision.code();
    Message::of(
        CYCLE,
        vec![
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
    )
}

/// The command channel: the controller's command `c` for cycle `cycle`, received by the plant
/// at `received_ns` (CLOCK_MONOTONIC ns; the live bridge, which is not the plant, says 0),
/// for a group with `m`-vectors (`m` ≤ 6).
pub fn command_message(cycle: u64, c: &CommandMsg, received_ns: u64, m: usize) -> Message {
    Message::of(
        COMMAND,
        vec![
            ("cycle", Value::U64(cycle)),
            ("seq", Value::U64(c.seq)),
            ("state_received_ns", Value::U64(c.state_received_ns)),
            ("stamp_ns", Value::U64(c.stamp_ns)),
            ("compute_ns", Value::U64(c.compute_ns)),
            ("received_ns", Value::U64(received_ns)),
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
    )
}

/// The actuators channel of a vehicle's command: the allocator's status, the demand, what
/// its answer achieves, what the law counts as applied, and the actuator commands.
fn actuators_message(cycle: u64, c: &CommandMsg, m: usize) -> Message {
    let count = (c.actuators as usize).min(ipc_types::MAX_ACTUATORS);
    Message::of(
        ACTUATORS,
        vec![
            ("cycle", Value::U64(cycle)),
            ("alloc_status", Value::U32(c.alloc_status)),
            ("demand", Value::F64s(c.demand[..m].to_vec())),
            ("achieved", Value::F64s(c.achieved[..m].to_vec())),
            ("accounted", Value::F64s(c.accounted[..m].to_vec())),
            ("u_cmd", Value::F64s(c.u_cmd[..count].to_vec())),
        ],
    )
}

/// The detection channel of a command from a controller running the failure detector
/// (docs/wire.md): its last test (the suspect, 0-based, or −1 before the first test, and
/// its statistic), its alarms so far, and what it found this cycle (actuator −1: nothing;
/// kind `""`, `"dead"`, `"stuck"` or `"effectiveness"`; the value or factor told).
fn detection_message(cycle: u64, c: &CommandMsg) -> Message {
    Message::of(
        DETECTION,
        vec![
            ("cycle", Value::U64(cycle)),
            ("suspect", Value::F64(f64::from(c.suspect) - 1.0)),
            ("statistic", Value::F64(c.statistic)),
            ("alarms", Value::U32(c.alarms)),
            ("detected", Value::F64(f64::from(c.detected) - 1.0)),
            (
                "kind",
                Value::Str(ipc_types::detected_kind_name(c.detected_kind).to_owned()),
            ),
            ("value", Value::F64(c.detected_value)),
            ("refined", Value::Bool(c.detected_refined != 0)),
        ],
    )
}

/// The failsafe channel of a command from a controller running the failsafe manager
/// (docs/failsafe.md): the action flown and the cause that engaged it (`""` when nominal),
/// the raised causes (bit 0 link … bit 3 tracking), and the word itself (docs/wire.md).
fn failsafe_message(cycle: u64, word: u32) -> Message {
    Message::of(
        FAILSAFE,
        vec![
            ("cycle", Value::U64(cycle)),
            ("action", Value::Str(failsafe_names(word).0.to_owned())),
            ("cause", Value::Str(failsafe_names(word).1.to_owned())),
            ("raised", Value::U32(word >> 8 & 0xf)),
            ("word", Value::U32(word)),
        ],
    )
}

/// The sensors channel: the tick's samples and the true state they were drawn from.
fn sensors_message(cycle: u64, x: &SensorRecord, n: usize, m: usize) -> Message {
    let sm = &x.samples;
    Message::of(
        SENSORS,
        vec![
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
    )
}

/// The estimate channel: the estimate the state message carried, and the filter's figures.
fn estimate_message(cycle: u64, s: &StateMsg, x: &SensorRecord, n: usize, m: usize) -> Message {
    Message::of(
        ESTIMATE,
        vec![
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
    )
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
    Message::of(
        PLAN,
        vec![
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
    )
}

/// The status channel: a running pair's live figures, as the plant's flight recorder
/// published them on the run's status board
/// (docs/wire.md, "`StatusMsg` (184 bytes): a run's live figures").
/// `cycle` and `t` are the newest cycle recorded; the round trip is over the last second.
pub fn status_message(s: &StatusMsg) -> Message {
    Message::of(
        STATUS,
        vec![
            ("cycle", Value::U64(s.cycle)),
            ("t", Value::F64(s.t)),
            ("seq", Value::U64(s.seq)),
            ("stamp_ns", Value::U64(s.stamp_ns)),
            ("group", Value::U32(s.group)),
            ("target_rate_hz", Value::F64(s.target_rate_hz)),
            ("rate_hz", Value::F64(s.rate_hz)),
            ("rtt_p50_ns", Value::U64(s.rtt_p50_ns)),
            ("rtt_p99_ns", Value::U64(s.rtt_p99_ns)),
            ("rtt_max_ns", Value::U64(s.rtt_max_ns)),
            ("misses", Value::U64(s.misses)),
            ("safe_mode_entries", Value::U64(s.safe_mode_entries)),
            ("lyapunov", Value::F64(s.lyapunov)),
            ("last_command_ns", Value::U64(s.last_command_ns)),
            ("flags", Value::U32(s.flags)),
            ("plant_pid", Value::U32(s.plant_pid)),
            ("scenario", Value::Str(name_str(&s.scenario).to_owned())),
            ("detections", Value::U32(s.detections)),
            (
                "last_detected",
                Value::F64(f64::from(s.last_detected) - 1.0),
            ),
            ("last_detected_kind", Value::U32(s.last_detected_kind)),
            ("last_detected_value", Value::F64(s.last_detected_value)),
            ("alarms", Value::U32(s.alarms)),
            (
                "failsafe_action",
                Value::Str(failsafe_names(s.failsafe).0.to_owned()),
            ),
            (
                "failsafe_cause",
                Value::Str(failsafe_names(s.failsafe).1.to_owned()),
            ),
            ("failsafe_transitions", Value::U32(s.failsafe_transitions)),
        ],
    )
}

/// A sample time `t` (s) in ns, as every channel stamps its messages (`log_time` and
/// `publish_time` in the MCAP export, the message data's time in the live bridge): rounded,
/// never negative (0 for a time that is not finite).
pub fn time_ns(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

/// The sample time of a record in ns: [`time_ns`] of its state's `t_k`.
pub fn log_time(r: &Record) -> u64 {
    time_ns(r.state.t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ipc_types::WireGroup;

    #[test]
    fn the_state_and_command_builders_take_the_groups_lengths() {
        let mut s = StateMsg::new(WireGroup::Se3);
        s.t = 0.25;
        s.v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let msg = state_message(7, &s, 4, 6);
        assert_eq!(msg.topic, "/eqtrack/state");
        assert_eq!(msg.fields[0], ("cycle", Value::U64(7)));
        assert_eq!(msg.fields[6].1, Value::F64s(s.q[..16].to_vec()));
        assert_eq!(msg.fields[7].1, Value::F64s(s.v.to_vec()));
        let so3 = state_message(7, &s, 3, 3);
        assert_eq!(so3.fields[7].1, Value::F64s(vec![1.0, 2.0, 3.0]));
        // the wheels' speeds: as many as the plant has, none without wheels
        assert_eq!(so3.fields[9], ("wheel_speeds", Value::F64s(vec![])));
        s.set_wheel_speeds(&[10.0, -20.0, 30.0, 0.5]);
        let wheeled = state_message(7, &s, 3, 3);
        assert_eq!(
            wheeled.fields.last(),
            Some(&("wheel_speeds", Value::F64s(vec![10.0, -20.0, 30.0, 0.5])))
        );
        let mut c = CommandMsg::new(WireGroup::So3);
        c.tau[..3].copy_from_slice(&[0.5, -0.5, 0.25]);
        let cmd = command_message(7, &c, 0, 3);
        assert_eq!(cmd.fields[5], ("received_ns", Value::U64(0)));
        assert_eq!(cmd.fields[6].1, Value::F64s(vec![0.5, -0.5, 0.25]));
        assert_eq!(time_ns(0.25), 250_000_000);
        assert_eq!(time_ns(f64::NAN), 0);
        assert_eq!(time_ns(-1.0), 0);
    }

    #[test]
    fn the_status_message_has_every_figure_of_the_board() {
        let mut s = StatusMsg::new(WireGroup::So3, "seed");
        s.cycle = 42;
        s.rtt_p99_ns = 12_345;
        s.lyapunov = f64::NAN;
        let msg = status_message(&s);
        let names: Vec<&str> = msg.fields.iter().map(|f| f.0).collect();
        for want in [
            "cycle",
            "t",
            "rate_hz",
            "rtt_p50_ns",
            "rtt_p99_ns",
            "rtt_max_ns",
            "misses",
            "safe_mode_entries",
            "lyapunov",
            "flags",
            "scenario",
        ] {
            assert!(names.contains(&want), "no field {want}");
        }
        assert_eq!(msg.fields[0].1, Value::U64(42));
        assert!(
            msg.fields
                .iter()
                .any(|f| *f == ("scenario", Value::Str("seed".to_owned())))
        );
        for want in [
            "detections",
            "last_detected",
            "alarms",
            "failsafe_action",
            "failsafe_cause",
            "failsafe_transitions",
        ] {
            assert!(names.contains(&want), "no field {want}");
        }
        assert!(msg.schema_text().contains("uint64 rtt_p99_ns\n"));
    }
}
