//! No module of a crate in the workspace reaches, through its imports, back to itself: the modules of each
//! crate form a graph without cycles (issue 66: the CLI's command files imported each other in two cycles).
//! A module is a file or folder directly under `src/` (a folder's files are one module), and, one level
//! down, each file of a folder (`cli/src/commands/fit.rs`); an edge is a `crate::NAME` path to another
//! top-level module, or a `super::NAME` path from a file to a sibling. Comments and `#[cfg(test)]` modules
//! do not count.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`, with its path relative to `dir`.
fn rust_files(dir: &Path, rel: &Path, out: &mut Vec<(PathBuf, PathBuf)>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        let name = rel.join(p.file_name().unwrap());
        if p.is_dir() {
            rust_files(&p, &name, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push((p, name));
        }
    }
}

/// The code of a file without its comment lines and its test module.
fn code(text: &str) -> String {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The names following `prefix` in `text` (`crate::` → the module named after it).
fn paths_after<'a>(text: &'a str, prefix: &str) -> Vec<&'a str> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find(prefix) {
        let before = rest[..i].chars().last();
        let after = &rest[i + prefix.len()..];
        let end = after
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        if !before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            out.push(&after[..end]);
        }
        rest = &after[end..];
    }
    out
}

/// The module graph of the crate whose sources are in `src`.
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(src, Path::new(""), &mut files);
    let top = |rel: &Path| -> String {
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .into_owned();
        first.trim_end_matches(".rs").to_string()
    };
    let modules: BTreeSet<String> = files.iter().map(|(_, r)| top(r)).collect();
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (path, rel) in &files {
        let text = code(&std::fs::read_to_string(path).unwrap());
        let depth = rel.components().count() - 1;
        let own = top(rel);
        let mut node = own.clone();
        if depth == 1 && rel.file_name().unwrap() != "mod.rs" {
            node = format!("{own}::{}", rel.file_stem().unwrap().to_string_lossy());
        }
        let edges = g.entry(node.clone()).or_default();
        for name in paths_after(&text, "crate::") {
            if modules.contains(name) && *name != own {
                edges.insert(name.to_string());
            }
        }
        for name in paths_after(&text, "super::") {
            match depth {
                0 if modules.contains(name) && *name != own => {
                    edges.insert(name.to_string());
                }
                1 if src.join(&own).join(format!("{name}.rs")).exists() => {
                    let sibling = format!("{own}::{name}");
                    if sibling != node {
                        edges.insert(sibling);
                    }
                }
                _ => {}
            }
        }
    }
    g
}

/// A cycle of `g` through `from`, if there is one.
fn cycle(g: &BTreeMap<String, BTreeSet<String>>, from: &str) -> Option<Vec<String>> {
    fn walk(g: &BTreeMap<String, BTreeSet<String>>, start: &str, at: &str, path: &mut Vec<String>) -> bool {
        for next in g.get(at).into_iter().flatten() {
            if next == start {
                return true;
            }
            if !path.contains(next) {
                path.push(next.clone());
                if walk(g, start, next, path) {
                    return true;
                }
                path.pop();
            }
        }
        false
    }
    let mut path = vec![from.to_string()];
    walk(g, from, from, &mut path).then_some(path)
}

#[test]
fn no_crate_has_an_import_cycle() {
    let crates = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut cycles = Vec::new();
    let mut modules = 0;
    let mut names: Vec<PathBuf> = std::fs::read_dir(&crates).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    for krate in names {
        let src = krate.join("src");
        if !src.is_dir() {
            continue;
        }
        let g = graph(&src);
        modules += g.len();
        for m in g.keys() {
            if let Some(c) = cycle(&g, m) {
                cycles.push(format!("{}: {} -> {m}", krate.display(), c.join(" -> ")));
            }
        }
    }
    assert!(modules > 100, "only {modules} modules read");
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

#[test]
fn a_cycle_between_two_files_is_found() {
    let d = testkit::scratch_dir("cli", "import_cycles");
    let src = d.join("src");
    std::fs::create_dir_all(src.join("commands")).unwrap();
    std::fs::write(src.join("lib.rs"), "mod a;\nmod b;\n").unwrap();
    std::fs::write(src.join("a.rs"), "use crate::b::f;\n// crate::c in a comment\n").unwrap();
    std::fs::write(
        src.join("b.rs"),
        "pub fn f() { super::a::g() }\n#[cfg(test)]\nmod tests { use crate::c; }\n",
    )
    .unwrap();
    std::fs::write(src.join("c.rs"), "").unwrap();
    std::fs::write(src.join("commands/fit.rs"), "use super::bodies::run;\n").unwrap();
    std::fs::write(src.join("commands/bodies.rs"), "use super::fit::Args;\n").unwrap();
    let g = graph(&src);
    assert_eq!(g["a"], BTreeSet::from(["b".to_string()]));
    assert_eq!(g["b"], BTreeSet::from(["a".to_string()]));
    assert!(cycle(&g, "a").is_some());
    assert!(cycle(&g, "commands::fit").is_some());
    assert!(cycle(&g, "c").is_none());
    let _ = std::fs::remove_dir_all(&d);
}
