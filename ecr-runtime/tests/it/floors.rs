//! The floors of the runtime (`docs/architecture.md`, "Floors"): every module imports only
//! modules on lower floors (or its own), so that no import runs back up and no two modules
//! import each other.
//!
//! Read from the sources: every `crate::MODULE` in code (comments and doc comments are not
//! imports) must name a module below the file's own. `crate::Error` and `crate::Result` are
//! the crate root's re-exports: below the root, modules import `crate::error`.

use std::path::Path;

/// Bottom up: a module may import the modules of the floors before its own.
const FLOORS: &[&[&str]] = &[
    &["test_rng"],
    &["error", "concurrent", "double_double"],
    &["storage", "tables"],
    &["phi"],
    &["operator", "precision"],
    &["system"],
    &["stepper"],
    &["second_order"],
    &["integrate"],
    &["solve"],
    &["ensemble"],
    &["lib"],
];

fn floor(module: &str) -> Option<usize> {
    FLOORS.iter().position(|f| f.contains(&module))
}

/// The module a source file belongs to: `stepper/iteration.rs` → `stepper`.
fn module_of(rel: &Path) -> String {
    let first = rel
        .components()
        .next()
        .unwrap()
        .as_os_str()
        .to_str()
        .unwrap();
    first.trim_end_matches(".rs").to_string()
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let path = e.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push(path);
        }
    }
}

/// The modules named `crate::NAME` (or `crate::{NAME, …}`) in a line of code.
fn crate_paths(line: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("crate::") {
        let after = &rest[at + "crate::".len()..];
        let preceded = rest[..at].chars().last();
        if !preceded.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            if let Some(group) = after.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                for item in group[..end].split(',') {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    names.push(name);
                }
            } else {
                names.push(
                    after
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect(),
                );
            }
        }
        rest = after;
    }
    names
}

#[test]
fn no_import_runs_back_up_a_floor() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    files.sort();
    let mut wrong = Vec::new();
    for path in &files {
        let rel = path.strip_prefix(&src).unwrap();
        let module = module_of(rel);
        let own = floor(&module).unwrap_or_else(|| panic!("{}: not on a floor", rel.display()));
        let text = std::fs::read_to_string(path).unwrap();
        for (n, line) in text.lines().enumerate() {
            let code = line.trim_start();
            if code.starts_with("//") {
                continue;
            }
            let code = code.split(" //").next().unwrap();
            for name in crate_paths(code) {
                // `crate::Error`, `crate::Result`, `crate::ecr_method`: the crate root's.
                let target = if floor(&name).is_some() {
                    name.clone()
                } else {
                    "lib".to_string()
                };
                let to = floor(&target).unwrap();
                if target != module && to >= own {
                    wrong.push(format!(
                        "{}:{}: `{module}` (floor {}) imports `crate::{name}` (floor {})",
                        rel.display(),
                        n + 1,
                        own + 1,
                        to + 1
                    ));
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports that run back up a floor:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn every_module_is_on_a_floor() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    for line in lib.lines() {
        let line = line.trim();
        let decl = line
            .strip_prefix("pub mod ")
            .or_else(|| line.strip_prefix("mod "));
        if let Some(name) = decl.and_then(|d| d.strip_suffix(';')) {
            assert!(floor(name).is_some(), "module {name} is on no floor");
        }
    }
}
