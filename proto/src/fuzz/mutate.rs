//! Mutations of a valid encoding: what a corrupt link, a truncated
//! write or a hostile sender makes of a good message.

use proptest::prelude::*;

/// One change to a payload. Positions are taken modulo its length, so a
/// mutation drawn for one payload applies to any.
#[derive(Debug, Clone)]
pub enum Mutation {
    /// Flip one bit.
    FlipBit {
        /// Byte position.
        at: usize,
        /// Bit 0-7.
        bit: u8,
    },
    /// Cut the payload to this length (modulo its length).
    Truncate(usize),
    /// Append these bytes.
    Extend(Vec<u8>),
    /// Overwrite the 4-byte-aligned `u32` at this position (CDR length
    /// prefixes are 4-aligned after the header) with a huge or edge value.
    SetU32 {
        /// Position (rounded down to 4-byte alignment).
        at: usize,
        /// The value written, little-endian.
        value: u32,
    },
    /// Overwrite one byte.
    SetByte {
        /// Byte position.
        at: usize,
        /// The new value.
        value: u8,
    },
}

/// Any mutation; length fields get the values that break naive decoders.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    let edge_u32 = prop_oneof![
        Just(u32::MAX),
        Just(0x7fff_ffff),
        Just(0x8000_0000),
        Just(0x0100_0000),
        Just(0),
        0u32..64,
        any::<u32>(),
    ];
    prop_oneof![
        3 => (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        1 => any::<usize>().prop_map(Mutation::Truncate),
        1 => proptest::collection::vec(any::<u8>(), 1..16).prop_map(Mutation::Extend),
        2 => (any::<usize>(), edge_u32).prop_map(|(at, value)| Mutation::SetU32 { at, value }),
        1 => (any::<usize>(), any::<u8>()).prop_map(|(at, value)| Mutation::SetByte { at, value }),
    ]
}

/// Up to four mutations.
pub fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    proptest::collection::vec(mutation(), 1..5)
}

/// Applies `mutations` in order to `bytes`.
pub fn apply(bytes: &mut Vec<u8>, mutations: &[Mutation]) {
    for m in mutations {
        let len = bytes.len();
        match m {
            Mutation::FlipBit { at, bit } if len > 0 => bytes[at % len] ^= 1 << bit,
            Mutation::Truncate(n) if len > 0 => bytes.truncate(n % len),
            Mutation::Extend(more) => bytes.extend_from_slice(more),
            Mutation::SetU32 { at, value } if len >= 4 => {
                let at = (at % (len - 3)) & !3;
                bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            }
            Mutation::SetByte { at, value } if len > 0 => bytes[at % len] = *value,
            _ => {}
        }
    }
}

/// One change to a text file (a site or an MSU configuration).
#[derive(Debug, Clone)]
pub enum TextMutation {
    /// A byte mutation of the file (the result read as lossy UTF-8).
    Bytes(Mutation),
    /// Replace the `n`-th number (modulo their count) with an extreme one.
    Number {
        /// Which number.
        n: usize,
        /// What to write instead.
        with: &'static str,
    },
    /// Delete line `n` (modulo the line count).
    DeleteLine(usize),
    /// Write line `n` twice (a duplicated key or table).
    DuplicateLine(usize),
    /// Move line `from` in front of line `to`.
    MoveLine {
        /// Line moved.
        from: usize,
        /// Where to.
        to: usize,
    },
}

/// Numbers a hostile or clumsy file holds.
const EXTREME_NUMBERS: [&str; 14] = [
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "-inf",
    "0",
    "-0.0",
    "-1",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999",
    "1e-320",
    "4294967296",
    "1e16",
];

/// Any text mutation.
pub fn text_mutation() -> impl Strategy<Value = TextMutation> {
    prop_oneof![
        2 => mutation().prop_map(TextMutation::Bytes),
        4 => (any::<usize>(), proptest::sample::select(&EXTREME_NUMBERS[..]))
            .prop_map(|(n, with)| TextMutation::Number { n, with }),
        1 => any::<usize>().prop_map(TextMutation::DeleteLine),
        1 => any::<usize>().prop_map(TextMutation::DuplicateLine),
        1 => (any::<usize>(), any::<usize>()).prop_map(|(from, to)| TextMutation::MoveLine { from, to }),
    ]
}

/// Up to three text mutations.
pub fn text_mutations() -> impl Strategy<Value = Vec<TextMutation>> {
    proptest::collection::vec(text_mutation(), 1..4)
}

/// Applies `mutations` in order to `text`.
pub fn apply_text(text: &str, mutations: &[TextMutation]) -> String {
    let mut text = text.to_string();
    for m in mutations {
        text = match m {
            TextMutation::Bytes(b) => {
                let mut bytes = text.into_bytes();
                apply(&mut bytes, std::slice::from_ref(b));
                String::from_utf8_lossy(&bytes).into_owned()
            }
            TextMutation::Number { n, with } => replace_number(&text, *n, with),
            TextMutation::DeleteLine(n) => edit_lines(&text, |lines| {
                let n = n % lines.len();
                lines.remove(n);
            }),
            TextMutation::DuplicateLine(n) => edit_lines(&text, |lines| {
                let n = n % lines.len();
                lines.insert(n, lines[n].clone());
            }),
            TextMutation::MoveLine { from, to } => edit_lines(&text, |lines| {
                let line = lines.remove(from % lines.len());
                lines.insert(to % (lines.len() + 1), line);
            }),
        };
    }
    text
}

fn edit_lines(text: &str, edit: impl FnOnce(&mut Vec<String>)) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if !lines.is_empty() {
        edit(&mut lines);
    }
    lines.join("\n")
}

/// Replaces the `n`-th run of digits (with its sign, point and exponent)
/// modulo the number of runs.
fn replace_number(text: &str, n: usize, with: &str) -> String {
    let bytes = text.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && bytes[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || b".+-_".contains(&bytes[i]))
            {
                i += 1;
            }
            spans.push(start..i);
        } else {
            i += 1;
        }
    }
    if spans.is_empty() {
        return text.to_string();
    }
    let span = spans[n % spans.len()].clone();
    format!("{}{}{}", &text[..span.start], with, &text[span.end..])
}
