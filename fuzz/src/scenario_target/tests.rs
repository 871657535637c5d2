use super::checks::scenario_error_kind;
use super::mutation::{TOML_OPS, toml_op};
use super::text::{list_elements, matching_close, number_spans};
use super::{Corpus, check};
use crate::Outcome;
use crate::rng::Streams;
use scenario::ScenarioError;

#[test]
fn every_seed_is_accepted() {
    for item in &Corpus::new().items {
        assert_eq!(
            check(item),
            Outcome::Accepted,
            "{}",
            String::from_utf8_lossy(item)
        );
    }
}

#[test]
fn number_tokens_are_found() {
    let spans = number_spans(b"a = [1.0, -2e-3, +inf, nan]\nse3 = x_1 # 7");
    let toks: Vec<&[u8]> = spans
        .iter()
        .map(|(s, e)| &b"a = [1.0, -2e-3, +inf, nan]\nse3 = x_1 # 7"[*s..*e])
        .collect();
    assert_eq!(
        toks,
        [&b"1.0"[..], b"-2e-3", b"+inf", b"nan", b"7"].to_vec()
    );
}

#[test]
fn list_length_changes_keep_nested_lists_apart() {
    let data = b"x = [[1, 2], [3, 4]]";
    assert_eq!(matching_close(data, 4), Some(19));
    assert_eq!(
        list_elements(&data[5..19]),
        vec![b"[1, 2]".to_vec(), b"[3, 4]".to_vec()]
    );
    assert_eq!(matching_close(b"[1, {]", 0), None);
}

#[test]
fn invalid_keys_are_named_without_indices() {
    let e = ScenarioError::Invalid {
        origin: String::new(),
        key: "reference.torque[2].terms[10]".to_owned(),
        message: String::new(),
    };
    assert_eq!(
        scenario_error_kind(&e),
        "ScenarioError::Invalid (reference.torque[*].terms[*])"
    );
}

#[test]
fn every_op_runs_on_every_seed() {
    let c = Corpus::new();
    let s = Streams::new(3);
    for (case, (op, _)) in TOML_OPS.iter().cycle().take(2000).enumerate() {
        let mut g = s.case(case as u64);
        let mut data = g.pick(&c.items).clone();
        toml_op(&mut g, *op, &mut data, &c.items[0]);
        let _ = check(&data);
    }
}
