//! The serial frames: every kind round-trips, the largest fits, corruption is caught (every
//! single flipped bit of a frame, by the CRC or COBS), another version is refused, and line
//! noise never panics the deframer nor costs more than the frame it lands in.

use eqtrack_serial_wire::{
    Allocation, CommandFrame, Deframer, Detection, Estimate, Frame, FrameError, Hello, MAX_ENCODED,
    SERIAL_VERSION, Samples, StateFrame, WHITEN, decode, encode, mismatch,
};
use proptest::prelude::*;

fn vec<const N: usize>(xs: &[f32]) -> heapless::Vec<f32, N> {
    heapless::Vec::from_slice(xs).unwrap()
}

fn hello(fingerprint: u64) -> Hello {
    Hello {
        group: 2,
        period: 0.002,
        fingerprint,
        scenario: heapless::String::try_from("hexarotor_eqf").unwrap(),
    }
}

/// An SE(3) state with every sample present, and six reaction wheels.
fn state() -> StateFrame {
    StateFrame {
        seq: 123_456,
        t: 246.912,
        q: vec(&[0.5; 16]),
        v: vec(&[-1.25; 6]),
        applied: vec(&[3.0e-7; 6]),
        samples: Some(Samples {
            gyro: [0.1, -0.2, 0.3],
            directions: heapless::Vec::from_slice(&[[1.0, 0.0, 0.0]; 4]).unwrap(),
            accel: Some([0.0, 2.9, 9.4]),
            position: Some([1.5, -0.5, 0.25]),
        }),
        wheel_speeds: vec(&[-512.5; 6]),
    }
}

/// The largest command: SE(3) with both terms, an estimate, twelve actuators, the
/// detector's cycle and the failsafe manager's word.
fn command() -> CommandFrame {
    CommandFrame {
        seq: u64::MAX,
        law: 3,
        tau: vec(&[f32::MAX; 6]),
        lyapunov: 1.0e-7,
        observer: vec(&[0.01; 6]),
        integral: vec(&[-0.02; 6]),
        estimate: Some(Estimate {
            q: vec(&[0.25; 16]),
            v: vec(&[0.125; 6]),
            bias: [1e-3, -2e-3, 3e-3],
        }),
        allocation: Some(Allocation {
            status: 2,
            u_cmd: vec(&[8.0; 12]),
            demand: vec(&[1.0; 6]),
            achieved: vec(&[0.5; 6]),
            accounted: vec(&[-1.0; 6]),
        }),
        detection: Some(Detection {
            alarms: u32::MAX,
            suspect: 12,
            statistic: f32::MAX,
            detected: 12,
            kind: 3,
            value: 0.5,
            refined: true,
        }),
        failsafe: Some(u32::MAX),
    }
}

/// A command with nothing but its `k` (0), law 0 and `L` (0): every vector empty, no option.
fn bare_command() -> CommandFrame {
    CommandFrame {
        seq: 0,
        law: 0,
        tau: heapless::Vec::new(),
        lyapunov: 0.0,
        observer: heapless::Vec::new(),
        integral: heapless::Vec::new(),
        estimate: None,
        allocation: None,
        detection: None,
        failsafe: None,
    }
}

fn all_frames() -> Vec<Frame> {
    vec![
        Frame::Hello(hello(0xdead_beef_0123_4567)),
        Frame::Refused {
            mismatch: mismatch::SCENARIO | mismatch::PERIOD,
            identity: hello(7),
        },
        Frame::State(state()),
        Frame::Command(command()),
        Frame::Bye,
    ]
}

fn encoded(f: &Frame) -> Vec<u8> {
    let mut out = [0u8; MAX_ENCODED];
    let n = encode(f, &mut out).unwrap();
    out[..n].to_vec()
}

#[test]
fn every_kind_round_trips_and_the_largest_fits() {
    for f in all_frames() {
        let bytes = encoded(&f);
        assert_eq!(*bytes.last().unwrap(), 0, "ends with the sentinel");
        assert!(
            !bytes[..bytes.len() - 1].contains(&0),
            "no zero inside a frame"
        );
        assert_eq!(decode(&bytes[..bytes.len() - 1]), Ok(f.clone()));
        let mut d = Deframer::new();
        let got: Vec<_> = bytes.iter().filter_map(|b| d.push(*b)).collect();
        assert_eq!(got, vec![Ok(f)]);
    }
    // the largest command fits, with room to spare (352 of 387 bytes)
    assert!(encoded(&Frame::Command(command())).len() < MAX_ENCODED - 32);
}

#[test]
fn every_flipped_bit_is_caught_and_the_next_frame_still_decodes() {
    for f in all_frames() {
        let good = encoded(&f);
        for i in 0..good.len() - 1 {
            for bit in 0..8 {
                let mut bad = good.clone();
                bad[i] ^= 1 << bit;
                let mut d = Deframer::new();
                let mut results: Vec<_> = bad.iter().filter_map(|b| d.push(*b)).collect();
                // a flip that makes a zero splits the frame in two: both are refused
                assert!(
                    results.iter().all(|r| r.is_err()),
                    "byte {i} bit {bit} of {f:?}: {results:?}"
                );
                // the line recovers at the next frame
                results = good.iter().filter_map(|b| d.push(*b)).collect();
                assert_eq!(results, vec![Ok(f.clone())]);
            }
        }
    }
}

/// A frame of another version with a valid CRC.
fn other_version(version: u8) -> Vec<u8> {
    let mut out = [0u8; MAX_ENCODED];
    let message = postcard::to_allocvec(&Frame::Bye).unwrap();
    let n = eqtrack_serial_wire::encode_raw(version, &message, &mut out).unwrap();
    out[..n - 1].to_vec()
}

#[test]
fn another_version_truncation_and_length_are_refused() {
    assert_eq!(
        decode(&other_version(SERIAL_VERSION + 1)),
        Err(FrameError::Version(SERIAL_VERSION + 1))
    );
    assert_eq!(decode(&other_version(SERIAL_VERSION)), Ok(Frame::Bye));
    let good = encoded(&Frame::State(state()));
    for cut in 1..good.len() - 1 {
        assert!(decode(&good[..cut]).is_err(), "cut at {cut}");
    }
    assert_eq!(decode(&[]), Err(FrameError::Cobs));
    // a valid envelope around a message that does not decode, or leaves bytes over
    let mut out = [0u8; MAX_ENCODED];
    let n = eqtrack_serial_wire::encode_raw(SERIAL_VERSION, &[0xff, 0xff, 0xff], &mut out).unwrap();
    assert_eq!(decode(&out[..n - 1]), Err(FrameError::Message));
    let mut bye_and_more = postcard::to_allocvec(&Frame::Bye).unwrap();
    bye_and_more.push(7);
    let n = eqtrack_serial_wire::encode_raw(SERIAL_VERSION, &bye_and_more, &mut out).unwrap();
    assert_eq!(decode(&out[..n - 1]), Err(FrameError::Message));
    // a run of non-zero bytes longer than any frame is dropped and counted; the next frame
    // decodes
    let mut d = Deframer::new();
    for _ in 0..3 * MAX_ENCODED {
        assert_eq!(d.push(0x55), None);
    }
    assert_eq!(d.push(0), Some(Err(FrameError::TooLong)));
    assert_eq!(d.too_long, 1);
    let got: Vec<_> = good.iter().filter_map(|b| d.push(*b)).collect();
    assert_eq!(got, vec![Ok(Frame::State(state()))]);
}

#[test]
fn identities_name_what_differs() {
    let a = hello(1);
    assert_eq!(a.mismatch(&a.clone()), 0);
    assert_eq!(a.mismatch(&hello(2)), mismatch::SCENARIO);
    let mut b = hello(1);
    b.group = 1;
    b.period = 0.01;
    assert_eq!(a.mismatch(&b), mismatch::GROUP | mismatch::PERIOD);
}

proptest! {
    /// Random bytes on the line: nothing panics; whatever decodes re-encodes to the bytes it
    /// came from (so nothing is half-read).
    #[test]
    fn line_noise_never_panics(noise in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let mut d = Deframer::new();
        let mut start = 0;
        for (i, b) in noise.iter().enumerate() {
            if let Some(Ok(f)) = d.push(*b) {
                let again = encoded(&f);
                prop_assert_eq!(&again[..again.len() - 1], &noise[start..i]);
            }
            if *b == 0 {
                start = i + 1;
            }
        }
    }

    /// A valid frame with random bytes spliced in at a random place: it is refused (or, if
    /// the noise holds a zero, split and refused), never mistaken for another frame.
    #[test]
    fn spliced_noise_is_refused(
        at in 0usize..200,
        noise in proptest::collection::vec(1u8..=255, 1..16),
    ) {
        let good = encoded(&Frame::Command(command()));
        let at = at % (good.len() - 1);
        let mut bad = good[..at].to_vec();
        bad.extend_from_slice(&noise);
        bad.extend_from_slice(&good[at..]);
        let mut d = Deframer::new();
        let results: Vec<_> = bad.iter().filter_map(|b| d.push(*b)).collect();
        prop_assert!(results.iter().all(|r| r.is_err()), "{:?}", results);
    }
}

/// The encoded sizes the docs give (bytes on the line, with COBS and the zero).
#[test]
fn frame_sizes_are_what_the_docs_say() {
    let seed_state = Frame::State(StateFrame {
        seq: 1999,
        t: 19.99,
        q: vec(&[0.3; 9]),
        v: vec(&[0.1; 3]),
        applied: vec(&[0.0; 3]),
        samples: None,
        wheel_speeds: Default::default(),
    });
    let seed_command = Frame::Command(CommandFrame {
        seq: 1999,
        tau: vec(&[0.2; 3]),
        lyapunov: 0.01,
        ..bare_command()
    });
    let sizes: Vec<usize> = [
        seed_state,
        seed_command,
        Frame::State(state()),
        Frame::Command(command()),
    ]
    .iter()
    .map(|f| encoded(f).len())
    .collect();
    assert_eq!(sizes, vec![83, 34, 247, 352]);
}

/// `version | W(message | crc32)` COBS-encoded by the `cobs` crate, with the closing zero
/// (`W`: each byte XORed with `WHITEN`; the CRC is the `crc` crate's, of the version and the
/// message as they are): the reference the frames' own encoder must equal byte for byte.
fn reference_encoding(version: u8, message: &[u8]) -> Vec<u8> {
    reference_framing(version, message, WHITEN)
}

/// The same framing with `white` for the whitening byte (0: none, as versions 5 and
/// earlier framed).
fn reference_framing(version: u8, message: &[u8], white: u8) -> Vec<u8> {
    let mut raw = vec![version];
    raw.extend_from_slice(message);
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    for b in &mut raw[1..] {
        *b ^= white;
    }
    let mut out = vec![0u8; cobs::max_encoding_length(raw.len())];
    let n = cobs::encode(&raw, &mut out);
    out.truncate(n);
    out.push(0);
    out
}

#[test]
fn the_encoding_is_the_reference_cobs_and_crc() {
    assert_eq!(
        MAX_ENCODED,
        cobs::max_encoding_length(eqtrack_serial_wire::MAX_FRAME) + 1
    );
    for f in all_frames() {
        let message = postcard::to_allocvec(&f).unwrap();
        assert_eq!(
            encoded(&f),
            reference_encoding(SERIAL_VERSION, &message),
            "{f:?}"
        );
    }
    // blocks of exactly 254 non-zero bytes, at the end and inside, and the largest frame: a
    // zero for COBS is a byte of the message that whitens to zero, `WHITEN` (zeros, two of
    // them in a row, and none; the CRC's bytes vary)
    for len in [252, 253, 254, 255, 379] {
        for zero_at in [
            None,
            Some(0),
            Some(len / 2),
            Some(len - 1),
            Some(252),
            Some(253),
        ] {
            let mut message = vec![0x5a; len];
            if let Some(z) = zero_at.filter(|z| *z < len) {
                message[z] = WHITEN;
                message[z.saturating_sub(1)] = WHITEN;
            }
            let mut out = [0u8; MAX_ENCODED];
            let n = eqtrack_serial_wire::encode_raw(7, &message, &mut out).unwrap();
            assert_eq!(
                out[..n].to_vec(),
                reference_encoding(7, &message),
                "{len} {zero_at:?}"
            );
            // and it decodes to the same bytes (as another version, with a valid CRC)
            assert_eq!(decode(&out[..n - 1]), Err(FrameError::Version(7)));
        }
    }
    let mut out = [0u8; MAX_ENCODED];
    assert_eq!(
        eqtrack_serial_wire::encode_raw(7, &[1; 380], &mut out),
        Err(FrameError::TooLong)
    );
}

/// A peer of an earlier version frames without whitening: its frames, valid in their own
/// version, are refused as that version, not as line noise; corrupted, they are a CRC error.
#[test]
fn an_unwhitened_frame_of_an_earlier_version_is_named_by_its_version() {
    for f in all_frames() {
        let message = postcard::to_allocvec(&f).unwrap();
        for version in [1, 4, 5] {
            let old = reference_framing(version, &message, 0);
            assert_eq!(
                decode(&old[..old.len() - 1]),
                Err(FrameError::Version(version))
            );
            let mut d = Deframer::new();
            let got: Vec<_> = old.iter().filter_map(|b| d.push(*b)).collect();
            assert_eq!(got, vec![Err(FrameError::Version(version))]);
            let mut bad = old.clone();
            let mid = bad.len() / 2;
            bad[mid] ^= 0x10;
            assert!(matches!(
                decode(&bad[..bad.len() - 1]),
                Err(FrameError::Crc | FrameError::Cobs)
            ));
        }
        // our own version unwhitened is not a frame
        let plain = reference_framing(SERIAL_VERSION, &message, 0);
        assert_eq!(decode(&plain[..plain.len() - 1]), Err(FrameError::Crc));
    }
}

proptest! {
    /// Any message up to the largest: the reference encoding byte for byte, and what the
    /// reference encodes the deframer takes back (checked as far as the version byte).
    #[test]
    fn any_message_is_the_reference_encoding(
        message in proptest::collection::vec(
            prop_oneof![Just(WHITEN), Just(0u8), 1u8..=255, Just(0xff ^ WHITEN)], 0..=379),
    ) {
        let reference = reference_encoding(9, &message);
        let mut out = [0u8; MAX_ENCODED];
        let n = eqtrack_serial_wire::encode_raw(9, &message, &mut out).unwrap();
        prop_assert_eq!(&out[..n], &reference[..]);
        let mut d = Deframer::new();
        let got: Vec<_> = reference.iter().filter_map(|b| d.push(*b)).collect();
        prop_assert_eq!(got, vec![Err(FrameError::Version(9))]);
    }
}

/// A candidate is refused the moment it decodes to more than a frame can hold, whatever its
/// encoding, and counted once.
#[test]
fn a_candidate_past_the_largest_frame_is_dropped() {
    let mut d = Deframer::new();
    // 0x01 codes decode to zeros: 2 × MAX_FRAME codes are MAX_FRAME zeros too many
    for _ in 0..2 * eqtrack_serial_wire::MAX_FRAME {
        assert_eq!(d.push(0x01), None);
    }
    assert_eq!(d.push(0), Some(Err(FrameError::TooLong)));
    assert_eq!(d.too_long, 1);
    // an empty candidate between two zeros is nothing
    assert_eq!(d.push(0), None);
    let good = encoded(&Frame::Bye);
    let got: Vec<_> = good.iter().filter_map(|b| d.push(*b)).collect();
    assert_eq!(got, vec![Ok(Frame::Bye)]);
    assert_eq!(d.too_long, 1);
}

/// The command's vectors go as byte strings (version 6): four bytes a number. A length that is
/// not a multiple of four, or more numbers than the vector holds, is a message that does not
/// decode; the numbers' bytes are read back exactly.
#[test]
fn a_commands_vector_of_bad_length_does_not_decode() {
    // a command with every vector empty and no options; its `tau` is the fourth byte (the
    // variant, k, the law, then the vector's length)
    let empty = CommandFrame {
        lyapunov: 0.5,
        ..bare_command()
    };
    let message = postcard::to_allocvec(&Frame::Command(empty.clone())).unwrap();
    assert_eq!(message[3], 0, "the empty tau's length");
    let with_tau = |tau: &[u8]| {
        let mut m = message[..3].to_vec();
        m.push(u8::try_from(tau.len()).unwrap());
        m.extend_from_slice(tau);
        m.extend_from_slice(&message[4..]);
        let mut out = [0u8; MAX_ENCODED];
        let n = eqtrack_serial_wire::encode_raw(SERIAL_VERSION, &m, &mut out).unwrap();
        decode(&out[..n - 1])
    };
    let numbers: Vec<u8> = [1.5f32, -2.0, 3.25, 0.0, f32::MAX, -1e-7]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    assert_eq!(
        with_tau(&numbers),
        Ok(Frame::Command(CommandFrame {
            tau: vec(&[1.5, -2.0, 3.25, 0.0, f32::MAX, -1e-7]),
            ..empty
        }))
    );
    for bad in [
        &numbers[..5],
        &numbers[..23],
        &[numbers.clone(), vec![1, 2, 3, 4]].concat()[..],
    ] {
        assert_eq!(
            with_tau(bad),
            Err(FrameError::Message),
            "{} bytes",
            bad.len()
        );
    }
}

/// The encoder's scan for zeros is skipped when its pass found none: the guards that call it
/// back, a version byte of zero and a CRC byte that whitens to zero, give the reference's
/// bytes.
#[test]
fn a_zero_version_and_a_crc_that_whitens_to_zero_are_the_reference() {
    let mut out = [0u8; MAX_ENCODED];
    for message in [vec![], vec![0x5a; 10], vec![0x5a; 300]] {
        let n = eqtrack_serial_wire::encode_raw(0, &message, &mut out).unwrap();
        assert_eq!(out[..n].to_vec(), reference_encoding(0, &message));
        assert_eq!(decode(&out[..n - 1]), Err(FrameError::Version(0)));
    }
    // messages of one byte value, searched for one whose CRC holds a 0x63 byte, and, for the
    // decoder, the same past a full block
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
    for len in [10, 300] {
        let message = (1u8..=255)
            .map(|b| vec![b; len])
            .find(|m| {
                let mut raw = vec![SERIAL_VERSION];
                raw.extend_from_slice(m);
                m[0] != WHITEN && crc.checksum(&raw).to_le_bytes().contains(&WHITEN)
            })
            .expect("a message whose CRC holds the whitening byte");
        let n = eqtrack_serial_wire::encode_raw(SERIAL_VERSION, &message, &mut out).unwrap();
        assert_eq!(
            out[..n].to_vec(),
            reference_encoding(SERIAL_VERSION, &message)
        );
        // the frame is not a message, but it passes COBS and the CRC
        assert_eq!(decode(&out[..n - 1]), Err(FrameError::Message));
    }
}
