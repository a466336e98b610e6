//! Structured mutations of text inputs (URDF, scenario, calibration and text mesh files): numbers to extremes, lines
//! deleted, duplicated or swapped, names and kinds swapped, nesting deepened (and YAML aliases multiplied), text
//! truncated.

use rand::rngs::StdRng;
use rand::RngExt;

/// The syntax a mutation keeps to (where it deepens nesting, which words it swaps).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Syntax {
    /// URDF (XML).
    Xml,
    /// A scenario file (TOML).
    Toml,
    /// A calibration file (YAML).
    Yaml,
    /// A line-based text mesh (Wavefront OBJ, ASCII STL).
    Lines,
}

/// Numbers that break naive code: overflow, underflow, NaN and infinities (in the spellings both formats and Rust's
/// float parser know), zero of both signs, sign flips, integers too large for their type.
const EXTREMES: [&str; 24] = [
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e400",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "0",
    "-0.0",
    "1e-320",
    "-1e-9",
    "-1",
    "1e200",
    "1e150",
    "1e6",
    "-1e6",
    "1001",
    "100000000",
    "18446744073709551615",
    "-9223372036854775808",
    "0.5",
    "3.4e38",
    "1e-300",
];

/// Words swapped into the text, per syntax: joint kinds, enum spellings, built-in robots.
const XML_WORDS: [&str; 9] = [
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
    "spherical",
    "bogus",
    "",
];
const TOML_WORDS: [&str; 14] = [
    "afma6",
    "ur5e",
    "rail7",
    "exact",
    "paper_approx",
    "desired",
    "auto",
    "side_ratios",
    "paper_invariants",
    "robust",
    "paper",
    "combined",
    "kernel_projection",
    "",
];

const YAML_WORDS: [&str; 9] = [
    "plumb_bob",
    "rational_polynomial",
    "equidistant",
    "!!opencv-matrix",
    "*a",
    "&a",
    "~",
    "{}",
    "",
];
const LINE_WORDS: [&str; 9] = [
    "v",
    "f",
    "vn",
    "facet",
    "vertex",
    "endloop",
    "endsolid",
    "mtllib /etc",
    "",
];

/// A YAML alias bomb: nine levels of anchors, each a list of nine aliases of the one before (9⁹ nodes once
/// expanded, from about 400 bytes).
const ALIAS_BOMB: &str = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n\
a1: &a1 [*a0, *a0, *a0, *a0, *a0, *a0, *a0, *a0, *a0]\n\
a2: &a2 [*a1, *a1, *a1, *a1, *a1, *a1, *a1, *a1, *a1]\n\
a3: &a3 [*a2, *a2, *a2, *a2, *a2, *a2, *a2, *a2, *a2]\n\
a4: &a4 [*a3, *a3, *a3, *a3, *a3, *a3, *a3, *a3, *a3]\n\
a5: &a5 [*a4, *a4, *a4, *a4, *a4, *a4, *a4, *a4, *a4]\n\
a6: &a6 [*a5, *a5, *a5, *a5, *a5, *a5, *a5, *a5, *a5]\n\
a7: &a7 [*a6, *a6, *a6, *a6, *a6, *a6, *a6, *a6, *a6]\n\
a8: &a8 [*a7, *a7, *a7, *a7, *a7, *a7, *a7, *a7, *a7]\n";

/// Nesting depths tried when deepening: around the URDF limit, and far beyond (where an unchecked recursive parser
/// overflows a 2 MiB stack).
const DEPTHS: [usize; 8] = [8, 63, 64, 65, 200, 1_000, 5_000, 30_000];

/// One to three mutations of `text`.
pub fn mutate(text: &str, syntax: Syntax, rng: &mut StdRng) -> String {
    let mut text = text.to_owned();
    for _ in 0..rng.random_range(1..=3) {
        text = match rng.random_range(0..12) {
            0..=4 => replace_numbers(&text, rng),
            5 => edit_lines(&text, rng, LineEdit::Delete),
            6 => edit_lines(&text, rng, LineEdit::Duplicate),
            7 => edit_lines(&text, rng, LineEdit::Swap),
            8 => replace_quoted(&text, syntax, rng),
            9 => deepen(&text, syntax, rng),
            10 => truncate(&text, rng),
            _ => replace_byte(&text, rng),
        };
    }
    text
}

/// The byte ranges of the numbers of `text` (an optional sign, digits, a fraction, an exponent).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let signed = matches!(bytes[i], b'-' | b'+')
            && bytes.get(i + 1).is_some_and(u8::is_ascii_digit)
            && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric());
        let starts = signed
            || (bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()));
        if !starts {
            i += 1;
            continue;
        }
        let start = i;
        i += 1;
        while i < bytes.len()
            && (bytes[i].is_ascii_digit()
                || bytes[i] == b'.'
                || bytes[i] == b'_'
                || ((bytes[i] == b'e' || bytes[i] == b'E') && i > start)
                || ((bytes[i] == b'-' || bytes[i] == b'+') && matches!(bytes[i - 1], b'e' | b'E')))
        {
            i += 1;
        }
        spans.push((start, i));
    }
    spans
}

/// Some numbers (one, a few, or all) replaced by extremes or by themselves scaled by a power of ten.
fn replace_numbers(text: &str, rng: &mut StdRng) -> String {
    let spans = numbers(text);
    if spans.is_empty() {
        return text.to_owned();
    }
    let all = rng.random_bool(0.05);
    let picked: Vec<bool> = if all {
        vec![true; spans.len()]
    } else {
        let count = rng.random_range(1..=3);
        let mut picked = vec![false; spans.len()];
        for _ in 0..count {
            picked[rng.random_range(0..spans.len())] = true;
        }
        picked
    };
    let mut out = String::with_capacity(text.len() + 64);
    let mut last = 0;
    for (&(start, end), _) in spans.iter().zip(&picked).filter(|(_, &p)| p) {
        out.push_str(&text[last..start]);
        let original = &text[start..end];
        if rng.random_bool(0.7) {
            out.push_str(EXTREMES[rng.random_range(0..EXTREMES.len())]);
        } else {
            let scale = rng.random_range(-12..=12);
            out.push_str(&format!("{original}e{scale}").replace("ee", "e"));
        }
        last = end;
    }
    out.push_str(&text[last..]);
    out
}

enum LineEdit {
    Delete,
    Duplicate,
    Swap,
}

/// A run of one to five lines deleted, duplicated, or swapped with another line.
fn edit_lines(text: &str, rng: &mut StdRng, edit: LineEdit) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    if lines.len() < 2 {
        return text.to_owned();
    }
    let start = rng.random_range(0..lines.len());
    let end = (start + rng.random_range(1..=5)).min(lines.len());
    match edit {
        LineEdit::Delete => {
            lines.drain(start..end);
        }
        LineEdit::Duplicate => {
            let copy: Vec<&str> = lines[start..end].to_vec();
            let at = rng.random_range(0..=lines.len());
            lines.splice(at..at, copy);
        }
        LineEdit::Swap => {
            let other = rng.random_range(0..lines.len());
            lines.swap(start, other);
        }
    }
    lines.join("\n")
}

/// The content of one quoted string replaced by a word of the syntax or by another quoted string of the text (link
/// and joint names swapped make cycles, several parents, unknown links).
fn replace_quoted(text: &str, syntax: Syntax, rng: &mut StdRng) -> String {
    let quotes: Vec<usize> = text.match_indices('"').map(|(i, _)| i).collect();
    let strings: Vec<(usize, usize)> = quotes
        .chunks_exact(2)
        .map(|pair| (pair[0] + 1, pair[1]))
        .collect();
    if strings.is_empty() {
        return text.to_owned();
    }
    let (start, end) = strings[rng.random_range(0..strings.len())];
    let replacement = if rng.random_bool(0.5) {
        let (a, b) = strings[rng.random_range(0..strings.len())];
        text[a..b].to_owned()
    } else {
        match syntax {
            Syntax::Xml => XML_WORDS[rng.random_range(0..XML_WORDS.len())],
            Syntax::Toml => TOML_WORDS[rng.random_range(0..TOML_WORDS.len())],
            Syntax::Yaml => YAML_WORDS[rng.random_range(0..YAML_WORDS.len())],
            Syntax::Lines => LINE_WORDS[rng.random_range(0..LINE_WORDS.len())],
        }
        .to_owned()
    };
    format!("{}{replacement}{}", &text[..start], &text[end..])
}

/// Nested elements (XML), nested arrays and inline tables (TOML), nested flow collections or an alias bomb (YAML), or
/// many vertices of extreme coordinates (text meshes), inserted at a line start.
fn deepen(text: &str, syntax: Syntax, rng: &mut StdRng) -> String {
    let depth = DEPTHS[rng.random_range(0..DEPTHS.len())];
    let nested = match syntax {
        Syntax::Xml => format!("{}{}\n", "<link>".repeat(depth), "</link>".repeat(depth)),
        Syntax::Toml if rng.random_bool(0.5) => {
            format!("deep = {}1{}\n", "[".repeat(depth), "]".repeat(depth))
        }
        Syntax::Toml => format!("deep = {}1{}\n", "{ a = ".repeat(depth), " }".repeat(depth)),
        Syntax::Yaml => match rng.random_range(0..3) {
            0 => format!("deep: {}1{}\n", "[".repeat(depth), "]".repeat(depth)),
            1 => format!("deep: {}1{}\n", "{a: ".repeat(depth), "}".repeat(depth)),
            _ => ALIAS_BOMB.to_owned(),
        },
        Syntax::Lines => format!("{}\n", "v 1e38 -1e38 3.4e38\n".repeat(depth.min(5_000))),
    };
    let starts: Vec<usize> = std::iter::once(0)
        .chain(text.match_indices('\n').map(|(i, _)| i + 1))
        .collect();
    // After the first line (the XML root or the TOML top level), so that the parser reaches it.
    let at = starts[rng
        .random_range(0..starts.len())
        .max(1)
        .min(starts.len() - 1)];
    format!("{}{nested}{}", &text[..at], &text[at..])
}

/// The text cut at a random character boundary.
fn truncate(text: &str, rng: &mut StdRng) -> String {
    let mut at = rng.random_range(0..=text.len());
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    text[..at].to_owned()
}

/// One ASCII byte replaced by a random printable byte or a structural character.
fn replace_byte(text: &str, rng: &mut StdRng) -> String {
    const STRUCTURE: &[u8] = b"<>/=\"'[]{}#\n.-e";
    let mut bytes = text.as_bytes().to_vec();
    let ascii: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i].is_ascii()).collect();
    if let Some(&i) = ascii.get(rng.random_range(0..ascii.len().max(1))) {
        bytes[i] = if rng.random_bool(0.5) {
            STRUCTURE[rng.random_range(0..STRUCTURE.len())]
        } else {
            rng.random_range(0x20..0x7f)
        };
    }
    String::from_utf8(bytes).unwrap_or_else(|_| text.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn numbers_are_found_with_sign_fraction_and_exponent() {
        let text = r#"<origin xyz="0 -0.5 1.25e-3" rpy="+3 x2 7"/> a-1"#;
        let found: Vec<&str> = numbers(text).iter().map(|&(a, b)| &text[a..b]).collect();
        // `x2` is part of a name; after a letter, `-` is no sign.
        assert_eq!(found, ["0", "-0.5", "1.25e-3", "+3", "7", "1"]);
    }

    #[test]
    fn mutations_change_the_text_and_keep_it_valid_utf8() {
        let mut rng = StdRng::seed_from_u64(7);
        let seed = "[a]\nx = 1.5\ny = \"afma6\"\n";
        let changed = (0..200)
            .filter(|_| mutate(seed, Syntax::Toml, &mut rng) != seed)
            .count();
        assert!(changed > 150, "{changed} of 200 mutations changed the text");
    }
}
