//! Reading the text files springfit is given (designs, catalogues, cam files, bills of
//! materials): every error names the file, and a TOML error the line, the column and the dotted
//! key (`robot.links[1].length`), in words rather than Rust's type names.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Error, Result};

/// Reads a file, naming it in the error.
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| Error::io(path, e))
}

/// FNV-1a (64-bit) of `bytes` as 16 hexadecimal digits: the fingerprint output folders record of
/// the files springfit wrote and of the design a run read. Not a cryptographic hash: it tells an
/// edited or different file from the same one, it does not guard against forgery.
pub(crate) fn fingerprint(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Parses TOML into `T`, turning the parser's byte span into a line and column.
pub fn parse_toml<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let start = e.span().map(|span| span.start);
        let (line, column) = start.map(|s| line_column(text, s)).unwrap_or((0, 0));
        // Say what a value must be in words, not in Rust's type names.
        let message = e
            .message()
            .trim()
            .replace("expected usize", "expected a whole number ≥ 0")
            .replace("expected u64", "expected a whole number ≥ 0")
            .replace("expected u32", "expected a whole number ≥ 0")
            .replace("expected i64", "expected a whole number")
            .replace("expected f64", "expected a number")
            .replace("expected a boolean", "expected true or false");
        let message = match start.and_then(|s| key_at(text, s)) {
            Some(key) if !message.contains("unknown field") => format!("field `{key}`: {message}"),
            _ => message,
        };
        Error::Parse { path: path.to_path_buf(), line, column, message }
    })
}

/// The dotted key of the `key = value` line at a byte offset, with its table path
/// (`robot.links[1].length`), so type errors name the field as validation errors do.
pub(crate) fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let line_start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next()?;
    let (key, _) = line.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.starts_with('[') || key.starts_with('#') {
        return None;
    }
    // The innermost table header above the line, with array-of-tables indices.
    let mut table = String::new();
    let mut counts: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for l in text[..line_start].lines() {
        let l = l.trim();
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            let name = name.trim().to_string();
            let c = counts.entry(name.clone()).or_insert(0);
            table = format!("{name}[{c}]");
            *c += 1;
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.split(']').next()) {
            table = name.trim().to_string();
        }
    }
    Some(if table.is_empty() { key.to_string() } else { format!("{table}.{key}") })
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map(|l| l.chars().count()).unwrap_or(0) + 1;
    (line, column)
}
