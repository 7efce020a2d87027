//! Shared pieces of the text formats: numbered lines, tokens, numbers, and
//! round-trip-exact number output.

use std::io::Write;

/// Lines of a text file with their 1-based numbers. Accepts `\n` and `\r\n`
/// endings; the ending is not part of the line.
pub(crate) struct Lines<'a> {
    rest: &'a [u8],
    number: usize,
}

impl<'a> Lines<'a> {
    /// Lines of `bytes`, the first numbered `first_number`.
    pub fn new(bytes: &'a [u8], first_number: usize) -> Self {
        Lines {
            rest: bytes,
            number: first_number.saturating_sub(1),
        }
    }

    /// Number of the line last returned (0 before the first).
    pub fn number(&self) -> usize {
        self.number
    }

    /// The bytes not yet returned.
    pub fn rest(&self) -> &'a [u8] {
        self.rest
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, &'a [u8]);

    fn next(&mut self) -> Option<(usize, &'a [u8])> {
        if self.rest.is_empty() {
            return None;
        }
        let (line, rest) = match self.rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&self.rest[..i], &self.rest[i + 1..]),
            None => (self.rest, &self.rest[self.rest.len()..]),
        };
        self.rest = rest;
        self.number += 1;
        Some((self.number, line.strip_suffix(b"\r").unwrap_or(line)))
    }
}

/// `bytes` cut at line ends into pieces of about `target` bytes (whole
/// lines), each with the number of its first line; the first piece starts
/// at line `first_number`.
pub(crate) fn line_chunks(bytes: &[u8], first_number: usize, target: usize) -> Vec<(usize, &[u8])> {
    let mut chunks = Vec::with_capacity(bytes.len() / target.max(1) + 1);
    let mut rest = bytes;
    let mut number = first_number;
    while !rest.is_empty() {
        let cut = target.max(1).min(rest.len());
        let end = match rest[cut..].iter().position(|&b| b == b'\n') {
            Some(i) => cut + i + 1,
            None => rest.len(),
        };
        let (chunk, tail) = rest.split_at(end);
        chunks.push((number, chunk));
        number += chunk.iter().filter(|&&b| b == b'\n').count();
        rest = tail;
    }
    chunks
}

/// Whitespace-separated tokens of one line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// `line` up to a `#` comment.
pub(crate) fn strip_comment(line: &[u8]) -> &[u8] {
    match line.iter().position(|&b| b == b'#') {
        Some(i) => &line[..i],
        None => line,
    }
}

/// Whether a line holds nothing but whitespace.
pub(crate) fn is_blank(line: &[u8]) -> bool {
    line.iter().all(|b| b.is_ascii_whitespace())
}

/// A decimal number (any form Rust's `f64` parser accepts, incl. `nan`/`inf`,
/// which callers reject where they must be finite).
pub(crate) fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// A decimal integer.
pub(crate) fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// A token quoted for an error message, shortened if long.
pub(crate) fn show(token: &[u8]) -> String {
    const MAX: usize = 32;
    let text = String::from_utf8_lossy(&token[..token.len().min(MAX)]);
    if token.len() > MAX {
        format!("\"{text}...\"")
    } else {
        format!("{text:?}")
    }
}

/// Write `v` so that parsing it gives back exactly `v`: the shortest
/// round-trip form, in exponent notation only for very large or small
/// magnitudes (Rust's plain `Display` would spell out hundreds of zeros).
pub(crate) fn write_f64(w: &mut dyn Write, v: f64) -> std::io::Result<()> {
    let a = v.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        write!(w, "{v}")
    } else {
        write!(w, "{v:e}")
    }
}

/// Write several numbers separated by spaces (no line end).
pub(crate) fn write_f64s(w: &mut dyn Write, values: &[f64]) -> std::io::Result<()> {
    for (i, &v) in values.iter().enumerate() {
        if i > 0 {
            w.write_all(b" ")?;
        }
        write_f64(w, v)?;
    }
    Ok(())
}
