//! The README's excerpt of `src/lib.rs` is the file's text: every line of it, in order.

#[test]
fn the_readmes_excerpt_is_the_source() {
    let readme = include_str!("../README.md");
    let source = include_str!("../src/lib.rs");
    let start = readme
        .find("```rust,ignore\n")
        .expect("the README has its excerpt")
        + 15;
    let excerpt = &readme[start..start + readme[start..].find("```").unwrap()];
    let mut rest = source;
    for line in excerpt.lines().filter(|l| !l.trim().is_empty()) {
        match rest.find(&format!("{line}\n")) {
            Some(at) => rest = &rest[at + line.len()..],
            None => panic!("the README's line `{line}` is not in src/lib.rs (in this order)"),
        }
    }
}
