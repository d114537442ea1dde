//! The documentation stands alone: every reference to a `docs/<file>.md` (with or without a
//! `#section` anchor) in the repository's sources and Markdown resolves to a file here and an
//! anchor (`<a id="…">`) in it, every relative link between the Markdown files of `docs/`
//! resolves, and nothing points to the notes outside the repository that the docs replaced.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `.rs`, `.md` and `.toml` files of the repository, without build output and VCS data.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.is_dir() {
            if !(name == "target" || name.starts_with('.')) {
                sources(&path, out);
            }
        } else if [".rs", ".md", ".toml"].iter().any(|e| name.ends_with(e)) {
            out.push(path);
        }
    }
}

/// The anchors `<a id="…">` of a Markdown file.
fn anchors(text: &str) -> BTreeSet<String> {
    text.split("<a id=\"")
        .skip(1)
        .filter_map(|rest| rest.split('"').next().map(str::to_string))
        .collect()
}

fn is_anchor_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '-' || c == '_'
}

/// `file#anchor` (or `file`) resolved against `base`: an error message if it does not resolve.
fn check_target(base: &Path, target: &str, from: &Path) -> Option<String> {
    let (file, anchor) = match target.split_once('#') {
        Some((f, a)) => (f, Some(a)),
        None => (target, None),
    };
    let path = if file.is_empty() {
        from.to_path_buf()
    } else {
        base.join(file)
    };
    let Ok(text) = fs::read_to_string(&path) else {
        return Some(format!(
            "{}: `{target}`: no file {}",
            from.display(),
            path.display()
        ));
    };
    match anchor {
        Some(a) if !anchors(&text).contains(a) => Some(format!(
            "{}: `{target}`: no anchor `{a}` in {}",
            from.display(),
            path.display()
        )),
        _ => None,
    }
}

#[test]
fn references_to_docs_resolve_and_nothing_points_outside() {
    let root = root();
    let mut files = Vec::new();
    sources(&root, &mut files);
    assert!(files.len() > 50, "walked too few files: {}", files.len());
    // Spelled in pieces, so that this file does not match what it forbids.
    let forbidden = [
        concat!("DES", "IGN.md"),
        concat!("../sha", "red"),
        concat!("sha", "red/DES"),
    ];
    let mut errors = Vec::new();
    let mut references = 0;
    for path in &files {
        let text = fs::read_to_string(path).unwrap();
        for f in forbidden {
            if text.contains(f) {
                errors.push(format!("{}: mentions `{f}`", path.display()));
            }
        }
        // `docs/<file>.md` and `docs/<file>.md#<anchor>`, anywhere (doc comments, README, docs).
        for (at, _) in text.match_indices("docs/") {
            let rest = &text[at + 5..];
            let name: String = rest.chars().take_while(|&c| is_anchor_char(c)).collect();
            let after = &rest[name.len()..];
            if name.is_empty() || !after.starts_with(".md") {
                continue;
            }
            let mut target = format!("{name}.md");
            if let Some(anchor) = after[3..].strip_prefix('#') {
                let anchor: String = anchor.chars().take_while(|&c| is_anchor_char(c)).collect();
                target = format!("{target}#{anchor}");
            }
            references += 1;
            errors.extend(check_target(&root.join("docs"), &target, path));
        }
    }
    // Relative Markdown links inside docs: `](<file>.md#<anchor>)`, `](#<anchor>)`,
    // `](../README.md)` (not other text that happens to follow a `]`, e.g. in formulas).
    let docs = root.join("docs");
    for entry in fs::read_dir(&docs).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "md") {
            continue;
        }
        let text = fs::read_to_string(&path).unwrap();
        for (at, _) in text.match_indices("](") {
            let target = text[at + 2..].split(')').next().unwrap();
            if target.contains("://") || !(target.starts_with('#') || target.contains(".md")) {
                continue;
            }
            references += 1;
            errors.extend(check_target(&docs, target, &path));
        }
    }
    assert!(errors.is_empty(), "{}", errors.join("\n"));
    assert!(references > 50, "found only {references} references");
}

/// docs/README.md, the index of the guides, links every Markdown file of docs/.
#[test]
fn the_docs_index_lists_every_guide() {
    let docs = root().join("docs");
    let index = fs::read_to_string(docs.join("README.md")).unwrap();
    for entry in fs::read_dir(&docs).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.ends_with(".md") && name != "README.md" {
            assert!(
                index.contains(&format!("]({name})")),
                "docs/README.md does not link {name}"
            );
        }
    }
}
