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
//!
//! ## Features
//!
//! None. [`heapless`] is re-exported: the frames' strings and vectors are its types.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

pub use heapless;

mod crc32;
mod frames;
pub use frames::{
    Allocation, CommandFrame, Detection, Estimate, Frame, Hello, Samples, StateFrame, mismatch,
};

/// The version byte every frame starts with; a frame of another version is refused (2: the
/// allocation carries the achieved wrench, and states the sensors' samples for an estimator
/// on board; 3: commands carry the failure detector's cycle; 4: commands carry the failsafe
/// manager's state word; 5: states carry the reaction wheels' speeds).
pub const SERIAL_VERSION: u8 = 5;
/// The largest decoded frame (version, postcard message and CRC), in bytes.
pub const MAX_FRAME: usize = 384;
/// The largest encoded frame: COBS's worst case for [`MAX_FRAME`] bytes (one code byte per
/// 254 data bytes, and one to start), plus the zero.
pub const MAX_ENCODED: usize = MAX_FRAME + MAX_FRAME / 254 + 1 + 1;

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
/// The message is written once, behind its version byte, straight into `out`, and framed
/// where it lies.
pub fn encode(frame: &Frame, out: &mut [u8; MAX_ENCODED]) -> Result<usize, FrameError> {
    out[1] = SERIAL_VERSION;
    let n = postcard::to_slice(frame, &mut out[2..MAX_FRAME - 3])
        .map_err(|_| FrameError::TooLong)?
        .len();
    Ok(seal(out, 1 + n))
}

/// Frames the bytes `message` as version `version`: the version byte, the bytes, their
/// CRC-32, COBS-encoded, and the closing zero. [`encode`] frames a postcard message the same
/// way; a test can frame anything (another version, a message that does not decode).
pub fn encode_raw(
    version: u8,
    message: &[u8],
    out: &mut [u8; MAX_ENCODED],
) -> Result<usize, FrameError> {
    let n = 1 + message.len();
    if n + 4 > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    out[1] = version;
    out[2..1 + n].copy_from_slice(message);
    Ok(seal(out, n))
}

/// Frames the `n` bytes at `out[1..]` (`n + 4 ≤ MAX_FRAME`): appends their CRC-32, COBS-encodes
/// the whole where it lies and closes it with a zero; returns the encoded length.
///
/// COBS in place: the encoding of bytes `r` is `r` behind one code byte, each zero of `r`
/// replaced by the distance to the next zero (or to the end), and the first code the distance
/// to the first, so a backward pass writes it over the bytes without moving them. That holds
/// while no run between zeros reaches 254 bytes, where COBS splits a block; a frame with such a
/// run is encoded by [`cobs_encode`] from a copy instead, about a third dearer (bytes of
/// arbitrary floats can go that long without a zero; `pil_hexarotor`'s frames do not).
fn seal(out: &mut [u8; MAX_ENCODED], n: usize) -> usize {
    let crc = crc32::checksum(&out[1..1 + n]);
    out[1 + n..5 + n].copy_from_slice(&crc.to_le_bytes());
    let len = n + 4;
    // `next`: where the code of the block that starts after position `i` goes
    let mut next = len + 1;
    let mut i = len;
    'scan: while i > 0 {
        // four bytes at once: a word with no zero byte moves nothing (the test is exact:
        // `(x − 0x01010101) & !x & 0x80808080` is non-zero exactly when a byte of x is zero)
        let mut stop = 0;
        if i >= 4 {
            let mut word = [0u8; 4];
            word.copy_from_slice(&out[i - 3..=i]);
            let x = u32::from_le_bytes(word);
            if x.wrapping_sub(0x0101_0101) & !x & 0x8080_8080 == 0 {
                i -= 4;
                continue;
            }
            stop = i - 4;
        }
        while i > stop {
            if out[i] == 0 {
                let d = next - i;
                if d >= 0xff {
                    break 'scan;
                }
                out[i] = d as u8;
                next = i;
            }
            i -= 1;
        }
    }
    if i == 0 && next < 0xff {
        out[0] = next as u8;
        out[len + 1] = 0;
        return len + 2;
    }
    // a run of 254 or more: put back the zeros the pass replaced, then encode from a copy
    let mut p = next;
    while p <= len {
        let d = usize::from(out[p]);
        out[p] = 0;
        p += d;
    }
    let mut raw = [0u8; MAX_FRAME];
    raw[..len].copy_from_slice(&out[1..1 + len]);
    let m = cobs_encode(&raw[..len], out);
    out[m] = 0;
    m + 1
}

/// COBS (Cheshire and Baker, 1999): each zero of `src` replaced by the distance to the next,
/// in blocks of at most 254 bytes, with a code byte in front of each. `src` is at most
/// [`MAX_FRAME`] bytes, so the encoding fits in `out` with room for the closing zero. The
/// same bytes as the `cobs` crate's encoder (tests/frames.rs checks it).
fn cobs_encode(src: &[u8], out: &mut [u8; MAX_ENCODED]) -> usize {
    // a byte loop: the runs between zeros are short (every small number has zero bytes), so
    // a copy call per run costs more than it saves
    let mut code_at = 0;
    let mut w = 1;
    let mut code = 1u8;
    for &b in src {
        if b == 0 {
            out[code_at] = code;
            code_at = w;
            w += 1;
            code = 1;
        } else {
            out[w] = b;
            w += 1;
            code += 1;
            if code == 0xff {
                out[code_at] = code;
                code_at = w;
                w += 1;
                code = 1;
            }
        }
    }
    // a full block that ends the input is not followed by an empty one (an empty block
    // after a non-zero last byte can only follow a full block)
    if code == 1 && src.last().is_some_and(|b| *b != 0) {
        return code_at;
    }
    out[code_at] = code;
    w
}

/// Decodes one frame's COBS bytes (without the closing zero): checks the encoding, the CRC
/// and the version, then the message. A zero among them is broken COBS.
pub fn decode(encoded: &[u8]) -> Result<Frame, FrameError> {
    let n = encoded.len();
    if n > MAX_ENCODED {
        return Err(FrameError::TooLong);
    }
    if n == 0 || encoded.contains(&0) {
        return Err(FrameError::Cobs);
    }
    let mut buf = [0u8; MAX_ENCODED];
    buf[..n].copy_from_slice(encoded);
    let (start, end) = cobs_decode_in_place(&mut buf[..n])?;
    check(&buf[start..end])
}

/// Collects bytes from the line into frames: each zero byte ends one. A byte is only stored
/// as it arrives; at the zero the candidate's COBS encoding is undone where it lies, a block
/// at a time, and the frame checked. A candidate longer than [`MAX_ENCODED`], or decoding to
/// more than [`MAX_FRAME`] bytes, is dropped up to the next zero and counted; bytes before the
/// first zero of a connection may be the tail of a frame and are treated the same way.
#[derive(Debug, Clone)]
pub struct Deframer {
    /// The candidate's bytes so far (decoded in place when it ends).
    buf: [u8; MAX_ENCODED],
    len: usize,
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
            buf: [0; MAX_ENCODED],
            len: 0,
            overflowed: false,
            too_long: 0,
        }
    }

    /// Takes one byte; at a zero, returns the candidate frame's decoding (`None`: no frame
    /// ended here, or an empty one between two zeros).
    #[inline]
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame, FrameError>> {
        if byte == 0 {
            return self.end();
        }
        match self.buf.get_mut(self.len) {
            Some(slot) => {
                *slot = byte;
                self.len += 1;
            }
            None => self.overflowed = true,
        }
        None
    }

    /// The candidate ends: decodes and checks it, and starts the next.
    #[inline(never)]
    fn end(&mut self) -> Option<Result<Frame, FrameError>> {
        let n = core::mem::take(&mut self.len);
        let out = if core::mem::take(&mut self.overflowed) {
            Err(FrameError::TooLong)
        } else if n == 0 {
            return None;
        } else {
            cobs_decode_in_place(&mut self.buf[..n]).and_then(|(a, b)| check(&self.buf[a..b]))
        };
        if matches!(out, Err(FrameError::TooLong)) {
            self.too_long = self.too_long.saturating_add(1);
        }
        Some(out)
    }
}

/// Undoes COBS in place; returns where the decoded bytes lie in `buf`. A code past the end is
/// broken COBS, and more than [`MAX_FRAME`] decoded bytes too long. `buf` holds no zero (both
/// callers make sure: the [`Deframer`] never stores one and [`decode`] refuses one); on an
/// error its bytes are left changed.
///
/// Each block's code gives the distance to the next code, and the decoded bytes are the
/// encoded ones behind the first code with every later code a zero. One walk from code to
/// code, O(blocks), checks each code and turns every one after the first to a zero: without
/// a full block (code 0xFF, 254 bytes and no zero) the frame is then `buf[1..]`. With one,
/// the codes are put back from the zeros (each the distance to the next zero, or to the end)
/// and the bytes move down a block at a time; the frame starts at `buf[0]`.
fn cobs_decode_in_place(buf: &mut [u8]) -> Result<(usize, usize), FrameError> {
    let n = buf.len();
    if n == 0 {
        return Err(FrameError::Cobs);
    }
    // one walk from code to code: each checked (none zero, none past the end), each after the
    // first turned to the zero it stands for, and whether any is a full block's
    let mut p = 0;
    let mut full = false;
    while p < n {
        let code = usize::from(buf[p]);
        if code == 0 || p + code > n {
            return Err(FrameError::Cobs);
        }
        full |= code == 0xff;
        if p > 0 {
            buf[p] = 0;
        }
        p += code;
    }
    if !full {
        if n - 1 > MAX_FRAME {
            return Err(FrameError::TooLong);
        }
        return Ok((1, n));
    }
    // a full block: the codes back (the encoded bytes hold no zero, so the zeros are exactly
    // the codes turned, each the distance to the next), then the bytes moved down
    let mut next = n;
    for z in (1..n).rev() {
        if buf[z] == 0 {
            buf[z] = (next - z) as u8;
            next = z;
        }
    }
    let (mut r, mut w) = (0, 0);
    while r < n {
        let code = usize::from(buf[r]);
        let end = r + code;
        // blocks are short (every small number has zero bytes): a byte loop, not a call
        for i in r + 1..end {
            buf[w] = buf[i];
            w += 1;
        }
        r = end;
        if code < 0xff && r < n {
            buf[w] = 0;
            w += 1;
        }
    }
    if w > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    Ok((0, w))
}

/// Checks a decoded frame: its length, its CRC, its version, then its message.
fn check(raw: &[u8]) -> Result<Frame, FrameError> {
    let n = raw.len();
    if n < 5 {
        return Err(FrameError::Short);
    }
    let (body, crc) = raw.split_at(n - 4);
    let mut sum = [0u8; 4];
    sum.copy_from_slice(crc);
    if crc32::checksum(body) != u32::from_le_bytes(sum) {
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

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]
        /// Undoing COBS in place gives back what the `cobs` crate encoded: data up to the
        /// largest frame, with zeros dense, sparse or absent (runs of 254 and more, full
        /// blocks), so that both the walk that turns codes to zeros and the full blocks' path
        /// (which turns them back first) run.
        #[test]
        fn cobs_in_place_undoes_the_reference_encoder(
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 1..=MAX_FRAME),
            zeros in 0u32..4,
        ) {
            // zeros: 0 none, then about one byte in 2, 16 and 256
            let data: std::vec::Vec<u8> = data
                .iter()
                .map(|b| match zeros {
                    0 => b | 1,
                    z if u32::from(*b) % [2, 16, 256][z as usize - 1] == 0 => 0,
                    _ => b | 1,
                })
                .collect();
            let mut enc = std::vec![0u8; MAX_ENCODED];
            let n = cobs::encode(&data, &mut enc);
            let mut buf = enc[..n].to_vec();
            let (a, b) = cobs_decode_in_place(&mut buf).expect("a valid encoding decodes");
            proptest::prop_assert_eq!(&buf[a..b], &data[..]);
        }
    }

    /// The COBS encoder against the `cobs` crate's, on the block boundaries: runs of 253 to
    /// 255 non-zero bytes at the start, inside and at the end, and the longest run. (A frame is
    /// never empty: it holds its version.)
    #[test]
    fn cobs_blocks_are_the_reference_encoders() {
        let mut cases: Vec<Vec<u8>> = vec![
            vec![0],
            vec![0, 0],
            vec![7],
            vec![0x5a; MAX_FRAME],
            vec![3, 0, 0, 9, 8, 0, 1],
        ];
        for len in [253, 254, 255] {
            let run = vec![0x5a; len];
            cases.push(run.clone());
            cases.push([run.clone(), vec![0]].concat());
            cases.push([vec![0], run.clone()].concat());
            cases.push([vec![1, 0], run.clone(), vec![0, 2]].concat());
        }
        for src in cases {
            let mut out = [0u8; MAX_ENCODED];
            let n = cobs_encode(&src, &mut out);
            let mut reference = vec![0u8; cobs::max_encoding_length(src.len())];
            let m = cobs::encode(&src, &mut reference);
            assert_eq!(out[..n], reference[..m], "{} bytes", src.len());
            let mut back = out[..n].to_vec();
            let (a, k) = cobs_decode_in_place(&mut back).unwrap();
            assert_eq!(back[a..k], src[..]);
        }
    }
}

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
