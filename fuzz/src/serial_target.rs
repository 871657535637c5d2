//! The serial target: bytes on the processor-in-the-loop line through `eqtrack-serial-wire`'s
//! `Deframer` and `decode` (COBS, CRC, version, postcard). Every frame that decodes must
//! re-encode, and that encoding must decode and encode to the same bytes again (a frame may
//! carry NaN, which is not equal to itself: the receiver's checks refuse it, not the
//! framing); a `Hello` goes through the identity check. Cases are
//! streams of valid frames with byte mutations (which the CRC refuses), and valid envelopes
//! (a correct CRC, sometimes another version) around mutated postcard messages, which reach
//! the message decoder.

use crate::Outcome;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use eqtrack_serial_wire::{
    Allocation, CommandFrame, Deframer, Detection, Estimate, Frame, FrameError, Hello, MAX_ENCODED,
    MAX_FRAME, SERIAL_VERSION, Samples, StateFrame, decode, encode, encode_raw,
};
use std::hint::black_box;

/// A vector of the frames' (capacity `N`).
fn v<const N: usize>(xs: &[f32]) -> heapless::Vec<f32, N> {
    heapless::Vec::from_slice(xs).expect("within capacity")
}

/// The seed frames: each kind, SO(3) and SE(3), with and without samples, wheel speeds, an
/// estimate and an allocation.
fn seed_frames() -> Vec<Frame> {
    let hello = Hello {
        group: 1,
        period: 0.01,
        fingerprint: 0x0123_4567_89ab_cdef,
        scenario: heapless::String::try_from("seed").expect("short"),
    };
    let so3_state = StateFrame {
        seq: 7,
        t: 0.07,
        q: v(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
        v: v(&[0.1, -0.2, 0.3]),
        applied: v(&[0.0; 3]),
        samples: None,
        // four reaction wheels' speeds (rad/s)
        wheel_speeds: v(&[120.0, -35.5, 0.0, 600.0]),
    };
    let se3_state = StateFrame {
        seq: 4000,
        t: 8.0,
        q: heapless::Vec::new(),
        v: heapless::Vec::new(),
        applied: v(&[0.5; 6]),
        samples: Some(Samples {
            gyro: [0.01, 0.02, -0.03],
            directions: heapless::Vec::from_slice(&[[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
                .expect("two"),
            accel: Some([0.0, 2.9, 9.4]),
            position: Some([0.1, 0.2, 0.3]),
        }),
        wheel_speeds: Default::default(),
    };
    let command = CommandFrame {
        seq: 4000,
        law: 0,
        tau: v(&[0.1; 6]),
        lyapunov: 1e-3,
        observer: v(&[0.01; 6]),
        integral: heapless::Vec::new(),
        estimate: Some(Estimate {
            q: v(&[0.5; 16]),
            v: v(&[0.0; 6]),
            bias: [1e-3; 3],
        }),
        allocation: Some(Allocation {
            status: 0,
            u_cmd: v(&[2.8; 6]),
            demand: v(&[0.0, 0.0, 0.0, 0.0, 0.0, 14.7]),
            achieved: v(&[0.0, 0.0, 0.0, 0.0, 0.0, 14.7]),
            accounted: v(&[0.0; 6]),
        }),
        detection: Some(Detection {
            alarms: 2,
            suspect: 3,
            statistic: 41.5,
            detected: 3,
            kind: 2,
            value: 12.5,
            refined: false,
        }),
        failsafe: Some(0x114),
    };
    vec![
        Frame::Hello(hello.clone()),
        Frame::Refused {
            mismatch: 4,
            identity: hello,
        },
        Frame::State(so3_state),
        Frame::State(se3_state),
        Frame::Command(command),
        Frame::Bye,
    ]
}

/// The seed corpus and the mutator of the serial target.
pub(crate) struct Corpus {
    /// Encoded streams: each frame alone, and the frames of a short run back to back.
    streams: Vec<Vec<u8>>,
    /// The frames' postcard messages (no envelope).
    messages: Vec<Vec<u8>>,
}

impl Corpus {
    /// The seed frames, encoded.
    pub(crate) fn new() -> Corpus {
        let frames = seed_frames();
        let encode_one = |f: &Frame| {
            let mut out = [0u8; MAX_ENCODED];
            let n = encode(f, &mut out).expect("a seed frame encodes");
            out[..n].to_vec()
        };
        let mut streams: Vec<Vec<u8>> = frames.iter().map(encode_one).collect();
        streams.push(frames.iter().flat_map(encode_one).collect());
        let messages = frames
            .iter()
            .map(|f| postcard::to_allocvec(f).expect("a seed frame serialises"))
            .collect();
        Corpus { streams, messages }
    }

    /// One case: a stream with 1–8 byte mutations, or (one case in three) a valid envelope
    /// around a mutated message.
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        if g.below(3) == 0 {
            let mut m = g.pick(&self.messages).clone();
            for _ in 0..g.mutation_count() {
                let other = g.pick(&self.messages);
                let op = *g.pick(&ByteOp::ALL);
                byte_op(g, op, &mut m, other);
            }
            m.truncate(MAX_FRAME - 5);
            let version = if g.chance(1, 10) {
                g.u32() as u8
            } else {
                SERIAL_VERSION
            };
            let mut out = [0u8; MAX_ENCODED];
            return match encode_raw(version, &m, &mut out) {
                Ok(n) => out[..n].to_vec(),
                Err(_) => m,
            };
        }
        let mut data = g.pick(&self.streams).clone();
        for _ in 0..g.mutation_count() {
            let other = g.pick(&self.streams);
            let op = *g.pick(&ByteOp::ALL);
            byte_op(g, op, &mut data, other);
        }
        data.truncate(MAX_INPUT);
        data
    }
}

/// The report's name of a frame error.
fn kind(e: &FrameError) -> &'static str {
    match e {
        FrameError::Cobs => "Cobs",
        FrameError::Short => "Short",
        FrameError::Crc => "Crc",
        FrameError::Version(_) => "Version",
        FrameError::Message => "Message",
        FrameError::TooLong => "TooLong",
    }
}

/// The oracle: the bytes through a deframer; every decoded frame round-trips; accepted when
/// every candidate frame decoded, else rejected with the first error's kind.
pub(crate) fn check(bytes: &[u8]) -> Outcome {
    let mut d = Deframer::new();
    let mut first = None;
    for b in bytes.iter().chain(std::iter::once(&0)) {
        match d.push(*b) {
            Some(Ok(f)) => {
                // compared as bytes: a frame may carry NaN, which is not equal to itself
                let mut out = [0u8; MAX_ENCODED];
                let n = encode(&f, &mut out).expect("a decoded frame re-encodes");
                let again = decode(&out[..n - 1]).expect("a re-encoded frame decodes");
                let mut out2 = [0u8; MAX_ENCODED];
                let n2 = encode(&again, &mut out2).expect("and re-encodes");
                assert_eq!(
                    &out[..n],
                    &out2[..n2],
                    "a re-encoded frame decodes to itself"
                );
                if let Frame::Hello(h) | Frame::Refused { identity: h, .. } = &f {
                    assert_eq!(h.mismatch(h), 0, "an identity agrees with itself");
                }
                black_box(&f);
            }
            Some(Err(e)) => {
                first.get_or_insert(e);
            }
            None => {}
        }
    }
    match first {
        None => Outcome::Accepted,
        Some(e) => Outcome::Rejected(format!("serial: FrameError::{}", kind(&e))),
    }
}
