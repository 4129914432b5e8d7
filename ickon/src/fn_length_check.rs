//! No function of the product over [`MAX_LINES`] lines: for every crate of
//! the workspace, the functions of its `src/` (test modules, `*_tests.rs`
//! files and the test crates left out), counted from the line of `fn` to
//! the line of the closing brace. The functions still longer are listed in
//! [`LONG`] with their length today: one that grows, a new long one, or a
//! listed one that got short (or went) fails the check, so the list only
//! shrinks.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::import_check::{crate_dirs, root};

/// The longest a function may be, in lines.
const MAX_LINES: usize = 100;

/// The functions still over [`MAX_LINES`]: file (from the repository's
/// root), function name, and its length in lines today, which it may not
/// pass.
const LONG: &[(&str, &str, usize)] = &[
    ("cell-controller/src/sync.rs", "estimate", 106),
    ("central-unit/src/foxglove/layout.rs", "layout", 102),
    ("central-unit/src/selection.rs", "choose", 101),
    ("device/src/message.rs", "decode", 106),
    ("evaluation/src/eval/fleet.rs", "print_report", 109),
    ("fusion/src/tdoa/closed_form.rs", "closed_form_subset", 114),
    ("launcher/src/report.rs", "render_report", 126),
    ("launcher/src/run.rs", "measure", 134),
    (
        "msu-agent/src/config_file/validate.rs",
        "apply_to_estimator",
        107,
    ),
    ("msu-agent/src/solver.rs", "solve", 103),
    ("operator/src/secure/acl.rs", "permissions", 120),
    ("operator/src/secure/mod.rs", "write_dir", 133),
    ("recording/src/record/mod.rs", "run", 108),
    ("recording/src/replay/mod.rs", "print_text", 101),
    ("recording/src/replay/mod.rs", "run", 111),
    ("sim/src/profile_file.rs", "check", 121),
    ("sim/src/score.rs", "score", 105),
    ("world-node/src/device_hosting.rs", "start", 127),
];

/// Crates whose code is tests or test support, not product (beside the
/// vendored ones and the build output, which `crate_dirs` leaves out).
const NOT_PRODUCT: &[&str] = &["tests", "testkit"];

/// Every product `.rs` file: under each crate's `src/`, no test files.
fn product_files() -> Vec<PathBuf> {
    let crates = crate_dirs().into_iter().filter(|p| {
        p.file_name()
            .is_some_and(|n| !NOT_PRODUCT.iter().any(|x| n == *x))
    });
    let mut out = Vec::new();
    for krate in crates {
        let mut dirs = vec![krate.join("src")];
        while let Some(d) = dirs.pop() {
            for entry in std::fs::read_dir(&d).expect("src/ is readable").flatten() {
                let p = entry.path();
                let name = p.file_name().unwrap_or_default().to_string_lossy();
                if p.is_dir() {
                    if name != "tests" {
                        dirs.push(p);
                    }
                } else if name.ends_with(".rs")
                    && !name.ends_with("_tests.rs")
                    && name != "tests.rs"
                    && !name.ends_with("_check.rs")
                {
                    out.push(p);
                }
            }
        }
    }
    out.sort();
    out
}

/// The code of `text` with comments, string and character literals blanked
/// out (each replaced by spaces, newlines kept), so that braces and words
/// inside them do not count.
fn blank_literals(text: &str) -> String {
    let b: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let blank = |out: &mut String, s: &[char]| {
        for &c in s {
            out.push(if c == '\n' { '\n' } else { ' ' });
        }
    };
    while i < b.len() {
        let end = literal_end(&b, i);
        if end > i {
            blank(&mut out, &b[i..end]);
            i = end;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    out
}

/// Where the comment or literal starting at `i` ends (one past it), or `i`
/// when none starts there.
fn literal_end(b: &[char], i: usize) -> usize {
    let at = |k: usize| b.get(k).copied().unwrap_or('\0');
    let prev_ident = i > 0 && (at(i - 1).is_alphanumeric() || at(i - 1) == '_');
    match at(i) {
        '/' if at(i + 1) == '/' => (i..b.len()).find(|&k| b[k] == '\n').unwrap_or(b.len()),
        '/' if at(i + 1) == '*' => {
            let (mut k, mut depth) = (i + 2, 1);
            while k < b.len() && depth > 0 {
                if at(k) == '/' && at(k + 1) == '*' {
                    depth += 1;
                    k += 1;
                } else if at(k) == '*' && at(k + 1) == '/' {
                    depth -= 1;
                    k += 1;
                }
                k += 1;
            }
            k
        }
        'r' | 'b' if !prev_ident => raw_string_end(b, i).unwrap_or(i),
        '"' => {
            let mut k = i + 1;
            while k < b.len() && b[k] != '"' {
                k += if b[k] == '\\' { 2 } else { 1 };
            }
            (k + 1).min(b.len())
        }
        // A character literal ('x', '\n', '{'), not a lifetime ('a).
        '\'' if at(i + 1) == '\\' => (i + 3..b.len())
            .find(|&k| b[k] == '\'')
            .map_or(i, |k| k + 1),
        '\'' if at(i + 2) == '\'' => i + 3,
        _ => i,
    }
}

/// The end of a raw string (`r"…"`, `r#"…"#`, `br"…"`) starting at `i`.
fn raw_string_end(b: &[char], i: usize) -> Option<usize> {
    let mut k = i;
    if b.get(k) == Some(&'b') {
        k += 1;
    }
    if b.get(k) != Some(&'r') {
        return None;
    }
    k += 1;
    let hashes = b[k..].iter().take_while(|&&c| c == '#').count();
    k += hashes;
    if b.get(k) != Some(&'"') {
        return None;
    }
    k += 1;
    while k < b.len() {
        if b[k] == '"'
            && b[k + 1..]
                .iter()
                .take(hashes)
                .filter(|&&c| c == '#')
                .count()
                == hashes
        {
            return Some(k + 1 + hashes);
        }
        k += 1;
    }
    Some(b.len())
}

/// The index of the brace closing the one at `open`.
fn closing(code: &[u8], open: usize) -> usize {
    let mut depth = 0usize;
    for (k, &c) in code.iter().enumerate().skip(open) {
        match c {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return k;
                }
            }
            _ => {}
        }
    }
    code.len()
}

/// The first `{` or `;` after `at` outside parentheses and brackets (a
/// signature's `[u8; 4]` holds a `;` that does not end it).
fn body_or_end(code: &[u8], at: usize) -> Option<usize> {
    let mut depth = 0i32;
    for (k, &c) in code.iter().enumerate().skip(at) {
        match c {
            b'(' | b'[' => depth += 1,
            b')' | b']' => depth -= 1,
            b'{' | b';' if depth <= 0 => return Some(k),
            _ => {}
        }
    }
    None
}

/// Each function of `text` outside `#[cfg(test)]` items: its name and its
/// length in lines.
fn functions(text: &str) -> Vec<(String, usize)> {
    let code = blank_literals(text);
    let bytes = code.as_bytes();
    let line_of = |at: usize| bytes[..at].iter().filter(|&&c| c == b'\n').count();
    // Test items (a `#[cfg(test)] mod` or fn) are skipped whole.
    let mut skip: Vec<(usize, usize)> = Vec::new();
    for (at, _) in code.match_indices("#[cfg(test)]") {
        if let Some(open) = code[at..].find(['{', ';']).map(|k| at + k)
            && bytes[open] == b'{'
        {
            skip.push((at, closing(bytes, open)));
        }
    }
    let mut out = Vec::new();
    for (at, _) in code.match_indices("fn ") {
        let word_start =
            at == 0 || !(bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_');
        if !word_start || skip.iter().any(|&(a, b)| a <= at && at <= b) {
            continue;
        }
        let name: String = code[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        // A declaration without a body (a trait's) ends at `;` first.
        let Some(open) = body_or_end(bytes, at) else {
            continue;
        };
        if name.is_empty() || bytes[open] != b'{' {
            continue;
        }
        let close = closing(bytes, open);
        out.push((name, line_of(close) - line_of(at) + 1));
    }
    out
}

/// Every product function over [`MAX_LINES`]: (file, name) -> the longest
/// of that name in that file.
fn long_functions() -> BTreeMap<(String, String), usize> {
    let root = root();
    let mut out = BTreeMap::new();
    for file in product_files() {
        let text = std::fs::read_to_string(&file).expect("readable");
        let rel = file
            .strip_prefix(&root)
            .unwrap_or(&file)
            .to_string_lossy()
            .replace('\\', "/");
        for (name, lines) in functions(&text) {
            if lines > MAX_LINES {
                let e = out.entry((rel.clone(), name)).or_insert(0);
                *e = (*e).max(lines);
            }
        }
    }
    out
}

#[test]
fn no_product_function_is_longer_than_allowed() {
    let found = long_functions();
    let mut wrong = Vec::new();
    for ((file, name), &lines) in &found {
        match LONG.iter().find(|(f, n, _)| f == file && n == name) {
            None => wrong.push(format!(
                "{file}: fn {name} is {lines} lines (at most {MAX_LINES}: split it)"
            )),
            Some(&(_, _, allowed)) if lines > allowed => wrong.push(format!(
                "{file}: fn {name} grew to {lines} lines (listed at {allowed}: split it)"
            )),
            Some(&(_, _, allowed)) if lines < allowed => wrong.push(format!(
                "{file}: fn {name} is {lines} lines now: lower its entry from {allowed}"
            )),
            Some(_) => {}
        }
    }
    for (file, name, _) in LONG {
        if !found.contains_key(&(file.to_string(), name.to_string())) {
            wrong.push(format!(
                "{file}: fn {name} is gone or short: remove its entry"
            ));
        }
    }
    assert!(wrong.is_empty(), "long functions:\n{}", wrong.join("\n"));
}

#[test]
fn the_check_counts_lines_and_skips_literals_and_tests() {
    let text = r##"
fn short() {
    let s = "}{ fn fake() {";
    let c = '{';
    let r = r#"}"#;
    // } fn commented() {
}

pub async fn long<'a>(x: &'a str, _: [u8; 4]) -> impl Fn() + 'a {
    move || {
        let _ = x;
    }
}

#[cfg(test)]
mod tests {
    fn hidden() {}
}
"##;
    let found = functions(text);
    assert_eq!(
        found,
        [("short".to_string(), 6), ("long".to_string(), 5)],
        "{found:?}"
    );
}
