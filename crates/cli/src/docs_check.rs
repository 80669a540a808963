//! The manual checked against the code: every relative link in README.md and docs/ resolves (to a file,
//! and to a heading where it names one), and every `pganeus` command line in their `sh` blocks parses with
//! this binary's arguments.

use crate::Cli;
use clap::Parser;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// README.md and every markdown file under docs/.
fn pages(root: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|e| e == "md") {
                out.push(p);
            }
        }
    }
    let mut out = vec![root.join("README.md")];
    walk(&root.join("docs"), &mut out);
    out
}

/// A heading's anchor as GitHub and mdBook make it: lower case, spaces to `-`, other punctuation dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a page's headings (outside code blocks).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

/// The targets of a page's markdown links and images, outside code (`[text](target)`).
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Inline code spans hold no links.
        let prose: String = line.split('`').step_by(2).collect::<Vec<_>>().join(" ");
        let mut rest = prose.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let end = after.find(')').unwrap_or(after.len());
            out.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    out
}

#[test]
fn every_relative_link_in_the_manual_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in pages(&root) {
        let text = std::fs::read_to_string(&page).unwrap();
        for target in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            checked += 1;
            let (file, anchor) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let path = if file.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(file)
            };
            if !path.exists() {
                broken.push(format!("{}: {target} (no such file)", page.display()));
                continue;
            }
            if let Some(a) = anchor.filter(|_| path.extension().is_some_and(|e| e == "md")) {
                if !anchors(&std::fs::read_to_string(&path).unwrap()).contains(a) {
                    broken.push(format!("{}: {target} (no such heading)", page.display()));
                }
            }
        }
    }
    assert!(
        broken.is_empty(),
        "{} broken links:\n{}",
        broken.len(),
        broken.join("\n")
    );
    assert!(checked > 100, "only {checked} links found");
}

/// The `pganeus` invocations in a page's `sh` blocks, each as its words (a line may chain commands with
/// `&&` and redirect or pipe the output; those parts are not `pganeus`'s).
fn command_lines(text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            in_sh = !in_sh && (t == "```sh" || t == "```bash" || t == "```shell");
            continue;
        }
        if !in_sh || t.starts_with('#') {
            continue;
        }
        for part in t.split("&&") {
            let part = part.split(" > ").next().unwrap_or("");
            let part = part.split(" | ").next().unwrap_or("");
            let part = part.split(" #").next().unwrap_or("").trim();
            let words = part
                .strip_prefix("cargo run --release -p pganeus -- ")
                .or_else(|| part.strip_prefix("./target/release/pganeus "))
                .or_else(|| part.strip_prefix("pganeus "));
            if let Some(words) = words {
                let mut argv = vec!["pganeus".to_string()];
                argv.extend(
                    words
                        .split_whitespace()
                        .map(|w| w.trim_matches(|c| c == '"' || c == '\'').to_string()),
                );
                out.push(argv);
            }
        }
    }
    out
}

#[test]
fn every_command_line_in_the_manual_parses() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut failures = Vec::new();
    let mut checked = 0;
    for page in pages(&root) {
        let text = std::fs::read_to_string(&page).unwrap();
        for argv in command_lines(&text) {
            checked += 1;
            if let Err(e) = Cli::try_parse_from(&argv) {
                let first = e.to_string().lines().next().unwrap_or("").to_string();
                failures.push(format!("{}: `{}`: {first}", page.display(), argv.join(" ")));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} command lines do not parse:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(checked > 50, "only {checked} command lines found");
}

#[test]
fn the_link_and_command_readers_find_what_is_there() {
    let page = "# A title\n## The scene's planes\nSee [bake](commands/bake.md#flags), `[not](a link)`.\n\
                ```sh\npganeus bake runs/scene --out s.sdf # comment\npganeus synth --print-preset tabletop > t.toml && pganeus synth --scene t.toml --out d\n```\n";
    assert_eq!(links(page), ["commands/bake.md#flags"]);
    assert!(anchors(page).contains("the-scenes-planes"));
    let lines = command_lines(page);
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0], ["pganeus", "bake", "runs/scene", "--out", "s.sdf"]);
    assert_eq!(lines[2].last().map(String::as_str), Some("d"));
}
