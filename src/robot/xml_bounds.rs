//! Bounds on URDF text checked before the XML parser sees it ([D17](crate::theory#d17)).
//!
//! urdf-rs parses recursively: every nesting level of XML elements costs stack, and a deep enough document (about
//! 4,000 levels, 28 KB of text, on a 2 MiB thread) overflows the stack, which aborts the process — no `Result` and no
//! `catch_unwind` can stop that. The text is therefore scanned first, in one pass and without recursion, for its size
//! and its element nesting depth.

use super::RobotError;
use crate::bounds::{read_text_file, ReadFailure};
use std::path::Path;

/// The largest URDF text accepted (bytes): 8 MiB. The largest robot descriptions (humanoids with many links,
/// meshes in separate files) are a few hundred kilobytes; the bound keeps the parser's time and memory bounded.
pub const MAX_URDF_BYTES: usize = 8 << 20;

/// The deepest element nesting accepted: 64 levels. A URDF nests 4 or 5 levels (`robot`, `link`, `visual`,
/// `geometry`, `mesh`); 64 levels use a few tens of kilobytes of the parser's stack, far below the 2 MiB of a spawned
/// thread (the fuzz harness runs on such a thread and checks it).
pub const MAX_URDF_DEPTH: usize = 64;

/// Checks the size and the element nesting depth of URDF text ([`first_too_deep`]).
///
/// # Errors
/// [`RobotError::UrdfTooLarge`], [`RobotError::UrdfTooDeep`] (with the line where the limit is passed).
pub(crate) fn check_urdf_text(xml: &str) -> Result<(), RobotError> {
    if xml.len() > MAX_URDF_BYTES {
        return Err(RobotError::UrdfTooLarge {
            bytes: xml.len() as u64,
            limit: MAX_URDF_BYTES,
        });
    }
    match first_too_deep(xml.as_bytes(), MAX_URDF_DEPTH) {
        Some(line) => Err(RobotError::UrdfTooDeep {
            depth: MAX_URDF_DEPTH + 1,
            limit: MAX_URDF_DEPTH,
            line,
        }),
        None => Ok(()),
    }
}

/// The line (from 1) of the first element of XML text nested deeper than `limit` levels, `None` when none is: one
/// pass, no recursion, for any XML the crate reads (URDF, COLLADA meshes).
///
/// The depth counted is never less than a parser's: comments, processing instructions, CDATA sections and
/// declarations are skipped, attribute values are skipped whole (a `>` inside quotes does not end a tag), an
/// element opens one level unless its tag ends with `/>`, and a closing tag closes one.
pub(crate) fn first_too_deep(bytes: &[u8], limit: usize) -> Option<usize> {
    let mut depth = 0usize;
    let mut i = 0;
    while let Some(offset) = bytes[i..].iter().position(|&b| b == b'<') {
        let start = i + offset;
        let rest = &bytes[start..];
        let skip_to = |end: &[u8]| {
            rest.windows(end.len())
                .position(|w| w == end)
                .map_or(bytes.len(), |p| start + p + end.len())
        };
        i = if rest.starts_with(b"<!--") {
            skip_to(b"-->")
        } else if rest.starts_with(b"<![CDATA[") {
            skip_to(b"]]>")
        } else if rest.starts_with(b"<?") {
            skip_to(b"?>")
        } else if rest.starts_with(b"<!") {
            skip_to(b">")
        } else {
            let (end, self_closing) = tag_end(bytes, start + 1);
            if rest.starts_with(b"</") {
                depth = depth.saturating_sub(1);
            } else if !self_closing {
                depth += 1;
                if depth > limit {
                    return Some(1 + bytes[..start].iter().filter(|&&b| b == b'\n').count());
                }
            }
            end
        };
    }
    None
}

/// The index after the `>` that ends the tag whose content starts at `from` (quoted attribute values skipped), and
/// whether the tag ends with `/>`. An unterminated tag runs to the end of the text.
///
/// A quote opens a value only right after `=` (spaces allowed between): a stray quote elsewhere in a malformed tag
/// (`<link na'me>`) must not hide the rest of the text from the depth count while the parser, recovering or not, may
/// still read it. A `>` inside a value does not end the tag, so `<a x="/>">` counts as an opening tag.
fn tag_end(bytes: &[u8], from: usize) -> (usize, bool) {
    let mut quote = None;
    let mut after_equals = false;
    for (k, &b) in bytes.iter().enumerate().skip(from) {
        match (quote, b) {
            (Some(q), _) if b == q => quote = None,
            (Some(_), _) => {}
            (None, b'"' | b'\'') if after_equals => quote = Some(b),
            (None, b'>') => return (k + 1, bytes[k - 1] == b'/'),
            (None, b'=') => {
                after_equals = true;
                continue;
            }
            (None, b' ' | b'\t' | b'\n' | b'\r') if after_equals => continue,
            (None, _) => {}
        }
        after_equals = false;
    }
    (bytes.len(), false)
}

/// Reads a URDF file, refusing one larger than [`MAX_URDF_BYTES`] before reading it.
///
/// # Errors
/// [`RobotError::File`] when the file cannot be read, [`RobotError::UrdfTooLarge`].
pub(crate) fn read_urdf_file(path: &Path) -> Result<String, RobotError> {
    read_text_file(path, MAX_URDF_BYTES).map_err(|failure| match failure {
        ReadFailure::Io(e) => RobotError::File {
            path: path.display().to_string(),
            message: e.to_string(),
        },
        ReadFailure::TooLarge(bytes) => RobotError::UrdfTooLarge {
            bytes,
            limit: MAX_URDF_BYTES,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nested(depth: usize, open: &str, close: &str) -> String {
        format!("{}{}", open.repeat(depth), close.repeat(depth))
    }

    /// A stray quote inside a tag name (a fuzz finding: `urdf-rail7-stray-quote.urdf`) does not hide the nesting that
    /// follows; a `>` or `/>` inside an attribute value does not end the tag.
    #[test]
    fn stray_quotes_and_quoted_brackets_do_not_hide_nesting() {
        let stray = format!(
            "<robot><li'nk name='x'>{}",
            nested(100, "<link>", "</link>")
        );
        assert!(matches!(
            check_urdf_text(&stray),
            Err(RobotError::UrdfTooDeep { .. })
        ));
        let quoted = nested(100, r#"<link name="/>">"#, "</link>");
        assert!(matches!(
            check_urdf_text(&quoted),
            Err(RobotError::UrdfTooDeep { .. })
        ));
        assert_eq!(
            check_urdf_text(r#"<robot name = 'a>b'><link name="c"/></robot>"#),
            Ok(())
        );
    }

    #[test]
    fn depth_at_the_limit_passes_and_one_more_fails() {
        assert_eq!(
            check_urdf_text(&nested(MAX_URDF_DEPTH, "<a>", "</a>")),
            Ok(())
        );
        assert_eq!(
            check_urdf_text(&format!("<r>\n{}", nested(MAX_URDF_DEPTH, "<a>", "</a>"))),
            Err(RobotError::UrdfTooDeep {
                depth: MAX_URDF_DEPTH + 1,
                limit: MAX_URDF_DEPTH,
                line: 2
            })
        );
    }

    #[test]
    fn siblings_self_closing_tags_and_skipped_sections_do_not_count() {
        // 1000 siblings, each one level deep.
        let siblings = format!(
            "<robot>{}</robot>",
            "<link name='a'/><joint></joint>".repeat(1000)
        );
        assert_eq!(check_urdf_text(&siblings), Ok(()));
        // Tags inside comments, CDATA, declarations and attribute values are not elements.
        let hidden = format!(
            "<?xml version='1.0'?><!DOCTYPE robot><robot name='<a><a>'><!-- {} --><![CDATA[{}]]></robot>",
            "<a>".repeat(1000),
            "<a>".repeat(1000)
        );
        assert_eq!(check_urdf_text(&hidden), Ok(()));
        // A `>` inside a quoted value does not end the tag: the next element is still nested.
        let quoted = nested(MAX_URDF_DEPTH + 1, "<a b='>/'>", "</a>");
        assert!(matches!(
            check_urdf_text(&quoted),
            Err(RobotError::UrdfTooDeep { .. })
        ));
    }

    #[test]
    fn unterminated_input_is_scanned_without_panicking() {
        for text in ["<", "<a", "<a b='", "<!--", "<![CDATA[", "<?", "</", "<a/"] {
            assert_eq!(check_urdf_text(text), Ok(()), "{text:?}");
        }
    }

    #[test]
    fn text_larger_than_the_limit_is_refused() {
        let text = " ".repeat(MAX_URDF_BYTES + 1);
        assert_eq!(
            check_urdf_text(&text),
            Err(RobotError::UrdfTooLarge {
                bytes: MAX_URDF_BYTES as u64 + 1,
                limit: MAX_URDF_BYTES
            })
        );
    }
}
