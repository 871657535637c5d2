//! The frames of the processor-in-the-loop serial link (docs/pil.md, "The serial frames"):
//! what a plant on the host and a controller on a microcontroller exchange over a UART.
//!
//! A frame is one [`Frame`] serialised with postcard, behind a version byte and followed by
//! its CRC-32 (ISO-HDLC, little-endian). All but the version byte are whitened (each XORed
//! with [`WHITEN`]), and the whole is COBS-encoded and ended by a zero byte:
//!
//! ```text
//! COBS( version | W( postcard(Frame) | crc32(version | postcard(Frame)) ) ) 0x00
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
//! - `planted-slow-path` (off by default): eqtrack's own CI only, never a link: one more CRC
//!   pass over every frame sent, so that the firmware's framing count can be shown to catch a
//!   slow path.
//!
//! [`heapless`] is re-exported: the frames' strings and vectors are its types.
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
/// manager's state word; 5: states carry the reaction wheels' speeds; 6: the bytes behind the
/// version are whitened, [`WHITEN`]).
pub const SERIAL_VERSION: u8 = 6;
/// The byte every byte of a frame behind its version is XORed with before COBS (version 6).
///
/// COBS replaces each zero byte of a frame with a code, and the frames' numbers are full of
/// zero bytes (0.0, small integers, empty options): a quarter of `pil_hexarotor`'s bytes. XORed
/// with a byte value the frames seldom hold (0x63 is the rarest in `pil_hexarotor`'s, about one
/// byte in 800), a frame has few zeros, so encoding and decoding pass over it a word at a time
/// and have few codes to place. The CRC is taken before whitening, and XOR with a constant
/// moves no bit, so what the CRC catches is unchanged.
pub const WHITEN: u8 = 0x63;
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

/// Frames the `n` bytes at `out[1..]` (`n + 4 ≤ MAX_FRAME`): the version byte `out[1]`
/// and the message behind it. Appends their CRC-32, whitens all but the version byte
/// ([`WHITEN`]), COBS-encodes the whole where it lies and closes it with a zero; returns the
/// encoded length. The CRC is taken, the bytes whitened and their zeros looked for in one pass:
/// a frame without any (most) is encoded without a scan.
fn seal(out: &mut [u8; MAX_ENCODED], n: usize) -> usize {
    let crc = crc32::byte(!0, out[1]);
    let (crc, zeros) = crc32::update_whitening(crc, &mut out[2..1 + n]);
    let sum = u32::from_le_bytes([WHITEN; 4]) ^ !crc;
    out[1 + n..5 + n].copy_from_slice(&sum.to_le_bytes());
    // a planted slow path (scripts/cortex-m.sh's self-test): one more pass over the frame
    // must break the framing limit
    #[cfg(feature = "planted-slow-path")]
    core::hint::black_box(crc32::update(!0, core::hint::black_box(&out[1..5 + n])));
    let scan = zeros || out[1] == 0 || zero_bytes(sum) != 0;
    let m = cobs_in_place(out, n + 4, scan);
    out[m] = 0;
    m + 1
}

/// COBS (Cheshire and Baker, 1999) where the bytes lie: the `len` bytes at `out[1..]` become
/// their encoding at `out[..m]`; returns `m`. Each zero is replaced by the distance to the next
/// zero (or to the end), and a code byte in front (`out[0]`) gives the distance to the first.
/// A run of 254 non-zero bytes makes a full block (code 0xFF) that stands for no zero: the
/// bytes behind it move up one to make room for the next block's code. Runs are long and
/// zeros few, as whitened frames are, so the scan goes a word at a time, and without `scan`
/// (the caller knows the bytes hold no zero) there is none. `len ≤ MAX_FRAME`, so every
/// block's code fits in `out`. The same bytes as the `cobs` crate's encoder (the tests check
/// it).
fn cobs_in_place(out: &mut [u8; MAX_ENCODED], len: usize, scan: bool) -> usize {
    // `code_at`: the current block's code; `end`: one past the bytes (moves up with each
    // full block)
    let mut code_at = 0;
    let mut end = len + 1;
    loop {
        let mut zero = end;
        if scan && let Some(i) = first_zero(&out[code_at + 1..end]) {
            zero = code_at + 1 + i;
        }
        if zero - code_at < 0xff {
            out[code_at] = (zero - code_at) as u8;
            if zero == end {
                return end;
            }
            code_at = zero;
            continue;
        }
        // 254 bytes and no zero: a full block
        out[code_at] = 0xff;
        let next = code_at + 0xff;
        if next == end {
            // it ends the bytes: no empty block follows
            return end;
        }
        shift_up(out, next, end);
        end += 1;
        code_at = next;
    }
}

/// Moves `out[from..end]` up by one byte, four bytes a step (`end < out.len()`); `out[from]`
/// is left zero. Each word shifts up by a byte and takes the top byte of the word below
/// (`copy_within` would call `memmove`, whose misaligned path costs several times as much on
/// the Cortex-M4F).
fn shift_up(out: &mut [u8; MAX_ENCODED], from: usize, end: usize) {
    let (body, last) = out[from..=end].split_at_mut(end - from);
    let mut carry = 0u32;
    let mut words = body.chunks_exact_mut(4);
    for w in &mut words {
        let x = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
        w.copy_from_slice(&((x << 8) | carry).to_le_bytes());
        carry = x >> 24;
    }
    for b in words.into_remainder() {
        let x = *b;
        *b = carry as u8;
        carry = u32::from(x);
    }
    last[0] = carry as u8;
}

/// `0x80` in each byte of `x` that is zero, and maybe in bytes above one (a borrow): non-zero
/// exactly when a byte of `x` is zero, and its lowest set bit marks the first.
#[inline(always)]
pub(crate) const fn zero_bytes(x: u32) -> u32 {
    x.wrapping_sub(0x0101_0101) & !x & 0x8080_8080
}

/// Where the first zero of `bytes` is, four bytes a step: a word with no zero byte is passed
/// over whole ([`zero_bytes`]).
#[inline(always)]
fn first_zero(bytes: &[u8]) -> Option<usize> {
    let mut words = bytes.chunks_exact(4);
    let mut at = 0;
    for w in &mut words {
        let hit = zero_bytes(u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
        if hit != 0 {
            return Some(at + (hit.trailing_zeros() / 8) as usize);
        }
        at += 4;
    }
    words
        .remainder()
        .iter()
        .position(|b| *b == 0)
        .map(|i| at + i)
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
    check(&mut buf[start..end])
}

/// Collects bytes from the line into frames: each zero byte ends one. A byte is only stored
/// as it arrives; at the zero the candidate's COBS encoding is undone where it lies, a block
/// at a time, and the frame checked. A candidate longer than [`MAX_ENCODED`], or decoding to
/// more than [`MAX_FRAME`] bytes, is dropped up to the next zero and counted; bytes before the
/// first zero of a connection may be the tail of a frame and are treated the same way.
#[derive(Debug, Clone)]
#[repr(C)] // the buffer first: a byte is stored at the deframer's address plus its length
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
        let len = self.len;
        match self.buf.get_mut(len) {
            Some(slot) => {
                *slot = byte;
                self.len = len + 1;
            }
            None => self.overflowed = true,
        }
        None
    }

    /// The candidate ends: decodes and checks it, and starts the next. (Each answer is built
    /// where it is returned: a frame is a few hundred bytes, and wrapping a finished one in
    /// `Some` would copy it.)
    #[inline(never)]
    fn end(&mut self) -> Option<Result<Frame, FrameError>> {
        let n = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            self.too_long = self.too_long.saturating_add(1);
            return Some(Err(FrameError::TooLong));
        }
        if n == 0 {
            return None;
        }
        match cobs_decode_in_place(&mut self.buf[..n]) {
            Ok((a, b)) => Some(check(&mut self.buf[a..b])),
            Err(e) => {
                if e == FrameError::TooLong {
                    self.too_long = self.too_long.saturating_add(1);
                }
                Some(Err(e))
            }
        }
    }
}

/// Undoes COBS in place; returns where the decoded bytes lie in `buf`. A code past the end is
/// broken COBS, and more than [`MAX_FRAME`] decoded bytes too long. `buf` holds no zero (both
/// callers make sure: the [`Deframer`] never stores one and [`decode`] refuses one); on an
/// error its bytes are left changed.
///
/// Each block's code gives the distance to the next code, and the decoded bytes are the
/// encoded ones behind the first code with every later code a zero, except the code behind a
/// full block (0xFF), which stands for nothing and is taken out. One walk from code to code,
/// O(blocks): nothing moves unless a full block came before (then each later block moves down
/// by the codes taken out, one copy each). The frame is `buf[1..]`, less the codes taken out.
fn cobs_decode_in_place(buf: &mut [u8]) -> Result<(usize, usize), FrameError> {
    let n = buf.len();
    let Some(&first) = buf.first() else {
        return Err(FrameError::Cobs);
    };
    // `p`: the block's code; `code`: its value, read before the byte is turned to a zero;
    // `gone`: the full blocks' codes taken out so far
    let (mut p, mut code, mut gone) = (0, usize::from(first), 0);
    loop {
        let next = p + code;
        if code == 0 || next > n {
            return Err(FrameError::Cobs);
        }
        if gone > 0 {
            buf.copy_within(p + 1..next, p + 1 - gone);
        }
        if next == n {
            break;
        }
        let full = code == 0xff;
        code = usize::from(buf[next]);
        if full {
            gone += 1;
        } else {
            buf[next - gone] = 0;
        }
        p = next;
    }
    if n - 1 - gone > MAX_FRAME {
        return Err(FrameError::TooLong);
    }
    Ok((1, n - gone))
}

/// Checks a decoded frame: its length, its CRC (un-whitening the bytes behind the version in
/// the same pass), its version, then its message. A frame of a version before the whitening
/// (5 and earlier) fails the CRC here but holds its own: it is reported as its version.
fn check(raw: &mut [u8]) -> Result<Frame, FrameError> {
    let n = raw.len();
    if n < 5 {
        return Err(FrameError::Short);
    }
    let crc = crc32::byte(!0, raw[0]);
    let crc = !crc32::update_unwhitening(crc, &mut raw[1..n - 4]);
    let mut sum = [0u8; 4];
    sum.copy_from_slice(&raw[n - 4..]);
    if crc != u32::from_le_bytes(sum) ^ u32::from_le_bytes([WHITEN; 4]) {
        // the bytes as they came, read as an unwhitened frame
        for b in &mut raw[1..n - 4] {
            *b ^= WHITEN;
        }
        let plain = crc32::update(!0, &raw[..n - 4]);
        if raw[0] != SERIAL_VERSION && !plain == u32::from_le_bytes(sum) {
            return Err(FrameError::Version(raw[0]));
        }
        return Err(FrameError::Crc);
    }
    if raw[0] != SERIAL_VERSION {
        return Err(FrameError::Version(raw[0]));
    }
    match postcard::take_from_bytes::<Frame>(&raw[1..n - 4]) {
        Ok((frame, [])) => Ok(frame),
        _ => Err(FrameError::Message),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `data` with its zeros set by `zeros`: 0 none, then about one byte in 2, 16 and 256
    /// (runs of 254 and more, full blocks, where they are sparse).
    fn with_zeros(data: &[u8], zeros: u32) -> std::vec::Vec<u8> {
        data.iter()
            .map(|b| match zeros {
                0 => b | 1,
                z if u32::from(*b) % [2, 16, 256][z as usize - 1] == 0 => 0,
                _ => b | 1,
            })
            .collect()
    }

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
            let data = with_zeros(&data, zeros);
            let mut enc = std::vec![0u8; MAX_ENCODED];
            let n = cobs::encode(&data, &mut enc);
            let mut buf = enc[..n].to_vec();
            let (a, b) = cobs_decode_in_place(&mut buf).expect("a valid encoding decodes");
            proptest::prop_assert_eq!(&buf[a..b], &data[..]);
        }
    }

    /// COBS in place as the `cobs` crate encodes, and back: `src` at `out[1..]`, encoded
    /// where it lies.
    fn in_place_is_the_reference(src: &[u8]) {
        let mut out = [0u8; MAX_ENCODED];
        out[1..=src.len()].copy_from_slice(src);
        let n = cobs_in_place(&mut out, src.len(), true);
        // and without the scan, where the bytes hold no zero
        if !src.contains(&0) {
            let mut again = [0u8; MAX_ENCODED];
            again[1..=src.len()].copy_from_slice(src);
            assert_eq!(cobs_in_place(&mut again, src.len(), false), n);
            assert_eq!(again[..n], out[..n]);
        }
        let mut reference = vec![0u8; cobs::max_encoding_length(src.len())];
        let m = cobs::encode(src, &mut reference);
        assert_eq!(out[..n], reference[..m], "{} bytes", src.len());
        let mut back = out[..n].to_vec();
        let (a, k) = cobs_decode_in_place(&mut back).unwrap();
        assert_eq!(back[a..k], src[..], "{} bytes back", src.len());
    }

    /// The in-place encoder against the `cobs` crate's, on the block boundaries: runs of 253
    /// to 255 non-zero bytes at the start, inside and at the end, two full blocks, and the
    /// longest run. (A frame is never empty: it holds its version.)
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
            cases.push([vec![0; 3], run.clone(), vec![0], vec![9; 100]].concat());
        }
        cases.push([vec![0x11; 254], vec![0x22; 127]].concat());
        cases.push([vec![0x11; 254], vec![0], vec![0x22; 127]].concat());
        for src in cases {
            in_place_is_the_reference(&src);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]
        /// The in-place encoder against the `cobs` crate's on data up to the largest frame,
        /// zeros dense, sparse or absent.
        #[test]
        fn cobs_in_place_is_the_reference_encoder(
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 1..=MAX_FRAME),
            zeros in 0u32..4,
        ) {
            let data = with_zeros(&data, zeros);
            in_place_is_the_reference(&data);
        }
    }
}

/// This crate's README (its example), compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
