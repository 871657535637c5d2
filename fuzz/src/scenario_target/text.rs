//! Reading TOML text as the mutations see it: number and string tokens, lines, lists.

/// Whether `b` can be part of a bare token (a key or a number).
fn is_token_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'.' | b'+' | b'-')
}

/// The spans of number-like tokens (digits first, or a sign then a digit, `.`, `i` or `n`).
pub(crate) fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if !is_token_byte(data[i]) || (i > 0 && is_token_byte(data[i - 1])) {
            i += 1;
            continue;
        }
        let start = i;
        while i < data.len() && is_token_byte(data[i]) {
            i += 1;
        }
        let tok = &data[start..i];
        let numeric = tok[0].is_ascii_digit()
            || (matches!(tok[0], b'+' | b'-')
                && tok
                    .get(1)
                    .is_some_and(|b| b.is_ascii_digit() || matches!(b, b'.' | b'i' | b'n')))
            || tok == b"nan"
            || tok == b"inf";
        if numeric {
            spans.push((start, i));
        }
    }
    spans
}

/// The spans of the text of strings (between two quotes on one line).
pub(crate) fn string_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut open = None;
    for (i, b) in data.iter().enumerate() {
        match (b, open) {
            (b'"', None) => open = Some(i + 1),
            (b'"', Some(s)) => {
                spans.push((s, i));
                open = None;
            }
            (b'\n', _) => open = None,
            _ => {}
        }
    }
    spans
}

/// The lines of `data` (split at `\n`, the newlines dropped).
pub(crate) fn split_lines(data: &[u8]) -> Vec<Vec<u8>> {
    data.split(|b| *b == b'\n').map(<[u8]>::to_vec).collect()
}

/// The lines joined with `\n`: the inverse of [`split_lines`].
pub(crate) fn join_lines(lines: &[Vec<u8>]) -> Vec<u8> {
    lines.join(&b'\n')
}

/// The index of the bracket closing the list opened at `open`, brackets and braces nested.
pub(super) fn matching_close(data: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (i, b) in data.iter().enumerate().skip(open) {
        match b {
            b'[' | b'{' => depth += 1,
            b']' | b'}' => {
                depth = depth.checked_sub(1)?;
                if depth == 0 {
                    return (*b == b']').then_some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The top-level elements of a list's inside, trimmed, empty ones dropped.
pub(super) fn list_elements(inside: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut start = 0;
    for (i, b) in inside.iter().enumerate() {
        match b {
            b'[' | b'{' => depth += 1,
            b']' | b'}' => depth -= 1,
            b',' if depth == 0 => {
                out.push(inside[start..i].trim_ascii().to_vec());
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(inside[start..].trim_ascii().to_vec());
    out.retain(|e| !e.is_empty());
    out
}
