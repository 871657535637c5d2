//! The scenario target: TOML text through [`Scenario::from_toml`], and every accepted scenario
//! through what the processes do with it (fingerprint, step count, law overrides, the
//! controller, the reference generator and the plant body of its group, a few closed-loop
//! cycles).
//!
//! By concern: `seeds` (the seed corpus: the built-ins and hand-written scenarios), `tables`
//! (the values and lines the mutations write), `text` (finding numbers, strings, lines and
//! lists in TOML text), `mutation` (the case generator and its mutations), `checks` (the
//! oracle: parsing, validating, and exercising an accepted scenario).
//!
//! [`Scenario::from_toml`]: scenario::Scenario::from_toml

mod checks;
mod mutation;
mod seeds;
mod tables;
#[cfg(test)]
mod tests;
mod text;

pub(crate) use checks::{check, controller_error_kind, parse_class};
pub(crate) use mutation::random_number;
pub(crate) use tables::INTERESTING;
pub(crate) use text::{join_lines, number_spans, split_lines, string_spans};

/// The seed corpus and the mutator of the scenario target.
pub(crate) struct Corpus {
    items: Vec<Vec<u8>>,
}
