//! The scenario reference (docs/scenario.md) cannot drift from the parser: every key the
//! parser accepts is a row of the page, and every row of the page names a key the parser
//! accepts.
//!
//! The parser is asked, not a list kept beside it: a scenario with an unknown key in a table
//! is refused with serde's "unknown field `…`, expected one of `…`", which names every key of
//! that table. Starting from the top level, each key is tried as a table (`[a.b]`) and as an
//! array of tables (`[[a.b]]`); where the parser answers with a list, the walk goes on inside.
//! The page's rows name keys by their dotted path in backticks, `[]` marking the elements of
//! an array of tables (`plant.disturbance_steps[].t`).

use scenario::Scenario;
use std::collections::BTreeSet;

const PROBE: &str = "zz_not_a_key";

/// One step of a key's path: its name and whether it is an array of tables.
type Step = (String, bool);

/// The TOML that puts [`PROBE`] into the table at `path`.
fn probe_toml(path: &[Step]) -> String {
    let mut text = String::new();
    let dotted = |n: usize| {
        path[..n]
            .iter()
            .map(|(k, _)| k.as_str())
            .collect::<Vec<_>>()
            .join(".")
    };
    for (i, (_, array)) in path.iter().enumerate() {
        if *array {
            text += &format!("[[{}]]\n", dotted(i + 1));
        }
    }
    if let Some((_, false)) = path.last() {
        text += &format!("[{}]\n", dotted(path.len()));
    }
    text + &format!("{PROBE} = 1\n")
}

/// The keys of the table at `path`, as the parser lists them (`None`: not a table there).
fn keys_of(path: &[Step]) -> Option<Vec<String>> {
    let err = Scenario::from_toml(&probe_toml(path), "probe", "probe")
        .err()?
        .to_string();
    let list = err
        .split(&format!("unknown field `{PROBE}`, expected "))
        .nth(1)?;
    let list = list.lines().next().unwrap_or("");
    // "one of `a`, `b`", "`a` or `b`", "`a`"
    Some(
        list.split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_owned)
            .collect(),
    )
}

fn name(path: &[Step]) -> String {
    path.iter()
        .map(|(k, array)| format!("{k}{}", if *array { "[]" } else { "" }))
        .collect::<Vec<_>>()
        .join(".")
}

/// Every key the parser accepts, by dotted path: `(leaves, tables)`.
fn parser_keys() -> (BTreeSet<String>, BTreeSet<String>) {
    let (mut leaves, mut tables) = (BTreeSet::new(), BTreeSet::new());
    let mut todo: Vec<Vec<Step>> = vec![vec![]];
    while let Some(path) = todo.pop() {
        let keys = keys_of(&path).unwrap_or_else(|| panic!("`{}` is not a table", name(&path)));
        assert!(!keys.is_empty(), "no keys listed for `{}`", name(&path));
        for key in keys {
            let inner = [false, true].into_iter().find_map(|array| {
                let mut p = path.clone();
                p.push((key.clone(), array));
                keys_of(&p).map(|_| p)
            });
            match inner {
                Some(p) => {
                    tables.insert(name(&p));
                    todo.push(p);
                }
                None => {
                    let mut p = path.clone();
                    p.push((key, false));
                    leaves.insert(name(&p));
                }
            }
        }
    }
    (leaves, tables)
}

/// The keys the page's tables document: the first cell of each row, in backticks.
fn page_keys(page: &str) -> BTreeSet<String> {
    page.lines()
        .filter_map(|l| l.trim().strip_prefix("| `")?.split('`').next())
        .map(str::to_owned)
        .collect()
}

fn page() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("docs/scenario.md");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_probe_finds_keys_where_they_are_and_nothing_elsewhere() {
    let top = keys_of(&[]).expect("the top level is a table");
    assert!(top.iter().any(|k| k == "control_period"), "{top:?}");
    let steps = keys_of(&[("plant".into(), false), ("disturbance_steps".into(), true)]);
    assert_eq!(steps, Some(vec!["t".to_owned(), "value".to_owned()]));
    assert_eq!(keys_of(&[("duration".into(), false)]), None);
}

#[test]
fn every_key_the_parser_accepts_is_on_the_scenario_page_and_every_row_is_a_key() {
    let (leaves, tables) = parser_keys();
    assert!(
        leaves.len() > 40,
        "only {} keys found: {leaves:?}",
        leaves.len()
    );
    let documented = page_keys(&page());
    let missing: Vec<&String> = leaves.difference(&documented).collect();
    assert!(
        missing.is_empty(),
        "keys the parser accepts that docs/scenario.md does not document: {missing:?}"
    );
    let unknown: Vec<&String> = documented
        .iter()
        .filter(|k| !leaves.contains(*k) && !tables.contains(*k))
        .collect();
    assert!(
        unknown.is_empty(),
        "rows of docs/scenario.md that the parser does not accept: {unknown:?}"
    );
}

#[test]
fn the_comparison_catches_a_row_too_many_and_a_row_too_few() {
    let (leaves, _) = parser_keys();
    let page = page();
    let documented = page_keys(&page);
    let planted = page_keys(&format!("{page}\n| `plant.no_such_key` | x | | y |\n"));
    assert!(planted.contains("plant.no_such_key") && !leaves.contains("plant.no_such_key"));
    let dropped = page_keys(&page.replace("| `control_period`", "| control_period"));
    assert!(documented.contains("control_period") && !dropped.contains("control_period"));
}
