//! The flight recorder's file formats (docs/architecture.md, "The flight recorder").
//!
//! `messages.log`: a small fixed header ([`Header`], [`HEADER_BYTES`]) followed by fixed-size
//! records ([`Record`], [`Header::record_bytes`]), all little-endian: the state message the
//! plant published for tick k, the command that answered it (if one came in time), the
//! plant's decision (fresh, held, safe mode), the torque applied and the monotonic stamps;
//! in a run with sensors, also the tick's sensor samples, the true state and what the
//! estimator said beside the estimate it published ([`SensorRecord`]). A log cut short (a
//! SIGKILL) is read up to its last whole record.
//!
//! `plans.log` (streamed runs only): every plan message the recorder saw on the run's plan
//! board ([`PlanEntry`]), so replay can give the controller the pieces it took, when it took
//! them.

use ipc_types::{
    COMMAND_BYTES, CommandMsg, Decision, MAX_M, NAME_BYTES, PLAN_BYTES, PlanMsg, STATE_BYTES,
    StateMsg, padded_bytes, padded_str,
};
use nalgebra::Vector3;

/// Direction samples a sensor block holds (the scenario's limit on direction sensors).
pub const MAX_DIRECTIONS: usize = 4;

/// One tick's sensor samples, as the board would read them (and as the sensor block of a
/// record keeps them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Samples {
    /// The gyro: body rate plus bias plus noise (rad/s).
    pub gyro: Vector3<f64>,
    /// Direction samples in the body frame (the first `count` used).
    pub directions: [Vector3<f64>; MAX_DIRECTIONS],
    /// How many directions.
    pub count: usize,
    /// SE(3): the body-frame specific force `Rᵀ(ẍ − g)` plus noise (m/s²).
    pub accel: Option<Vector3<f64>>,
    /// SE(3): a position fix, on ticks that take one.
    pub position: Option<Vector3<f64>>,
    /// The true gyro bias at this tick (rad/s).
    pub bias: Vector3<f64>,
}

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"EQTRKLOG";
/// The format version this build writes and reads (8: protocol 10's messages, whose state
/// carries the reaction wheels' speeds, 1216-byte records; 7: protocol 9's messages, whose command
/// carries the failsafe manager's state word and whose state the estimator's health, records
/// as in 6; 6: protocol 8's messages, whose
/// command carries the failure detector's finding and last test, 1160-byte records; 5:
/// protocol 7's, whose command carries a vehicle's actuator commands, 1120-byte records; 4:
/// protocol 6's, whose command says which plan messages a streamed controller had taken,
/// 776-byte records; in a run
/// with sensors a [`SENSOR_BYTES`] sensor block after each; 3: protocol 5, 760 bytes; 2:
/// protocols 3 and 4, 752 bytes; 1: before protocol 3. Other versions are refused, naming
/// both).
pub const FORMAT_VERSION: u32 = 8;
/// Bytes of the header.
pub const HEADER_BYTES: usize = 192;
/// Where a record's state message starts.
pub const RECORD_STATE_OFFSET: usize = 80;
/// Where a record's command message starts.
pub const RECORD_COMMAND_OFFSET: usize = RECORD_STATE_OFFSET + STATE_BYTES;
/// Bytes of a record without sensors.
pub const RECORD_BYTES: usize = RECORD_COMMAND_OFFSET + COMMAND_BYTES;
/// Bytes of the sensor block that follows each record of a run with sensors.
pub const SENSOR_BYTES: usize =
    8 + 8 * (3 + 3 * MAX_DIRECTIONS + 3 + 3 + 3 + 16 + 6 + 3 + 1 + 6 + 1);
/// The file name in a run's output directory.
pub const LOG_FILE: &str = "messages.log";
/// The file of a streamed run's plan messages, beside [`LOG_FILE`].
pub const PLANS_FILE: &str = "plans.log";
/// `plans.log`'s first eight bytes.
pub const PLANS_MAGIC: [u8; 8] = *b"EQTRKPLN";
/// Bytes of `plans.log`'s header: magic, version, header bytes, entry bytes, zeros.
pub const PLANS_HEADER_BYTES: usize = 32;
/// Bytes of a `plans.log` entry: the cycle the recorder had reached, zero, the message.
pub const PLAN_ENTRY_BYTES: usize = 16 + PLAN_BYTES;

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
    /// Each record carries a [`SensorRecord`] (the run simulates sensors).
    pub sensors: bool,
}

impl Header {
    /// Bytes of each of this log's records.
    pub fn record_bytes(&self) -> usize {
        RECORD_BYTES + if self.sensors { SENSOR_BYTES } else { 0 }
    }

    /// The header's bytes.
    pub fn to_bytes(&self) -> [u8; HEADER_BYTES] {
        let mut b = [0u8; HEADER_BYTES];
        b[0..8].copy_from_slice(&MAGIC);
        put(&mut b, 8, &FORMAT_VERSION.to_le_bytes());
        put(&mut b, 12, &(HEADER_BYTES as u32).to_le_bytes());
        put(&mut b, 16, &(self.record_bytes() as u32).to_le_bytes());
        put(&mut b, 20, &self.group.to_le_bytes());
        put(&mut b, 24, &self.control_period.to_le_bytes());
        put(&mut b, 32, &self.rate_hz.to_le_bytes());
        b[40] = u8::from(self.realtime);
        b[41] = u8::from(self.event_wake);
        b[42] = u8::from(self.sensors);
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
        let sensors = b.get(42).is_some_and(|x| *x != 0);
        let expected = RECORD_BYTES + if sensors { SENSOR_BYTES } else { 0 };
        if hb != HEADER_BYTES || rb != expected || b.len() < HEADER_BYTES {
            return Err(format!(
                "header of {hb} bytes and records of {rb} bytes; version {FORMAT_VERSION} has {HEADER_BYTES} and {expected}"
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
            sensors,
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
    /// The tick's sensors and estimator (runs with sensors).
    pub sensors: Option<SensorRecord>,
}

/// What the plant's sensors and estimator did at tick k: the samples the estimator was given
/// (after any planted fault), the true state they were drawn from, and what the estimator
/// said beside the estimate it published (the state message holds `Q̂`, `V̂`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorRecord {
    /// The samples.
    pub samples: Samples,
    /// The true configuration `Q`, row-major (first n² entries used).
    pub q_true: [f64; 16],
    /// The true body velocity `V` (first m entries used).
    pub v_true: [f64; 6],
    /// The estimated gyro bias.
    pub bias_hat: [f64; 3],
    /// The attitude angle of `R̂ᵀR` (rad).
    pub estimate_error: f64,
    /// EqF: the diagonal of its covariance.
    pub covariance: Option<[f64; 6]>,
    /// EqF: the normalised estimation error squared.
    pub nees: Option<f64>,
}

impl SensorRecord {
    /// The block's bytes.
    pub fn to_bytes(&self) -> [u8; SENSOR_BYTES] {
        let mut b = [0u8; SENSOR_BYTES];
        let s = &self.samples;
        let present = u32::from(s.accel.is_some())
            | (u32::from(s.position.is_some()) << 1)
            | (u32::from(self.covariance.is_some()) << 2)
            | (u32::from(self.nees.is_some()) << 3);
        put(&mut b, 0, &present.to_le_bytes());
        put(&mut b, 4, &(s.count as u32).to_le_bytes());
        let mut at = 8;
        let mut f = |xs: &[f64]| {
            for x in xs {
                put(&mut b, at, &x.to_le_bytes());
                at += 8;
            }
        };
        f(s.gyro.as_slice());
        for d in &s.directions {
            f(d.as_slice());
        }
        f(s.accel.unwrap_or_else(Vector3::zeros).as_slice());
        f(s.position.unwrap_or_else(Vector3::zeros).as_slice());
        f(s.bias.as_slice());
        f(&self.q_true);
        f(&self.v_true);
        f(&self.bias_hat);
        f(&[self.estimate_error]);
        f(&self.covariance.unwrap_or([0.0; 6]));
        f(&[self.nees.unwrap_or(0.0)]);
        b
    }

    /// Reads a block.
    pub fn from_bytes(b: &[u8]) -> Result<SensorRecord, String> {
        if b.len() != SENSOR_BYTES {
            return Err(format!(
                "a sensor block of {} bytes, expected {SENSOR_BYTES}",
                b.len()
            ));
        }
        let present = u32_at(b, 0);
        let count = u32_at(b, 4) as usize;
        if count > MAX_DIRECTIONS {
            return Err(format!(
                "{count} direction samples (at most {MAX_DIRECTIONS})"
            ));
        }
        let mut at = 8;
        let mut take = || {
            let x = f64_at(b, at);
            at += 8;
            x
        };
        let mut v3 = || Vector3::new(take(), take(), take());
        let gyro = v3();
        let directions = std::array::from_fn(|_| v3());
        let (accel, position, bias) = (v3(), v3(), v3());
        let mut take = || {
            let x = f64_at(b, at);
            at += 8;
            x
        };
        let q_true = std::array::from_fn(|_| take());
        let v_true = std::array::from_fn(|_| take());
        let bias_hat = std::array::from_fn(|_| take());
        let estimate_error = take();
        let covariance: [f64; 6] = std::array::from_fn(|_| take());
        let nees = take();
        Ok(SensorRecord {
            samples: Samples {
                gyro,
                directions,
                count,
                accel: (present & 1 != 0).then_some(accel),
                position: (present & 2 != 0).then_some(position),
                bias,
            },
            q_true,
            v_true,
            bias_hat,
            estimate_error,
            covariance: (present & 4 != 0).then_some(covariance),
            nees: (present & 8 != 0).then_some(nees),
        })
    }
}

/// A plan message as the recorder saw it on the plan board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanEntry {
    /// The last cycle the recorder had written when it saw the message (`u64::MAX`: none
    /// yet). The cycle the controller took it in is the first whose command names it.
    pub seen_after: u64,
    /// The message.
    pub msg: PlanMsg,
}

impl PlanEntry {
    /// The entry's bytes.
    pub fn to_bytes(&self) -> [u8; PLAN_ENTRY_BYTES] {
        let mut b = [0u8; PLAN_ENTRY_BYTES];
        put(&mut b, 0, &self.seen_after.to_le_bytes());
        put(&mut b, 16, &self.msg.to_bytes());
        b
    }

    /// Reads an entry.
    pub fn from_bytes(b: &[u8]) -> Result<PlanEntry, String> {
        if b.len() != PLAN_ENTRY_BYTES {
            return Err(format!(
                "a plan entry of {} bytes, expected {PLAN_ENTRY_BYTES}",
                b.len()
            ));
        }
        Ok(PlanEntry {
            seen_after: u64_at(b, 0),
            msg: PlanMsg::from_bytes(&b[16..]).map_err(|e| format!("plan message: {e}"))?,
        })
    }
}

/// `plans.log`'s header.
pub fn plans_header() -> [u8; PLANS_HEADER_BYTES] {
    let mut b = [0u8; PLANS_HEADER_BYTES];
    b[0..8].copy_from_slice(&PLANS_MAGIC);
    put(&mut b, 8, &FORMAT_VERSION.to_le_bytes());
    put(&mut b, 12, &(PLANS_HEADER_BYTES as u32).to_le_bytes());
    put(&mut b, 16, &(PLAN_ENTRY_BYTES as u32).to_le_bytes());
    b
}

/// Checks `plans.log`'s header; names what is wrong.
pub fn check_plans_header(b: &[u8]) -> Result<(), String> {
    if b.len() < PLANS_HEADER_BYTES || b[0..8] != PLANS_MAGIC {
        return Err("not an eqtrack plan recording (its first bytes are not `EQTRKPLN`)".into());
    }
    let version = u32_at(b, 8);
    if version != FORMAT_VERSION {
        return Err(format!(
            "format version {version}; this build reads version {FORMAT_VERSION}"
        ));
    }
    let (hb, eb) = (u32_at(b, 12) as usize, u32_at(b, 16) as usize);
    if hb != PLANS_HEADER_BYTES || eb != PLAN_ENTRY_BYTES {
        return Err(format!(
            "header of {hb} bytes and entries of {eb} bytes; version {FORMAT_VERSION} has {PLANS_HEADER_BYTES} and {PLAN_ENTRY_BYTES}"
        ));
    }
    Ok(())
}

/// Process ids as a lockstep log keeps them: each pid seen (a planner's) becomes its ordinal,
/// 1, 2, … in the order the writer met them; 0 stays 0 (none). The plans and the commands
/// that name them are mapped through one table, so replay still pairs them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PidOrdinals {
    seen: Vec<u32>,
}

impl PidOrdinals {
    /// The ordinal of `pid`.
    pub fn ordinal(&mut self, pid: u32) -> u32 {
        if pid == 0 {
            return 0;
        }
        let i = match self.seen.iter().position(|p| *p == pid) {
            Some(i) => i,
            None => {
                self.seen.push(pid);
                self.seen.len() - 1
            }
        };
        u32::try_from(i + 1).unwrap_or(u32::MAX)
    }
}

impl Record {
    /// The record as a lockstep log keeps it
    /// (docs/architecture.md, "A lockstep log is reproducible"): no clock reading and no
    /// process id, so two lockstep runs of one scenario write the same bytes. The state's publication stamp, the controller's
    /// receive and publication stamps and the plant's receive stamp become the tick's nominal
    /// time `t_k = k·period` (ns), the compute time 0, the plant's pid 0, and the planner's
    /// pid its ordinal ([`PidOrdinals`]). The deadline is already nominal.
    pub fn lockstep_form(&self, period_ns: u64, pids: &mut PidOrdinals) -> Record {
        let t_k = self.cycle.saturating_mul(period_ns);
        let mut r = *self;
        r.state.stamp_ns = t_k;
        r.state.plant_pid = 0;
        if let Some((c, received)) = r.command.as_mut() {
            c.state_received_ns = t_k;
            c.stamp_ns = t_k;
            c.compute_ns = 0;
            c.plan_pid = pids.ordinal(c.plan_pid);
            *received = t_k;
        }
        r
    }

    /// The record's bytes without the sensor block.
    pub fn to_bytes(&self) -> [u8; RECORD_BYTES] {
        let mut b = [0u8; RECORD_BYTES];
        put(&mut b, 0, &self.cycle.to_le_bytes());
        b[8] = self.decision.code();
        b[9] = u8::from(self.command.is_some());
        b[10] = u8::from(self.sensors.is_some());
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

    /// Writes the record into `out` (`header.record_bytes()` long): the record, then, in a
    /// log with sensors, its sensor block (zeros if the record has none).
    pub fn write_into(&self, out: &mut [u8]) {
        out[..RECORD_BYTES].copy_from_slice(&self.to_bytes());
        if out.len() >= RECORD_BYTES + SENSOR_BYTES {
            let block = self.sensors.map(|s| s.to_bytes());
            out[RECORD_BYTES..RECORD_BYTES + SENSOR_BYTES]
                .copy_from_slice(block.as_ref().map_or(&[0u8; SENSOR_BYTES][..], |x| &x[..]));
        }
    }

    /// Reads a record (`b`: a whole record of its log, with the sensor block if it has one).
    pub fn from_bytes(b: &[u8]) -> Result<Record, String> {
        if b.len() != RECORD_BYTES && b.len() != RECORD_BYTES + SENSOR_BYTES {
            return Err(format!(
                "a record of {} bytes, expected {RECORD_BYTES} or {}",
                b.len(),
                RECORD_BYTES + SENSOR_BYTES
            ));
        }
        let decision = Decision::from_code(b[8])
            .ok_or_else(|| format!("decision code {} (expected 0, 1 or 2)", b[8]))?;
        let state = StateMsg::from_bytes(&b[RECORD_STATE_OFFSET..RECORD_COMMAND_OFFSET])
            .map_err(|e| format!("state message: {e}"))?;
        let command = match b[9] {
            0 => None,
            _ => Some((
                CommandMsg::from_bytes(&b[RECORD_COMMAND_OFFSET..RECORD_BYTES])
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
            sensors: match (b[10], b.len() > RECORD_BYTES) {
                (0, _) | (_, false) => None,
                _ => Some(
                    SensorRecord::from_bytes(&b[RECORD_BYTES..])
                        .map_err(|e| format!("sensor block: {e}"))?,
                ),
            },
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
