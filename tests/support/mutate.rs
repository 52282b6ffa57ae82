//! Random damage to valid files, for the parsers' property tests (each crate includes this
//! file with `#[path]`): truncations, byte changes, insertions, deletions, repeated spans, and
//! numbers replaced by extreme ones (the damage a disk, a transfer or a hand edit does).
//! Positions are drawn as fractions of the length, so one edit list fits any file.

use proptest::prelude::*;

/// Numbers a hand edit or a corrupt writer puts where a valid one was.
pub const EXTREME_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "-0",
    "1e309",
    "-1e309",
    "nan",
    "inf",
    "18446744073709551616",
    "4294967296",
    "2147483648",
    "99999999999999999999",
    "0.0000000000000000000001",
    "",
];

/// Bytes that matter to parsers: separators, signs, digits, quotes, high bytes.
const SPECIAL_BYTES: &[u8] = b"\0\n\r \t,.:-+e9\"{}[]=\xff\x80";

/// One edit of a file.
#[derive(Debug, Clone)]
pub enum Edit {
    /// Keep only the first `at` fraction of the bytes.
    Truncate(f64),
    /// Overwrite one byte.
    Set(f64, u8),
    /// Insert bytes.
    Insert(f64, Vec<u8>),
    /// Remove up to `len` bytes.
    Remove(f64, usize),
    /// Repeat a span (a duplicated line or record).
    Repeat(f64, usize),
    /// Replace the `k`-th number (run of digits, mod their count) by an extreme one.
    Number(usize, &'static str),
}

fn byte() -> impl Strategy<Value = u8> {
    prop_oneof![any::<u8>(), prop::sample::select(SPECIAL_BYTES)]
}

fn edit() -> impl Strategy<Value = Edit> {
    let at = 0.0..1.0f64;
    prop_oneof![
        1 => at.clone().prop_map(Edit::Truncate),
        3 => (at.clone(), byte()).prop_map(|(a, b)| Edit::Set(a, b)),
        2 => (at.clone(), prop::collection::vec(byte(), 1..8)).prop_map(|(a, b)| Edit::Insert(a, b)),
        2 => (at.clone(), 1..64usize).prop_map(|(a, n)| Edit::Remove(a, n)),
        1 => (at, 1..64usize).prop_map(|(a, n)| Edit::Repeat(a, n)),
        3 => (any::<usize>(), prop::sample::select(EXTREME_NUMBERS))
            .prop_map(|(k, n)| Edit::Number(k, n)),
    ]
}

/// One to four edits.
pub fn edits() -> impl Strategy<Value = Vec<Edit>> {
    prop::collection::vec(edit(), 1..5)
}

/// `bytes` with `edits` applied in order.
pub fn apply(bytes: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for e in edits {
        let pos = |f: f64, len: usize| ((f * len as f64) as usize).min(len);
        match e {
            Edit::Truncate(f) => b.truncate(pos(*f, b.len())),
            Edit::Set(f, v) => {
                if !b.is_empty() {
                    let i = pos(*f, b.len() - 1);
                    b[i] = *v;
                }
            }
            Edit::Insert(f, v) => {
                let i = pos(*f, b.len());
                b.splice(i..i, v.iter().copied());
            }
            Edit::Remove(f, n) => {
                let i = pos(*f, b.len());
                let j = (i + n).min(b.len());
                b.drain(i..j);
            }
            Edit::Repeat(f, n) => {
                let i = pos(*f, b.len());
                let j = (i + n).min(b.len());
                let span = b[i..j].to_vec();
                b.splice(j..j, span);
            }
            Edit::Number(k, n) => {
                let runs = digit_runs(&b);
                if !runs.is_empty() {
                    let (i, j) = runs[k % runs.len()];
                    b.splice(i..j, n.bytes());
                }
            }
        }
    }
    b
}

/// `[start, end)` of every run of ASCII digits.
fn digit_runs(b: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let start = i;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            runs.push((start, i));
        } else {
            i += 1;
        }
    }
    runs
}

/// The property-test settings: `cases` cases, no regression files written into the tree (a
/// failure found here becomes a named test instead).
pub fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}
