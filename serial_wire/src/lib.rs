//! The frames of the processor-in-the-loop serial link (docs/pil.md, "The serial frames"):
//! what a plant on the host and a controller on a microcontroller exchange over a UART.
//!
//! A frame is one [`Frame`] serialised with postcard, behind a version byte and followed by
//! its CRC-32 (ISO-HDLC, little-endian), the whole COBS-encoded and ended by a zero byte:
//!
//! ```text
//! COBS( version | postcard(Frame) | crc32(version | postcard(Frame)) ) 0x00
//! ```
//!
//! A receiver feeds bytes to a [`Deframer`]; each zero ends a candidate frame, which
//! [`decode`] checks (COBS, CRC, version, postcard) and either returns or refuses with a
//! [`FrameError`]. A flipped bit anywhere is caught by the CRC, or by COBS; a frame longer
//! than [`MAX_FRAME`] is dropped and counted; line noise between frames only costs the frame
//! it lands in. `no_std`, no `alloc`: the firmware uses the same code as the host.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

mod frames;
pub use frames::{Allocation, CommandFrame, Estimate, Frame, Hello, Samples, StateFrame, mismatch};

use crc::{CRC_32_ISO_HDLC, Crc};

/// The version byte every frame starts with; a frame of another version is refused (2: the
/// allocation carries the achieved wrench, and states the sensors' samples for an estimator
/// on board).
pub const SERIAL_VERSION: u8 = 2;
/// The largest decoded frame (version, postcard message and CRC), in bytes.
pub const MAX_FRAME: usize = 384;
/// The largest encoded frame: COBS's worst case for [`MAX_FRAME`] bytes, plus the zero.
pub const MAX_ENCODED: usize = cobs::max_encoding_length(MAX_FRAME) + 1;

const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// Why bytes are not a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// The COBS encoding is broken (a zero inside, or a code past the end).
    Cobs,
    /// Too short to hold a version and a CRC.
    Short,
    /// The CRC does not match: the frame was corrupted on the line.
    Crc,
    /// Another version of this protocol.
    Version(u8),
    /// The postcard message does not decode (or leaves bytes over).
    Message,
    /// Longer than [`MAX_FRAME`] (dropped by the [`Deframer`]) or too long to encode.
    TooLong,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Cobs => f.write_str("broken COBS encoding"),
            FrameError::Short => f.write_str("a frame too short for its version and CRC"),
            FrameError::Crc => f.write_str("CRC mismatch (corrupted on the line)"),
            FrameError::Version(v) => write!(
                f,
                "serial protocol version {v}, this side speaks {SERIAL_VERSION}"
            ),
            FrameError::Message => f.write_str("a message that does not decode"),
            FrameError::TooLong => write!(f, "a frame longer than {MAX_FRAME} bytes"),
        }
    }
}

/// Encodes `frame` into `out` (the COBS bytes and the closing zero); returns their length.
pub fn encode(frame: &Frame, out: &mut [u8; MAX_ENCODED]) -> Result<usize, FrameError> {
    let mut message = [0u8; MAX_FRAME];
    let n = postcard::to_slice(frame, &mut message[..MAX_FRAME - 5])
        .map_err(|_| FrameError::TooLong)?
        .len();
    encode_raw(SERIAL_VERSION, &message[..n], out)
}

/// Frames the bytes `message` as version `version`: the version byte, the bytes, their
/// CRC-32, COBS-encoded, and the closing zero. [`encode`] frames a postcard message with it;
/// a test can frame anything (another version, a message that does not decode).
pub fn encode_raw(
    version: u8,
    message: &[u8],
    out: &mut [u8; MAX_ENCODED],
) -> Result<usize, FrameError> {
    let n = 1 + message.len();
    if n + 4 > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    let mut raw = [0u8; MAX_FRAME];
    raw[0] = version;
    raw[1..n].copy_from_slice(message);
    let crc = CRC32.checksum(&raw[..n]);
    raw[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    let len = cobs::try_encode(&raw[..n + 4], &mut out[..MAX_ENCODED - 1])
        .map_err(|_| FrameError::TooLong)?;
    out[len] = 0;
    Ok(len + 1)
}

/// Decodes one frame's COBS bytes (without the closing zero): checks the encoding, the CRC
/// and the version, then the message.
pub fn decode(encoded: &[u8]) -> Result<Frame, FrameError> {
    if encoded.len() > MAX_ENCODED {
        return Err(FrameError::TooLong);
    }
    let mut raw = [0u8; MAX_ENCODED];
    let n = cobs::decode(encoded, &mut raw).map_err(|_| FrameError::Cobs)?;
    if n < 5 {
        return Err(FrameError::Short);
    }
    if n > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    let (body, crc) = raw[..n].split_at(n - 4);
    let mut sum = [0u8; 4];
    sum.copy_from_slice(crc);
    if CRC32.checksum(body) != u32::from_le_bytes(sum) {
        return Err(FrameError::Crc);
    }
    if body[0] != SERIAL_VERSION {
        return Err(FrameError::Version(body[0]));
    }
    match postcard::take_from_bytes::<Frame>(&body[1..]) {
        Ok((frame, [])) => Ok(frame),
        _ => Err(FrameError::Message),
    }
}

/// Collects bytes from the line into frames: each zero byte ends one. A candidate longer
/// than [`MAX_ENCODED`] is dropped up to the next zero and counted; bytes before the first
/// zero of a connection may be the tail of a frame and are treated the same way.
#[derive(Debug, Clone)]
pub struct Deframer {
    buf: heapless::Vec<u8, MAX_ENCODED>,
    overflowed: bool,
    /// Frames dropped for length.
    pub too_long: u32,
}

impl Default for Deframer {
    fn default() -> Self {
        Self::new()
    }
}

impl Deframer {
    /// An empty deframer.
    pub const fn new() -> Self {
        Deframer {
            buf: heapless::Vec::new(),
            overflowed: false,
            too_long: 0,
        }
    }

    /// Takes one byte; at a zero, returns the candidate frame's decoding (`None`: no frame
    /// ended here, or an empty one between two zeros).
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        if byte != 0 {
            if self.buf.push(byte).is_err() {
                self.overflowed = true;
            }
            return None;
        }
        let out = if self.overflowed {
            self.too_long = self.too_long.saturating_add(1);
            Some(Err(FrameError::TooLong))
        } else if self.buf.is_empty() {
            None
        } else {
            Some(decode(&self.buf))
        };
        self.buf.clear();
        self.overflowed = false;
        out
    }
}
