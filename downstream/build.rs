//! Writes the Rust blocks of the repository's README.md and docs/*.md, verbatim, and the
//! examples the README names into modules of this crate's tests (`tests/from_the_docs.rs`
//! includes them): each must compile as a user copies it into a crate that depends on `ecr` as
//! the README says (`default-features = false`), and its `main` must succeed.
//!
//! A block must be a whole program (with `fn main`) and must not use rustdoc's hidden lines
//! (`# ...`): a user copying it gets those lines too.

use std::fmt::Write as _;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

fn main() -> io::Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let mut documents = vec![root.join("README.md")];
    let mut docs: Vec<PathBuf> = fs::read_dir(root.join("docs"))?
        .map(|e| e.map(|e| e.path()))
        .collect::<io::Result<_>>()?;
    docs.retain(|p| p.extension().is_some_and(|x| x == "md"));
    docs.sort();
    documents.extend(docs);

    let mut modules = String::new();
    let mut examples = Vec::new();
    for document in &documents {
        println!("cargo:rerun-if-changed={}", document.display());
        let text = fs::read_to_string(document)?;
        let stem = document
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("doc")
            .to_lowercase()
            .replace(['-', '.'], "_");
        let name = document.strip_prefix(&root).unwrap_or(document).display();
        for (line, block) in rust_blocks(&text) {
            if let Some(hidden) = block.lines().find(|l| l.trim_start().starts_with("# ")) {
                panic!(
                    "{name}:{line}: a Rust block with a rustdoc hidden line ({hidden:?}): a user copies it as it is"
                );
            }
            if !block.contains("fn main(") {
                panic!(
                    "{name}:{line}: a Rust block without `fn main`: a user cannot run it as it is"
                );
            }
            let module = format!("{stem}_line_{line}");
            let doc = format!("{name}, the Rust block at line {line}");
            module_with_test(&mut modules, &out, &module, &doc, &block)?;
        }
        if document.ends_with("README.md") {
            examples.extend(example_names(&text));
        }
    }
    examples.sort();
    examples.dedup();
    for example in examples {
        let file = root.join("examples").join(format!("{example}.rs"));
        println!("cargo:rerun-if-changed={}", file.display());
        let source = fs::read_to_string(&file)?;
        let doc = format!("examples/{example}.rs, which the README names");
        module_with_test(
            &mut modules,
            &out,
            &format!("example_{example}"),
            &doc,
            &source,
        )?;
    }
    fs::write(out.join("from_the_docs.rs"), modules)
}

/// Declares `module` in `modules`: a copy of `source` in `out` with a test appended that runs
/// its `main` (which stays private, as the user wrote it).
fn module_with_test(
    modules: &mut String,
    out: &Path,
    module: &str,
    doc: &str,
    source: &str,
) -> io::Result<()> {
    let file = out.join(format!("{module}.rs"));
    let test = "\n#[test]\n#[allow(clippy::unit_arg)]\nfn main_succeeds() {\n    crate::Outcome::check(main());\n}\n";
    fs::write(&file, format!("{source}{test}"))?;
    let path = file.display().to_string();
    writeln!(
        modules,
        "/// {doc}.\n#[path = {path:?}]\n#[allow(dead_code)]\nmod {module};"
    )
    .expect("writing to a String");
    Ok(())
}

/// The ```rust blocks of a Markdown text: (line of the opening fence, content).
fn rust_blocks(text: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        match &mut current {
            None => {
                let fence = line.trim_start();
                if let Some(info) = fence.strip_prefix("```") {
                    let lang = info.split(',').next().unwrap_or("").trim();
                    if lang == "rust" {
                        current = Some((i + 1, String::new()));
                    }
                }
            }
            Some((_, body)) => {
                if line.trim_start().starts_with("```") {
                    blocks.push(current.take().unwrap());
                } else {
                    body.push_str(line);
                    body.push('\n');
                }
            }
        }
    }
    blocks
}

/// The names of `examples/NAME.rs` that a text mentions.
fn example_names(text: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("examples/") {
        let tail = &rest[at + "examples/".len()..];
        let name: String = tail
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        if !name.is_empty() && tail[name.len()..].starts_with(".rs") {
            names.push(name);
        }
        rest = tail;
    }
    names
}
