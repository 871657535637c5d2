//! What each side runs ([`Identity`]), compared once on the first state, and the NUL-padded names the messages carry.

use crate::{NAME_BYTES, WireGroup, mismatch};

/// What one side runs: compared once, on the first state, to catch two processes started with
/// different settings (docs/architecture.md, "Configuration identity").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identity {
    /// The group.
    pub group: u32,
    /// The control period (s); 0 on the controller's side: it follows the plant.
    pub period: f64,
    /// The scenario fingerprint; 0: none (accepted by anyone).
    pub fingerprint: u64,
    /// The scenario name, NUL-padded.
    pub scenario: [u8; NAME_BYTES],
}

impl Identity {
    /// An identity; `scenario` is cut to [`NAME_BYTES`] bytes (at a character boundary).
    pub fn new(group: WireGroup, period: f64, fingerprint: u64, scenario: &str) -> Identity {
        Identity {
            group: group.code(),
            period,
            fingerprint,
            scenario: name_bytes(scenario),
        }
    }

    /// The [`mismatch`] bits of a plant's identity against this controller's.
    pub fn mismatch(&self, plant: &Identity) -> u32 {
        let mut bits = 0;
        if plant.group != self.group {
            bits |= mismatch::GROUP;
        }
        if self.period != 0.0 && plant.period != self.period {
            bits |= mismatch::PERIOD;
        }
        if self.fingerprint != 0 && plant.fingerprint != 0 && plant.fingerprint != self.fingerprint
        {
            bits |= mismatch::SCENARIO;
        }
        bits
    }
}

impl core::fmt::Display for Identity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match WireGroup::from_code(self.group) {
            Some(g) => write!(f, "group {}", g.name())?,
            None => write!(f, "group code {}", self.group)?,
        }
        if self.period == 0.0 {
            write!(f, ", period: the plant's")?;
        } else {
            write!(f, ", period {} s", self.period)?;
        }
        match (name_str(&self.scenario), self.fingerprint) {
            (_, 0) => write!(f, ", no scenario fingerprint"),
            ("", fp) => write!(f, ", scenario {fp:016x}"),
            (name, fp) => write!(f, ", scenario `{name}` ({fp:016x})"),
        }
    }
}

/// `text` as `N` NUL-padded bytes, cut at a character boundary to fit.
pub fn padded_bytes<const N: usize>(text: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let mut end = text.len().min(N);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    out[..end].copy_from_slice(&text.as_bytes()[..end]);
    out
}

/// The text of NUL-padded bytes (`"?"` if they are not UTF-8).
pub fn padded_str<const N: usize>(bytes: &[u8; N]) -> &str {
    let end = bytes.iter().position(|b| *b == 0).unwrap_or(N);
    core::str::from_utf8(&bytes[..end]).unwrap_or("?")
}

/// `text` as NUL-padded name bytes ([`NAME_BYTES`]), cut at a character boundary to fit.
pub fn name_bytes(text: &str) -> [u8; NAME_BYTES] {
    padded_bytes(text)
}

/// The text of NUL-padded name bytes (`"?"` if they are not UTF-8).
pub fn name_str(bytes: &[u8; NAME_BYTES]) -> &str {
    padded_str(bytes)
}
