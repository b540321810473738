//! The repository stands on its own: no test, script or doc names a path outside it, and every
//! XML, JSON and TOML file it ships parses with a real parser (roxmltree, serde_json, toml), so a
//! file a simulator or a tool must read is not found broken by its first user.

use std::path::{Component, Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The files the repository ships: `git ls-files` where there is a Git checkout, else a walk
/// that skips build outputs.
fn shipped() -> Vec<PathBuf> {
    let git = Command::new("git")
        .args(["ls-files", "-z"])
        .current_dir(root())
        .output();
    if let Ok(o) = git {
        if o.status.success() && !o.stdout.is_empty() {
            return o
                .stdout
                .split(|&b| b == 0)
                .filter(|s| !s.is_empty())
                .map(|s| PathBuf::from(String::from_utf8_lossy(s).into_owned()))
                .filter(|p| root().join(p).is_file())
                .collect();
        }
    }
    let mut out = Vec::new();
    walk(&root(), Path::new(""), &mut out);
    out
}

fn walk(dir: &Path, rel: &Path, out: &mut Vec<PathBuf>) {
    const SKIP: [&str; 6] = [".git", "target", "corpus", "artifacts", ".gl", "out"];
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let rel = rel.join(&name);
        let path = e.path();
        if path.is_dir() {
            if !SKIP.contains(&name.to_string_lossy().as_ref()) {
                walk(&path, &rel, out);
            }
        } else if path.is_file() {
            out.push(rel);
        }
    }
}

fn with_ext<'a>(files: &'a [PathBuf], exts: &[&str]) -> Vec<&'a PathBuf> {
    files
        .iter()
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| exts.contains(&e))
        })
        .collect()
}

/// `base/rel` with `.` and `..` folded lexically; `None` where `..` climbs above `top`.
fn resolve(top: &Path, base: &Path, rel: &str) -> Option<PathBuf> {
    let mut parts: Vec<Component> = base.components().collect();
    let floor = top.components().count();
    for c in Path::new(rel).components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if parts.len() <= floor {
                    return None;
                }
                parts.pop();
            }
            other => parts.push(other),
        }
    }
    Some(parts.iter().collect())
}

/// Every `../…` path written in `text` (after a quote, a bracket, a space or `=`).
fn parent_paths(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while let Some(at) = text[i..].find("../") {
        let s = i + at;
        let starts = s == 0 || b" \t\n\"'`([=<:".contains(&b[s - 1]);
        let mut e = s;
        while e < b.len() && (b[e].is_ascii_alphanumeric() || b"._/-".contains(&b[e])) {
            e += 1;
        }
        if starts {
            out.push(text[s..e].trim_end_matches(['.', '/']).to_string());
        }
        i = e.max(s + 3);
    }
    out
}

/// The directory of the crate a file belongs to (the nearest ancestor with a Cargo.toml).
fn crate_dir(top: &Path, file: &Path) -> PathBuf {
    let mut d = file.parent().map(Path::to_path_buf).unwrap_or_default();
    while d.starts_with(top) && d != top {
        if d.join("Cargo.toml").is_file() {
            return d;
        }
        d.pop();
    }
    top.to_path_buf()
}

/// Whether the relative path `p`, written in `file`, stays in the repository. Rust code is run
/// by cargo from its crate's folder (and joins paths to `CARGO_MANIFEST_DIR`), so there `p` must
/// not climb out of the repository from the crate's folder, or name a file from its own (tests also write made-up paths such as `../x` as hostile
/// input: those stay inside). Docs link from their own folder and scripts run from the root:
/// there `p` must name something that exists in the repository.
fn stays_inside(top: &Path, file: &Path, p: &str) -> bool {
    let here = file.parent().unwrap_or(top);
    if file.extension().is_some_and(|e| e == "rs") {
        // include_str! reads from the file's own folder.
        return resolve(top, &crate_dir(top, file), p).is_some()
            || resolve(top, here, p).is_some_and(|r| r.exists());
    }
    [here, top]
        .iter()
        .any(|b| resolve(top, b, p).is_some_and(|r| r.exists()))
}

#[test]
fn no_file_names_a_path_outside_the_repository() {
    let top = root();
    let files = shipped();
    let text_files = with_ext(
        &files,
        &["rs", "sh", "md", "py", "toml", "wgsl", "xml", "json"],
    );
    assert!(
        text_files.len() > 50,
        "only {} text files found",
        text_files.len()
    );
    let mut bad = Vec::new();
    let mut checked = 0;
    // This file writes the forbidden paths itself, as the check's own test cases.
    for rel in text_files
        .into_iter()
        .filter(|r| !r.ends_with("tests/repository.rs"))
    {
        let path = top.join(rel);
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        for (n, line) in text.lines().enumerate() {
            for word in ["/shared/", "/work/", "/home/", "/root/"] {
                if line.contains(word) && !line.contains("http") {
                    bad.push(format!("{}:{}: names {word}", rel.display(), n + 1));
                }
            }
            for p in parent_paths(line) {
                checked += 1;
                if !stays_inside(&top, &path, &p) {
                    bad.push(format!("{}:{}: {p}", rel.display(), n + 1));
                }
            }
        }
    }
    assert!(checked > 0, "no relative path was checked at all");
    assert!(
        bad.is_empty(),
        "paths outside the repository (or to nothing in it):\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_path_check_catches_a_path_outside() {
    let top = root();
    let tests = top.join("tests");
    assert_eq!(
        parent_paths(r#"join("../beside/data") and [x](../docs/fly.md)."#),
        ["../beside/data", "../docs/fly.md"]
    );
    assert!(resolve(&top, &top, "../beside/data").is_none());
    assert!(resolve(&top, &tests, "../beside/data").is_some_and(|r| !r.exists()));
    assert!(resolve(&top, &tests, "../docs/fly.md").is_some_and(|r| r.exists()));
    assert!(!stays_inside(
        &top,
        &tests.join("fetch.rs"),
        "../beside/data"
    ));
    assert!(!stays_inside(
        &top,
        &top.join("ingest/tests/reference.rs"),
        "../../beside"
    ));
    assert!(stays_inside(
        &top,
        &top.join("ingest/tests/reference.rs"),
        "../data-samples"
    ));
    assert!(!stays_inside(
        &top,
        &top.join("docs/fly.md"),
        "../beside/DESIGN.md"
    ));
    assert!(stays_inside(&top, &top.join("docs/fly.md"), "../README.md"));
}

#[test]
fn every_xml_json_and_toml_file_parses() {
    let top = root();
    let files = shipped();
    let mut counts = [0usize; 3];
    let mut bad = Vec::new();
    for rel in with_ext(&files, &["xml"]) {
        let text = std::fs::read_to_string(top.join(rel)).unwrap_or_default();
        counts[0] += 1;
        if let Err(e) = roxmltree::Document::parse(&text) {
            bad.push(format!("{}: {e}", rel.display()));
        }
    }
    for rel in with_ext(&files, &["json"]) {
        let bytes = std::fs::read(top.join(rel)).unwrap_or_default();
        counts[1] += 1;
        if let Err(e) = serde_json::from_slice::<serde_json::Value>(&bytes) {
            bad.push(format!("{}: {e}", rel.display()));
        }
    }
    for rel in with_ext(&files, &["toml", "lock"]) {
        let text = std::fs::read_to_string(top.join(rel)).unwrap_or_default();
        counts[2] += 1;
        if let Err(e) = text.parse::<toml::Table>() {
            bad.push(format!("{}: {e}", rel.display()));
        }
    }
    assert!(
        counts.iter().all(|&c| c > 0),
        "found (xml, json, toml) = {counts:?}"
    );
    assert!(
        bad.is_empty(),
        "files that do not parse:\n{}",
        bad.join("\n")
    );
}

/// The XML parser is strict where FlightGear's (expat) is: two dashes inside a comment are not
/// XML, the fault that once kept FlightGear from reading the protocol file.
#[test]
fn the_xml_parser_refuses_what_flightgear_refuses() {
    assert!(
        roxmltree::Document::parse("<PropertyList><!-- fgfs --generic --></PropertyList>").is_err()
    );
    assert!(
        roxmltree::Document::parse("<PropertyList><!-- fgfs generic --></PropertyList>").is_ok()
    );
}

/// The protocol file is what FlightGear's generic protocol needs: a PropertyList with an output
/// section of chunks, each naming a property node and a type.
#[test]
fn the_flightgear_protocol_file_is_a_generic_output_protocol() {
    let text = std::fs::read_to_string(root().join("docs/flightgear/stratus.xml"))
        .expect("docs/flightgear/stratus.xml");
    let doc = roxmltree::Document::parse(&text).expect("stratus.xml is XML");
    let rootel = doc.root_element();
    assert_eq!(rootel.tag_name().name(), "PropertyList");
    let output = rootel
        .descendants()
        .find(|n| n.has_tag_name("generic"))
        .and_then(|g| g.children().find(|n| n.has_tag_name("output")))
        .expect("generic/output");
    let chunks: Vec<_> = output
        .children()
        .filter(|n| n.has_tag_name("chunk"))
        .collect();
    assert!(chunks.len() >= 6, "{} chunks", chunks.len());
    for c in chunks {
        let node = c.children().find(|n| n.has_tag_name("node"));
        assert!(
            node.and_then(|n| n.text())
                .is_some_and(|t| t.trim().starts_with('/')),
            "a chunk without a property node"
        );
        assert!(
            c.children().any(|n| n.has_tag_name("type")),
            "a chunk without a type"
        );
    }
}
