//! Bounds on scenario text checked before the TOML parser sees it ([D17](crate::theory#d17)).
//!
//! The TOML parser builds (and drops) nested arrays and inline tables recursively: a deep enough nesting overflows the
//! stack, which aborts the process. The text is scanned first, in one pass and without recursion, for its size and its
//! bracket nesting depth.

use super::ScenarioError;
use crate::bounds::{read_text_file, ReadFailure};
use std::path::Path;

/// The largest scenario text accepted (bytes): 1 MiB, a hundred times the largest shipped scenario.
pub const MAX_SCENARIO_BYTES: usize = 1 << 20;

/// The deepest nesting of arrays and inline tables accepted: 64 (a scenario nests 3 levels: `pose = { rpy_deg = [..]
/// }` inside an array of tables).
pub const MAX_SCENARIO_DEPTH: usize = 64;

/// Checks the size and the nesting depth of `[` and `{` (table headers included) outside strings and comments.
///
/// # Errors
/// [`ScenarioError::TooLarge`], [`ScenarioError::TooDeep`] (with the line where the limit is passed).
pub(super) fn check_scenario_text(text: &str) -> Result<(), ScenarioError> {
    if text.len() > MAX_SCENARIO_BYTES {
        return Err(ScenarioError::TooLarge {
            bytes: text.len() as u64,
            limit: MAX_SCENARIO_BYTES,
        });
    }
    let bytes = text.as_bytes();
    let (mut depth, mut line, mut i) = (0usize, 1usize, 0usize);
    while i < bytes.len() {
        let rest = &bytes[i..];
        // The end of a string or comment starting here, if one does.
        let skip = |open: &[u8], close: &[u8], escapes: bool| -> Option<usize> {
            if !rest.starts_with(open) {
                return None;
            }
            let mut k = open.len();
            while k < rest.len() {
                if escapes && rest[k] == b'\\' {
                    k += 2;
                } else if rest[k..].starts_with(close) {
                    return Some(k + close.len());
                } else {
                    k += 1;
                }
            }
            Some(rest.len())
        };
        let skipped = skip(b"\"\"\"", b"\"\"\"", true)
            .or_else(|| skip(b"'''", b"'''", false))
            .or_else(|| skip(b"\"", b"\"", true))
            .or_else(|| skip(b"'", b"'", false))
            .or_else(|| skip(b"#", b"\n", false).map(|k| k - 1));
        if let Some(length) = skipped {
            let length = length.min(rest.len());
            line += rest[..length].iter().filter(|&&b| b == b'\n').count();
            i += length.max(1);
            continue;
        }
        match rest[0] {
            b'[' | b'{' => {
                depth += 1;
                if depth > MAX_SCENARIO_DEPTH {
                    return Err(ScenarioError::TooDeep {
                        depth,
                        limit: MAX_SCENARIO_DEPTH,
                        line,
                    });
                }
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            b'\n' => line += 1,
            _ => {}
        }
        i += 1;
    }
    Ok(())
}

/// Reads a scenario file, refusing one larger than [`MAX_SCENARIO_BYTES`] before reading it.
///
/// # Errors
/// [`ScenarioError::Io`], [`ScenarioError::TooLarge`].
pub(super) fn read_scenario_file(path: &Path) -> Result<String, ScenarioError> {
    read_text_file(path, MAX_SCENARIO_BYTES).map_err(|failure| match failure {
        ReadFailure::Io(source) => ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        },
        ReadFailure::TooLarge(bytes) => ScenarioError::TooLarge {
            bytes,
            limit: MAX_SCENARIO_BYTES,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn depth_error(text: &str) -> Option<(usize, usize)> {
        match check_scenario_text(text) {
            Err(ScenarioError::TooDeep { depth, line, .. }) => Some((depth, line)),
            _ => None,
        }
    }

    #[test]
    fn nesting_beyond_the_limit_is_refused_with_its_line() {
        let at_limit = format!("a = {}1{}", "[".repeat(64), "]".repeat(64));
        assert!(check_scenario_text(&at_limit).is_ok());
        let beyond = format!("x = 1\na = {}1{}", "{ b = ".repeat(65), " }".repeat(65));
        assert_eq!(depth_error(&beyond), Some((65, 2)));
    }

    #[test]
    fn brackets_in_strings_and_comments_do_not_count() {
        let deep = "[".repeat(100);
        for text in [
            format!("a = \"{deep}\""),
            format!("a = '{deep}'"),
            format!("a = \"\"\"\n{deep}\n\"\"\""),
            format!("a = '''{deep}'''"),
            format!("# {deep}\nb = 1"),
            format!("a = \"\\\"{deep}\""),
        ] {
            assert!(check_scenario_text(&text).is_ok(), "{text}");
        }
        // Unterminated strings and comments run to the end without panicking.
        for text in ["a = \"", "a = '''", "#", "a = \"\\"] {
            assert!(check_scenario_text(text).is_ok(), "{text}");
        }
    }

    #[test]
    fn text_larger_than_the_limit_is_refused() {
        let text = "#".repeat(MAX_SCENARIO_BYTES + 1);
        assert!(matches!(
            check_scenario_text(&text),
            Err(ScenarioError::TooLarge { bytes, limit: MAX_SCENARIO_BYTES }) if bytes == MAX_SCENARIO_BYTES as u64 + 1
        ));
    }
}
