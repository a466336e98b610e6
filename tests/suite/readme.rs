//! The README is a manual that renders on any Markdown viewer: its Rust code is compiled and run as doc tests (the
//! crate's front page in `src/lib.rs`, or a guide under `docs/guide/`) without rustdoc's hidden `# ` lines, its first
//! block holds the two commands CI and users run first, and it stays short, the study's history left to `docs/`.

use std::fs;
use std::path::PathBuf;

fn read(relative: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(relative);
    fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The fenced code blocks of a Markdown text whose info string starts with `lang`, fences included.
fn blocks<'a>(text: &'a str, lang: &str) -> Vec<&'a str> {
    let mut found = Vec::new();
    let mut start = None;
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let fence = line.trim_end();
        match start {
            None if fence.starts_with("```") && fence[3..].starts_with(lang) => {
                start = Some(offset)
            }
            Some(begin) if fence == "```" => {
                found.push(&text[begin..offset + fence.len()]);
                start = None;
            }
            _ => {}
        }
        offset += line.len();
    }
    found
}

/// The crate-level doc text of `src/lib.rs` (its `//!` lines without the prefix).
fn front_page() -> String {
    read("src/lib.rs")
        .lines()
        .filter_map(|line| line.strip_prefix("//!"))
        .map(|line| line.strip_prefix(' ').unwrap_or(line))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn every_rust_block_of_the_readme_is_a_doc_test_without_hidden_lines() {
    let readme = read("README.md");
    let rust = blocks(&readme, "rust");
    assert!(rust.len() >= 3, "the README's Rust blocks were not found");
    let mut compiled = vec![front_page()];
    for guide in ["your_robot", "camera_loop", "reading_results", "tuning"] {
        compiled.push(read(&format!("docs/guide/{guide}.md")));
    }
    for block in rust {
        let first = block.lines().nth(1).unwrap_or("");
        assert!(
            compiled.iter().any(|text| text.contains(block)),
            "the README's block starting `{first}` is not, as it stands, a doc test of src/lib.rs or docs/guide/"
        );
        assert!(
            !block.lines().any(|l| l.trim() == "#" || l.trim_start().starts_with("# ")),
            "the README's block starting `{first}` has a hidden `# ` line, which a Markdown viewer shows"
        );
    }
    assert!(
        front_page().contains(blocks(&readme, "rust")[0]),
        "the README's first loop is the front page's quick start"
    );
}

#[test]
fn the_readmes_scenario_section_is_the_guides() {
    let readme = read("README.md");
    let guide = read("docs/guide/your_robot.md");
    for block in blocks(&readme, "toml")
        .iter()
        .filter(|b| b.contains("[robot]"))
    {
        let body = block.trim_end_matches("```");
        assert!(
            guide.contains(body),
            "the README's [robot] section differs from the guide's:\n{block}"
        );
    }
}

#[test]
fn the_readme_opens_with_the_example_and_the_test_command() {
    let readme = read("README.md");
    let first = blocks(&readme, "sh")[0];
    assert!(
        readme.find(first) < readme.find("## "),
        "the commands come first"
    );
    assert!(first.contains("cargo run --release --example paper_experiment"));
    assert!(
        first
            .lines()
            .any(|l| l.starts_with("cargo test --all-features ")),
        "CI runs the README's test command"
    );
}

#[test]
fn the_readme_is_a_manual_not_a_notebook() {
    let readme = read("README.md");
    assert!(
        readme.len() <= 15 * 1024,
        "README.md is {} bytes; the study and the logs go to docs/",
        readme.len()
    );
    for word in ["seed", "not kept", "before D", "slow mode"] {
        assert!(
            !readme.contains(word),
            "README.md says `{word}`: history goes to docs/ and the CHANGELOG"
        );
    }
    let words = readme.split(|c: char| !c.is_ascii_alphanumeric() && c != '-');
    for word in words {
        let hash = word.len() >= 7
            && word.chars().all(|c| c.is_ascii_hexdigit())
            && word.chars().any(|c| c.is_ascii_alphabetic());
        let date = word.len() == 10
            && word.as_bytes()[4] == b'-'
            && word.as_bytes()[7] == b'-'
            && word[..4].chars().all(|c| c.is_ascii_digit());
        assert!(
            !hash && !date,
            "README.md names `{word}`: commit hashes and dated runs go to docs/"
        );
    }
}
