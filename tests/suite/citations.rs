//! Every citation in the code, the docs and the scenario files resolves in the crate's theory reference
//! (`docs/theory.md`, the module `servostack::theory`), every link into it lands on an anchor, and nothing sends the
//! reader to a document outside the repository.
//!
//! Citations take three forms: the crate's equations `[M14]` (written `\[M14\]` in doc comments), the paper's
//! equations `(F16)`, and the decisions `D7`. A range such as `\[M16\]–\[M21\]` or `D3–D7` cites every number in it.
//! The theory reference defines a number by an HTML anchor, `<a id="m14">`, `<a id="f16">`, `<a id="d7">`, which is
//! also what a link `crate::theory#m14` in the built docs points to.

use std::collections::BTreeSet;
use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};

const THEORY: &str = "docs/theory.md";

/// This file cites undefined numbers and names outside documents on purpose, in its samples.
const THIS_FILE: &str = "tests/suite/citations.rs";

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    /// `[Mk]`: the crate's equations.
    Equation,
    /// `(Fk)`: the paper's equations.
    Paper,
    /// `Dk`: the crate's decisions.
    Decision,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Citation {
    kind: Kind,
    number: u32,
}

impl fmt::Display for Citation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            Kind::Equation => write!(f, "[M{}]", self.number),
            Kind::Paper => write!(f, "(F{})", self.number),
            Kind::Decision => write!(f, "D{}", self.number),
        }
    }
}

/// A citation found in a text, with the byte range it covers.
struct Found {
    citation: Citation,
    start: usize,
    end: usize,
}

/// The digits of `text` from `at`, as a number and the index after them.
fn number_at(text: &str, at: usize) -> Option<(u32, usize)> {
    let digits = text[at..].bytes().take_while(u8::is_ascii_digit).count();
    let end = at + digits;
    text.get(at..end)?.parse().ok().map(|n| (n, end))
}

fn is_word_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

/// The citation that starts at byte `at` of `text`, if any.
fn citation_at(text: &str, at: usize) -> Option<Found> {
    let rest = &text[at..];
    let found = |kind, number, end| {
        Some(Found {
            citation: Citation { kind, number },
            start: at,
            end,
        })
    };
    if let Some(open) = ["\\[M", "[M"].iter().find(|open| rest.starts_with(*open)) {
        let (number, end) = number_at(text, at + open.len())?;
        let close = ["\\]", "]"]
            .iter()
            .find(|close| text[end..].starts_with(*close))?;
        return found(Kind::Equation, number, end + close.len());
    }
    if rest.starts_with("(F") {
        let (number, end) = number_at(text, at + 2)?;
        return text[end..]
            .starts_with(')')
            .then_some(())
            .and_then(|()| found(Kind::Paper, number, end + 1));
    }
    if rest.starts_with('D') && (at == 0 || !is_word_byte(text.as_bytes()[at - 1])) {
        let (number, end) = number_at(text, at + 1)?;
        let ends_word = text.as_bytes().get(end).is_none_or(|&b| !is_word_byte(b));
        return ends_word
            .then_some(())
            .and_then(|()| found(Kind::Decision, number, end));
    }
    None
}

/// Whether the text between two citations makes them a range: a dash, between plain citations or between links
/// (`[\[M16\]](crate::theory#m16)–[\[M21\]](crate::theory#m21)`).
fn is_range_dash(between: &str) -> bool {
    let after_link = between
        .strip_prefix("](")
        .and_then(|target| target.split_once(')'))
        .map_or(between, |(_, after)| after);
    let dash = after_link.strip_suffix('[').unwrap_or(after_link).trim();
    dash == "–" || dash == "-"
}

/// Every number `text` cites, ranges expanded: `\[M16\]–\[M21\]` cites M16 to M21, `D3–D7` cites D3 to D7.
fn citations(text: &str) -> BTreeSet<Citation> {
    let mut found: Vec<Found> = Vec::new();
    let mut at = 0;
    while at < text.len() {
        match citation_at(text, at) {
            Some(citation) => {
                at = citation.end;
                found.push(citation);
            }
            None => at += text[at..].chars().next().map_or(1, char::len_utf8),
        }
    }
    let mut cited: BTreeSet<Citation> = found.iter().map(|f| f.citation).collect();
    for pair in found.windows(2) {
        let (first, last) = (&pair[0], &pair[1]);
        if first.citation.kind == last.citation.kind && is_range_dash(&text[first.end..last.start])
        {
            cited.extend(
                (first.citation.number..=last.citation.number).map(|number| Citation {
                    kind: first.citation.kind,
                    number,
                }),
            );
        }
    }
    cited
}

/// The numbers a theory text defines: one per anchor `<a id="m14"></a>`.
fn defined(theory: &str) -> BTreeSet<Citation> {
    anchor_ids(theory)
        .iter()
        .filter_map(|id| {
            let kind = match id.chars().next()? {
                'm' => Kind::Equation,
                'f' => Kind::Paper,
                'd' => Kind::Decision,
                _ => return None,
            };
            Some(Citation {
                kind,
                number: id[1..].parse().ok()?,
            })
        })
        .collect()
}

fn repository() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn collect_files(dir: &Path, extensions: &[&str], files: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_files(&path, extensions, files);
        } else if path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| extensions.contains(&e))
        {
            files.push(path);
        }
    }
}

/// The files a reader of the code or the docs reads, relative to the repository, with their text.
fn scanned_files() -> Vec<(String, String)> {
    let root = repository();
    let mut files = vec![root.join("README.md")];
    for dir in ["src", "examples", "benches", "tests"] {
        collect_files(&root.join(dir), &["rs"], &mut files);
    }
    collect_files(&root.join("docs"), &["md"], &mut files);
    collect_files(&root.join("assets/scenarios"), &["toml"], &mut files);
    collect_files(&root.join("assets/urdf"), &["urdf"], &mut files);
    collect_files(&root.join("tests/data"), &["toml", "urdf"], &mut files);
    files.sort();
    files
        .into_iter()
        .map(|path| {
            let text =
                fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let relative = path
                .strip_prefix(&root)
                .unwrap_or(&path)
                .to_string_lossy()
                .replace('\\', "/");
            (relative, text)
        })
        .filter(|(relative, _)| relative != THIS_FILE)
        .collect()
}

#[test]
fn scanner_finds_each_form_and_expands_ranges() {
    let sample = "Recursive update (MATH \\[M8\\], (F8)); law [M18] (F19), D1; criteria \\[M23\\]–\\[M25\\], D3–D5, \
                  (F37)-(F38), [D9](crate::theory#d9)–[D11](crate::theory#d11). Not citations: 3D1, DD2, D1x, [M], \
                  (F), Dyn.";
    let expected: BTreeSet<Citation> = [
        (Kind::Equation, [8, 18, 23, 24, 25].as_slice()),
        (Kind::Paper, &[8, 19, 37, 38]),
        (Kind::Decision, &[1, 3, 4, 5, 9, 10, 11]),
    ]
    .into_iter()
    .flat_map(|(kind, numbers)| numbers.iter().map(move |&number| Citation { kind, number }))
    .collect();
    assert_eq!(citations(sample), expected);
}

#[test]
fn an_undefined_number_is_flagged() {
    let theory = "<a id=\"m8\"></a>**\\[M8\\]** … <a id=\"d1\"></a>D1 … <a id=\"s2\"></a>§2";
    let definitions = defined(theory);
    let undefined: Vec<String> = citations("as in \\[M8\\] and \\[M9\\], D1 and D2")
        .difference(&definitions)
        .map(ToString::to_string)
        .collect();
    assert_eq!(undefined, ["[M9]", "D2"]);
}

#[test]
fn every_citation_is_defined_in_the_theory_reference() {
    let theory_path = repository().join(THEORY);
    let theory = fs::read_to_string(&theory_path)
        .unwrap_or_else(|e| panic!("{}: {e}", theory_path.display()));
    let definitions = defined(&theory);
    assert!(
        definitions.len() > 90,
        "the anchors of {THEORY} were not found"
    );
    let mut undefined = Vec::new();
    for (file, text) in scanned_files() {
        for citation in citations(&text).difference(&definitions) {
            undefined.push(format!("{file}: {citation}"));
        }
    }
    assert!(
        undefined.is_empty(),
        "cited but not defined by an anchor <a id=\"…\"> in {THEORY}:\n{}",
        undefined.join("\n")
    );
}

/// The anchors that links to `crate::theory…#id` point to, as `(document, id)`: `docs/theory.md` for
/// `crate::theory#id`, `docs/peer_scene.md` for `crate::theory::peer_scene#id`.
fn theory_links(text: &str) -> Vec<(&'static str, String)> {
    text.match_indices("crate::theory")
        .filter_map(|(at, prefix)| {
            let rest = &text[at + prefix.len()..];
            let (document, rest) = match rest.strip_prefix("::peer_scene") {
                Some(rest) => ("docs/peer_scene.md", rest),
                None => (THEORY, rest),
            };
            let id: String = rest
                .strip_prefix('#')?
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            Some((document, id))
        })
        .collect()
}

/// The ids of the HTML anchors `<a id="…">` of a document.
fn anchor_ids(document: &str) -> BTreeSet<String> {
    document
        .split("<a id=\"")
        .skip(1)
        .filter_map(|rest| rest.split_once('"').map(|(id, _)| id.to_owned()))
        .collect()
}

#[test]
fn link_scanner_names_the_document_and_the_anchor() {
    let links = theory_links(
        "[\\[M8\\]](crate::theory#m8), [A](crate::theory::peer_scene#variant-a), [`crate::theory`]",
    );
    assert_eq!(
        links,
        [
            (THEORY, "m8".to_owned()),
            ("docs/peer_scene.md", "variant-a".to_owned())
        ]
    );
}

#[test]
fn every_link_into_the_theory_lands_on_an_anchor() {
    let anchors = |document: &str| {
        let path = repository().join(document);
        anchor_ids(&fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
    };
    let (theory, peer_scene) = (anchors(THEORY), anchors("docs/peer_scene.md"));
    let mut dangling = Vec::new();
    for (file, text) in scanned_files() {
        for (document, id) in theory_links(&text) {
            let ids = if document == THEORY {
                &theory
            } else {
                &peer_scene
            };
            if !ids.contains(&id) {
                dangling.push(format!("{file}: #{id} is not an anchor of {document}"));
            }
        }
    }
    assert!(dangling.is_empty(), "{}", dangling.join("\n"));
}

/// Names of documents that are not in the repository: a reader who meets one has nothing to open.
const OUTSIDE_DOCUMENTS: [&str; 4] = ["MATH.md", "PEER_SCENE", "DESIGN.md", "DESIGN principle"];

/// The citation wording of the internal notes ("MATH §6", "MATH \[M22\]", "MATH D10") instead of a reference to
/// `crate::theory`.
const NOTE_WORDING: [&str; 4] = ["MATH §", "MATH \\[", "MATH [", "MATH D"];

/// Files that still use [`NOTE_WORDING`] because they are being rewritten on another branch (the stack controller
/// redesign); each entry goes once its file refers to `crate::theory` instead.
const AWAITING_REWORDING: [&str; 0] = [];

#[test]
fn no_file_sends_the_reader_to_a_document_outside_the_repository() {
    let mut offending = Vec::new();
    let mut reworded = Vec::new();
    for (file, text) in scanned_files() {
        for (number, line) in text.lines().enumerate() {
            if let Some(name) = OUTSIDE_DOCUMENTS.iter().find(|name| line.contains(*name)) {
                offending.push(format!("{file}:{}: `{name}`", number + 1));
            }
        }
        let uses_note_wording = NOTE_WORDING.iter().any(|wording| text.contains(wording));
        if AWAITING_REWORDING.contains(&file.as_str()) {
            if !uses_note_wording {
                reworded.push(file);
            }
        } else if uses_note_wording {
            offending.push(format!(
                "{file}: cites `MATH …`; cite the theory reference (crate::theory)"
            ));
        }
    }
    assert!(offending.is_empty(), "{}", offending.join("\n"));
    assert!(
        reworded.is_empty(),
        "reworded, remove from AWAITING_REWORDING: {}",
        reworded.join(", ")
    );
}
