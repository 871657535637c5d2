//! The frames' CRC-32 (ISO-HDLC, as zlib and Ethernet: the reflected polynomial `0xEDB88320`,
//! initial value and final XOR `0xFFFFFFFF`) four bytes a step: slicing-by-4 (Kounavis and
//! Berry, "A systematic approach to building high performance software-based CRC
//! generators", 2005), with four 256-entry tables built at compile time (4 KiB of flash).
//!
//! The `crc` crate's one-table loop costs about 6.6 instructions a byte on the Cortex-M4F, and
//! its sixteen-table variant no fewer (BENCHMARKS sections 22 and 27); a word at a time this
//! one costs about 3.7 (section 28). The `crc` crate is the reference its tests hold it to.

/// The reflected polynomial.
const POLY: u32 = 0xEDB8_8320;

/// `T₀[i]`: the CRC of byte `i` (eight shifts of the register); `T_k[i]`: the CRC of byte
/// `i` followed by `k` zero bytes, `T_k[i] = (T_{k−1}[i] >> 8) ⊕ T₀[T_{k−1}[i] & 0xFF]`.
const fn tables() -> [[u32; 256]; 4] {
    let mut t = [[0u32; 256]; 4];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { (c >> 1) ^ POLY } else { c >> 1 };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut k = 1;
    while k < 4 {
        let mut i = 0;
        while i < 256 {
            let prev = t[k - 1][i];
            t[k][i] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            i += 1;
        }
        k += 1;
    }
    t
}

static TABLES: [[u32; 256]; 4] = tables();

/// The register after four more bytes, `w` their little-endian word.
#[inline(always)]
fn word(crc: u32, w: u32) -> u32 {
    let t = &TABLES;
    let c = crc ^ w;
    t[3][(c & 0xFF) as usize]
        ^ t[2][((c >> 8) & 0xFF) as usize]
        ^ t[1][((c >> 16) & 0xFF) as usize]
        ^ t[0][(c >> 24) as usize]
}

/// The register after one more byte.
#[inline(always)]
pub(crate) fn byte(crc: u32, b: u8) -> u32 {
    TABLES[0][((crc ^ u32::from(b)) & 0xFF) as usize] ^ (crc >> 8)
}

/// The register after `bytes` (no final XOR).
pub(crate) fn update(mut crc: u32, bytes: &[u8]) -> u32 {
    let mut words = bytes.chunks_exact(4);
    for w in &mut words {
        crc = word(crc, u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
    }
    for &b in words.remainder() {
        crc = byte(crc, b);
    }
    crc
}

/// The whitening word: [`crate::WHITEN`] in each byte.
const WHITE: u32 = u32::from_le_bytes([crate::WHITEN; 4]);

/// The register after `bytes` as they are, which are then whitened (each XORed with
/// [`crate::WHITEN`]), and whether a whitened byte is zero: the sender's one pass.
pub(crate) fn update_whitening(mut crc: u32, bytes: &mut [u8]) -> (u32, bool) {
    // the zero-byte test of each word ([`crate::zero_bytes`]) before its mask: the masks of
    // an OR are the mask of the ORs
    let mut zeros = 0;
    let mut words = bytes.chunks_exact_mut(4);
    for w in &mut words {
        let x = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
        crc = word(crc, x);
        let white = x ^ WHITE;
        zeros |= white.wrapping_sub(0x0101_0101) & !white;
        w.copy_from_slice(&white.to_le_bytes());
    }
    let mut zero = zeros & 0x8080_8080 != 0;
    for b in words.into_remainder() {
        crc = byte(crc, *b);
        *b ^= crate::WHITEN;
        zero |= *b == 0;
    }
    (crc, zero)
}

/// Un-whitens `bytes` (each XORed with [`crate::WHITEN`]) and returns the register after
/// them: the receiver's one pass.
pub(crate) fn update_unwhitening(mut crc: u32, bytes: &mut [u8]) -> u32 {
    let mut words = bytes.chunks_exact_mut(4);
    for w in &mut words {
        let x = u32::from_le_bytes([w[0], w[1], w[2], w[3]]) ^ WHITE;
        crc = word(crc, x);
        w.copy_from_slice(&x.to_le_bytes());
    }
    for b in words.into_remainder() {
        *b ^= crate::WHITEN;
        crc = byte(crc, *b);
    }
    crc
}

/// The CRC-32 of `bytes`.
#[cfg(test)]
pub(crate) fn checksum(bytes: &[u8]) -> u32 {
    !update(!0, bytes)
}

#[cfg(test)]
mod tests {
    use super::checksum;
    use crc::{CRC_32_ISO_HDLC, Crc};
    use proptest::prelude::*;

    const REFERENCE: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

    #[test]
    fn the_check_value_and_the_empty_input() {
        // the catalogue's check value: the CRC of the nine ASCII digits
        assert_eq!(checksum(b"123456789"), 0xCBF4_3926);
        assert_eq!(checksum(b""), 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Every length (each remainder of four) and every start within a word, against the
        /// `crc` crate's CRC-32/ISO-HDLC.
        #[test]
        fn equals_the_crc_crate(bytes in proptest::collection::vec(any::<u8>(), 0..600), skip in 0usize..4) {
            let s = &bytes[skip.min(bytes.len())..];
            prop_assert_eq!(checksum(s), REFERENCE.checksum(s));
        }
    }
}
