//! The messages a frame carries. Numbers the controller computes with are `f32`, as the
//! firmware computes; the time is `f64`. Vectors hold only the group's entries (n² for a
//! configuration, m for a velocity or a wrench, the actuator count for commands).

use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

/// The command's vectors on the wire as byte strings (version 6): postcard's length, then the
/// numbers' little-endian bytes, written with one copy instead of one call per number. The
/// board writes commands and reads states, so the command's vectors take the form that is
/// cheaper to write; the state's stay postcard sequences, cheaper to read. The length counts
/// bytes, four a number; one that is not a multiple of four, or more numbers than the vector
/// holds, does not decode.
mod floats {
    use heapless::Vec;
    use serde::de::{Error, Visitor};
    use serde::{Deserializer, Serializer};

    /// Writes `v`'s numbers into `buf` and serialises them as bytes.
    fn write<S: Serializer>(v: &[f32], buf: &mut [u8], s: S) -> Result<S::Ok, S::Error> {
        let Some(out) = buf.get_mut(..4 * v.len()) else {
            return Err(serde::ser::Error::custom(
                "a vector longer than its frame's",
            ));
        };
        for (b, x) in out.chunks_exact_mut(4).zip(v) {
            b.copy_from_slice(&x.to_le_bytes());
        }
        s.serialize_bytes(out)
    }

    /// Serialises a vector of up to 16 numbers (a buffer of six for the wrenches: clearing
    /// the larger one costs more than the copy saves).
    pub fn serialize<S: Serializer, const N: usize>(
        v: &Vec<f32, N>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        if N <= 6 {
            write(v, &mut [0u8; 24], s)
        } else {
            write(v, &mut [0u8; 64], s)
        }
    }

    /// Reads a vector of at most `N` numbers.
    pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<Vec<f32, N>, D::Error> {
        struct Floats<const N: usize>;
        impl<const N: usize> Visitor<'_> for Floats<N> {
            type Value = Vec<f32, N>;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                write!(f, "at most {N} little-endian f32, as bytes")
            }
            fn visit_bytes<E: Error>(self, bytes: &[u8]) -> Result<Self::Value, E> {
                if !bytes.len().is_multiple_of(4) || bytes.len() > 4 * N {
                    return Err(E::invalid_length(bytes.len(), &self));
                }
                let mut v = Vec::new();
                for b in bytes.chunks_exact(4) {
                    // within capacity: checked above
                    let _ = v.push(f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
                }
                Ok(v)
            }
        }
        d.deserialize_bytes(Floats::<N>)
    }
}

/// Bits of [`Frame::Refused`]'s `mismatch`: what differs between the two sides (the same
/// bits as the iceoryx2 pair's).
pub mod mismatch {
    /// The group.
    pub const GROUP: u8 = 1;
    /// The control period.
    pub const PERIOD: u8 = 2;
    /// The scenario (its fingerprint).
    pub const SCENARIO: u8 = 4;
}

/// One side's identity, sent first by the plant and answered by the controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// The group code (1 SO(3), 2 SE(3)).
    pub group: u8,
    /// The control period (s).
    pub period: f64,
    /// The scenario's fingerprint.
    pub fingerprint: u64,
    /// The scenario's name (up to 32 bytes of UTF-8).
    pub scenario: String<32>,
}

impl Hello {
    /// The [`mismatch`] bits between two identities (0: they agree).
    pub fn mismatch(&self, other: &Hello) -> u8 {
        let mut bits = 0;
        if self.group != other.group {
            bits |= mismatch::GROUP;
        }
        if self.period.to_bits() != other.period.to_bits() {
            bits |= mismatch::PERIOD;
        }
        if self.fingerprint != other.fingerprint {
            bits |= mismatch::SCENARIO;
        }
        bits
    }
}

/// A board's sensor samples at `t_k` (what the firmware's estimator takes instead of the
/// state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Samples {
    /// The gyro (rad/s, body).
    pub gyro: [f32; 3],
    /// The direction sensors' unit vectors (body), in the scenario's order.
    pub directions: Vec<[f32; 3], 4>,
    /// The accelerometer's specific force (m/s², body), where there is one.
    pub accel: Option<[f32; 3]>,
    /// A position fix (m, world), when one arrived at this tick.
    pub position: Option<[f32; 3]>,
}

/// The plant's state at `t_k`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateFrame {
    /// The control step k.
    pub seq: u64,
    /// `t_k` (s).
    pub t: f64,
    /// The configuration `Q`, row-major (n² entries; empty when `samples` stands in).
    pub q: Vec<f32, 16>,
    /// The body velocity `V` (m entries; empty when `samples` stands in).
    pub v: Vec<f32, 6>,
    /// The wrench applied over the last period (m entries).
    pub applied: Vec<f32, 6>,
    /// The sensors' samples, for a controller that estimates the state itself.
    pub samples: Option<Samples>,
    /// The reaction wheels' speeds relative to the body (rad/s), in the vehicle's wheel
    /// order (their tachometers; empty without wheels).
    pub wheel_speeds: Vec<f32, 6>,
}

/// What the controller's estimator made of the samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// `Q̂`, row-major (n² entries).
    #[serde(with = "floats")]
    pub q: Vec<f32, 16>,
    /// `V̂` (m entries).
    #[serde(with = "floats")]
    pub v: Vec<f32, 6>,
    /// The gyro bias estimate.
    pub bias: [f32; 3],
}

/// A vehicle's allocation of the law's wrench.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Allocation {
    /// The allocator's status code.
    pub status: u8,
    /// The actuator commands.
    #[serde(with = "floats")]
    pub u_cmd: Vec<f32, 12>,
    /// The demand (m entries).
    #[serde(with = "floats")]
    pub demand: Vec<f32, 6>,
    /// The wrench the commands achieve (m entries).
    #[serde(with = "floats")]
    pub achieved: Vec<f32, 6>,
    /// `B u_cmd` plus the compensated restoring wrench (m entries).
    #[serde(with = "floats")]
    pub accounted: Vec<f32, 6>,
}

/// The failure detector's cycle (docs/maths.md, "Failure detection"), when it runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Alarms so far: how often the best hypothesis's statistic crossed the threshold.
    pub alarms: u32,
    /// The last test's best actuator plus one (0: not testing yet).
    pub suspect: u8,
    /// Its statistic (χ²₁ under no failure; 0 when not testing).
    pub statistic: f32,
    /// The actuator found failed in this cycle plus one (0: none).
    pub detected: u8,
    /// Its kind: 1 dead, 2 stuck, 3 a loss of effectiveness (0: none).
    pub kind: u8,
    /// The stuck value or the factor (0 when dead).
    pub value: f32,
    /// Whether it refines an earlier finding of the same actuator.
    pub refined: bool,
}

/// The controller's answer to state k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CommandFrame {
    /// The state's k.
    pub seq: u64,
    /// The law that computed it: its index in `eqtrack_controller::Law::ALL` (0 EqT, 1 GT, 2 nog,
    /// 3 asym).
    pub law: u8,
    /// The law's wrench (m entries).
    #[serde(with = "floats")]
    pub tau: Vec<f32, 6>,
    /// The Lyapunov function at `t_k`.
    pub lyapunov: f32,
    /// The disturbance observer's estimate (m entries; empty without it).
    #[serde(with = "floats")]
    pub observer: Vec<f32, 6>,
    /// The integral's torque (m entries; empty without it).
    #[serde(with = "floats")]
    pub integral: Vec<f32, 6>,
    /// The estimate, when the controller ran its estimator.
    pub estimate: Option<Estimate>,
    /// The allocation, for a vehicle.
    pub allocation: Option<Allocation>,
    /// The failure detector's cycle, when it runs.
    pub detection: Option<Detection>,
    /// The failsafe manager's state word after this state's tick, when it runs (the pair's
    /// `CommandMsg::failsafe`; docs/wire.md). Serial protocol 4.
    pub failsafe: Option<u32>,
}

/// One message on the line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Frame {
    /// The sender's identity: the plant's first frame, and the controller's answer when it
    /// accepts.
    Hello(Hello),
    /// The controller refuses the run: its identity and what differs.
    Refused {
        /// The [`mismatch`] bits.
        mismatch: u8,
        /// The refusing side's identity.
        identity: Hello,
    },
    /// A state for the controller.
    State(StateFrame),
    /// The controller's command.
    Command(CommandFrame),
    /// The run is over.
    Bye,
}
