//! The shard target: the bytes of a Monte Carlo shard (`shard.bin`, which `plant_sim
//! montecarlo --merge` reads from files and the Python package's Ray engine receives from its
//! tasks) through `studies::shard::decode_shard` and `merge_encoded`. A shard that decodes
//! must re-encode to bytes that decode to the same shard again; a merge of it never panics.
//! Seeds: the shards of a small real study (one of one, and both of two).

use crate::Outcome;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use eqtrack_controller::Law;
use studies::shard::{Shard, Study, decode_shard, encode_shard, merge_encoded};

/// The seed corpus and the mutator of the shard target.
pub(crate) struct Corpus {
    shards: Vec<Vec<u8>>,
}

impl Corpus {
    /// A three-run, two-law study of 0.05 s, in one shard and in two.
    pub(crate) fn new() -> Corpus {
        let mut base = scenario::Scenario::builtin("montecarlo").expect("the built-in loads");
        base.duration = 0.05;
        let samples = studies::montecarlo::draw_samples(3, 1);
        let laws = [Law::Eqt, Law::Gt];
        let study = Study::new(base.fingerprint(), &samples, &laws);
        let stop = link::StopFlag::never();
        let shards = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .map(|&(index, count)| {
                let shard = Shard { index, count };
                let results = studies::montecarlo::run_indexed(
                    &base,
                    &shard.select(&samples),
                    &laws,
                    Some(1),
                    &|| {},
                    &stop,
                )
                .expect("the seed study runs");
                encode_shard(shard, &study, &results)
            })
            .collect();
        Corpus { shards }
    }

    /// One case: a seed shard with 1–8 byte mutations.
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        let mut data = g.pick(&self.shards).clone();
        for _ in 0..g.mutation_count() {
            let other = g.pick(&self.shards);
            let op = *g.pick(&ByteOp::ALL);
            byte_op(g, op, &mut data, other);
        }
        data.truncate(MAX_INPUT);
        data
    }
}

/// The report's name of a refusal (the error's message names what is wrong).
fn kind(message: &str) -> &'static str {
    [
        ("cut short", "CutShort"),
        ("magic", "Magic"),
        ("format version", "Version"),
        ("unknown law code", "LawCode"),
        ("more than the file holds", "Count"),
        ("not a whole shard file", "NotWhole"),
    ]
    .iter()
    .find(|(needle, _)| message.contains(needle))
    .map_or("Other", |(_, k)| k)
}

/// The oracle: decode; an accepted shard re-encodes to bytes that decode to the same bytes
/// again, and merging it alone never panics.
pub(crate) fn check(bytes: &[u8]) -> Outcome {
    match decode_shard(bytes, "case") {
        Err(e) => Outcome::Rejected(format!("shard: {}", kind(&e.to_string()))),
        Ok((shard, study, results)) => {
            let again = encode_shard(shard, &study, &results);
            let (s2, st2, r2) =
                decode_shard(&again, "re-encoded").expect("a re-encoded shard decodes");
            assert_eq!(
                encode_shard(s2, &st2, &r2),
                again,
                "a re-encoded shard decodes to itself"
            );
            match merge_encoded(&[("case".to_owned(), again)], &study) {
                Ok(_) => Outcome::Accepted,
                Err(e) => Outcome::Rejected(format!("merge: {}", merge_kind(&e.to_string()))),
            }
        }
    }
}

fn merge_kind(message: &str) -> &'static str {
    if message.contains("is missing") {
        "Missing"
    } else if message.contains("not shard") {
        "NotItsShare"
    } else {
        "Other"
    }
}
