//! The house's rules, read from the source (issue 29): no import circle among a crate's
//! top-level modules, no module importing a layer above it in the layering its crate root
//! writes down (`# Layers`), no Rust function over 100 lines outside tests and no WGSL function
//! over 150, unless a `Stays whole:` line in its doc says why.
//!
//! The reader is a small lexer, not a compiler: it blanks comments and string literals (keeping
//! line breaks), drops `#[cfg(test)]` items and test-only files, and takes every `crate::NAME`
//! path (including the names inside `use crate::{a, b::c}` groups) and every `super::` chain
//! that reaches the crate root as an import of `NAME`. A folder module counts as one.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const RUST_LIMIT: usize = 100;
const WGSL_LIMIT: usize = 150;
const EXEMPT: &str = "Stays whole:";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The crate roots whose modules are checked: ingest's library, the root library, the binary.
fn crate_roots() -> Vec<PathBuf> {
    let r = root();
    vec![
        r.join("ingest/src/lib.rs"),
        r.join("src/lib.rs"),
        r.join("src/main.rs"),
    ]
}

// ---------------------------------------------------------------------------------------------
// Lexing

/// `src` with comments and the contents of string and char literals replaced by spaces; line
/// breaks kept, so line numbers stay true.
fn blank(src: &str) -> String {
    let b: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    let keep = |c: char| if c == '\n' { '\n' } else { ' ' };
    while i < b.len() {
        let c = b[i];
        let next = b.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < b.len() && b[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(keep(b[i]));
                    i += 1;
                }
            }
        } else if (c == 'r' || c == 'b')
            && !b
                .get(i.wrapping_sub(1))
                .is_some_and(|p| p.is_alphanumeric() || *p == '_')
            && raw_string_start(&b, i).is_some()
        {
            let (hashes, body) = raw_string_start(&b, i).unwrap_or((0, i));
            for _ in i..body {
                out.push(' ');
            }
            i = body;
            // Find `"` followed by `hashes` hashes.
            while i < b.len() {
                if b[i] == '"' && (0..hashes).all(|k| b.get(i + 1 + k) == Some(&'#')) {
                    for _ in 0..=hashes {
                        out.push(' ');
                    }
                    i += 1 + hashes;
                    break;
                }
                out.push(keep(b[i]));
                i += 1;
            }
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < b.len() {
                    out.push(keep(b[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a): only the former is blanked.
            let lit_end = if next == Some('\\') {
                (i + 2..b.len().min(i + 12)).find(|&k| b[k] == '\'')
            } else if b.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match lit_end {
                Some(end) => {
                    for _ in i..=end {
                        out.push(' ');
                    }
                    i = end + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// Where a raw string literal starting at `i` (`r"`, `r#"`, `br#"`) begins its body, with its
/// number of hashes.
fn raw_string_start(b: &[char], i: usize) -> Option<(usize, usize)> {
    let mut k = i;
    if b.get(k) == Some(&'b') {
        k += 1;
    }
    if b.get(k) != Some(&'r') {
        return None;
    }
    k += 1;
    let mut hashes = 0;
    while b.get(k) == Some(&'#') {
        hashes += 1;
        k += 1;
    }
    (b.get(k) == Some(&'"')).then_some((hashes, k + 1))
}

/// The index of the brace matching the `{` at `open` in blanked text.
fn matching_brace(t: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (k, &c) in t.iter().enumerate().skip(open) {
        match c {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return Some(k);
                }
            }
            _ => {}
        }
    }
    None
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// Blanked text with every `#[cfg(test)]` item blanked too (kept line breaks), and the names of
/// out-of-line modules declared test-only (`#[cfg(test)] mod tests;`).
fn drop_test_items(t: &str) -> (String, Vec<String>) {
    let mut b = t.as_bytes().to_vec();
    let mut test_mods = Vec::new();
    let pat = b"#[cfg(test)]";
    let mut i = 0;
    while i + pat.len() <= b.len() {
        if &b[i..i + pat.len()] != pat {
            i += 1;
            continue;
        }
        let start = i;
        let k = i + pat.len();
        // The item ends at the first `;` before any `{`, or at the `{`'s matching brace.
        let semi = b[k..].iter().position(|&c| c == b';').map(|p| p + k);
        let brace = b[k..].iter().position(|&c| c == b'{').map(|p| p + k);
        let end = match (semi, brace) {
            (Some(s), Some(o)) if s < o => s,
            (Some(s), None) => s,
            (_, Some(o)) => matching_brace(&b, o).unwrap_or(b.len() - 1),
            (None, None) => b.len() - 1,
        };
        let item = String::from_utf8_lossy(&b[start..=end]).to_string();
        if semi.is_some_and(|s| s == end) {
            let words: Vec<&str> = item.split_whitespace().collect();
            if let Some(p) = words.iter().position(|w| *w == "mod") {
                if let Some(name) = words.get(p + 1) {
                    test_mods.push(name.trim_end_matches(';').to_string());
                }
            }
        }
        for c in &mut b[start..=end] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
        i = end + 1;
    }
    (String::from_utf8_lossy(&b).to_string(), test_mods)
}

// ---------------------------------------------------------------------------------------------
// Modules and imports

/// A source file of a crate: its path, its module path below the crate root, and its text with
/// comments, literals and test items blanked.
struct SourceFile {
    path: PathBuf,
    module: Vec<String>,
    text: String,
}

/// Every non-test file of the crate rooted at `root_file`, following `mod x;` declarations.
fn crate_files(root_file: &Path) -> Vec<SourceFile> {
    let mut out = Vec::new();
    let mut todo = vec![(root_file.to_path_buf(), Vec::<String>::new())];
    while let Some((path, module)) = todo.pop() {
        let Ok(src) = std::fs::read_to_string(&path) else {
            continue;
        };
        let (text, _) = drop_test_items(&blank(&src));
        // Children live beside a root/mod.rs, else in a folder named after the file.
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let dir = if module.is_empty() || name == "mod.rs" {
            path.parent().map(Path::to_path_buf).unwrap_or_default()
        } else {
            path.with_extension("")
        };
        for child in declared_mods(&text) {
            let a = dir.join(format!("{child}.rs"));
            let b = dir.join(&child).join("mod.rs");
            let file = if a.exists() { a } else { b };
            let mut m = module.clone();
            m.push(child);
            todo.push((file, m));
        }
        out.push(SourceFile { path, module, text });
    }
    out
}

/// Names of out-of-line modules declared in blanked text (`mod x;`, `pub(crate) mod x;`).
fn declared_mods(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        if let Some(p) = words.iter().position(|w| *w == "mod") {
            if let Some(name) = words.get(p + 1) {
                if let Some(n) = name.strip_suffix(';') {
                    out.push(n.to_string());
                }
            }
        }
    }
    out
}

/// The top-level module names a file's text reaches: `crate::NAME`, `crate::{NAME, ..}` and
/// `super::` chains as long as the file's module depth.
fn imports(text: &str, depth: usize) -> BTreeSet<String> {
    let b = text.as_bytes();
    let mut out = BTreeSet::new();
    let ident_at = |k: usize| -> String {
        let mut e = k;
        while e < b.len() && is_ident(b[e]) {
            e += 1;
        }
        String::from_utf8_lossy(&b[k..e]).to_string()
    };
    let skip_ws = |mut k: usize| {
        while k < b.len() && b[k].is_ascii_whitespace() {
            k += 1;
        }
        k
    };
    let mut i = 0;
    while i < b.len() {
        let word_start = i == 0 || !is_ident(b[i - 1]);
        if word_start && b[i..].starts_with(b"crate") && !b.get(i + 5).is_some_and(|c| is_ident(*c))
        {
            let k = skip_ws(i + 5);
            if b[k..].starts_with(b"::") {
                let k = skip_ws(k + 2);
                if b.get(k) == Some(&b'{') {
                    group_heads(b, k, &mut out);
                } else {
                    out.insert(ident_at(k));
                }
            }
            i += 5;
            continue;
        }
        if word_start && depth > 0 && b[i..].starts_with(b"super::") {
            let mut k = i;
            let mut n = 0;
            while b[k..].starts_with(b"super::") {
                n += 1;
                k = skip_ws(k + 7);
            }
            if n == depth {
                if b.get(k) == Some(&b'{') {
                    group_heads(b, k, &mut out);
                } else {
                    out.insert(ident_at(k));
                }
            }
            i = k;
            continue;
        }
        i += 1;
    }
    out.retain(|n| !n.is_empty() && n != "self");
    out
}

/// The first identifier of each item in a `{a, b::c, d::{e}}` group starting at `open`.
fn group_heads(b: &[u8], open: usize, out: &mut BTreeSet<String>) {
    let Some(close) = matching_brace(b, open) else {
        return;
    };
    let mut depth = 0;
    let mut expect = true;
    for k in open + 1..close {
        match b[k] {
            b'{' => depth += 1,
            b'}' => depth -= 1,
            b',' if depth == 0 => expect = true,
            c if expect && depth == 0 && is_ident(c) => {
                let mut e = k;
                while e < close && is_ident(b[e]) {
                    e += 1;
                }
                out.insert(String::from_utf8_lossy(&b[k..e]).to_string());
                expect = false;
            }
            _ => {}
        }
    }
}

/// The crate's module graph: top-level module → top-level modules it imports.
fn module_graph(files: &[SourceFile]) -> BTreeMap<String, BTreeSet<String>> {
    let tops: BTreeSet<String> = files
        .iter()
        .filter(|f| f.module.len() == 1)
        .map(|f| f.module[0].clone())
        .collect();
    let mut g: BTreeMap<String, BTreeSet<String>> =
        tops.iter().map(|t| (t.clone(), BTreeSet::new())).collect();
    for f in files.iter().filter(|f| !f.module.is_empty()) {
        let me = &f.module[0];
        for m in imports(&f.text, f.module.len()) {
            if &m != me && tops.contains(&m) {
                g.entry(me.clone()).or_default().insert(m);
            }
        }
    }
    g
}

/// Strongly connected components of more than one module (Tarjan), each sorted.
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a str) {
        let n = t.index.len();
        t.index.insert(v, n);
        t.low.insert(v, n);
        t.stack.push(v);
        t.on.insert(v);
        let g = t.g;
        for w in g.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low[v];
                t.low.insert(v, lv.min(lw));
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low[v];
                t.low.insert(v, lv.min(iw));
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !t.index.contains_key(v.as_str()) {
            visit(&mut t, v);
        }
    }
    t.out
}

/// The `# Layers` section of a crate root's doc: module → layer number (0 = bottom), or why it
/// cannot be read.
fn layers(root_src: &str) -> Result<BTreeMap<String, usize>, String> {
    let mut out = BTreeMap::new();
    let mut inside = false;
    let mut n = 0;
    for line in root_src.lines() {
        let Some(doc) = line.trim_start().strip_prefix("//!") else {
            if inside {
                break;
            }
            continue;
        };
        let doc = doc.trim();
        if doc.starts_with('#') {
            if inside {
                break;
            }
            inside = doc.trim_start_matches('#').trim() == "Layers";
            continue;
        }
        if !inside {
            continue;
        }
        let Some((num, rest)) = doc.split_once(". ") else {
            continue;
        };
        if num.is_empty() || !num.chars().all(|c| c.is_ascii_digit()) {
            continue;
        }
        let names = rest.split(" — ").next().unwrap_or("");
        for (k, part) in names.split('`').enumerate() {
            if k % 2 == 1 && out.insert(part.to_string(), n).is_some() {
                return Err(format!("`{part}` is on two layers"));
            }
        }
        n += 1;
    }
    if out.is_empty() {
        return Err("no `# Layers` section with numbered lines in its doc".into());
    }
    Ok(out)
}

/// Every breach of the house's import rules in one crate, as lines.
fn import_breaches(root_file: &Path) -> Vec<String> {
    let at = root_file
        .strip_prefix(root())
        .unwrap_or(root_file)
        .display()
        .to_string();
    let files = crate_files(root_file);
    let g = module_graph(&files);
    let mut out = Vec::new();
    for c in circles(&g) {
        out.push(format!("{at}: import circle among {}", c.join(", ")));
    }
    let src = std::fs::read_to_string(root_file).unwrap_or_default();
    match layers(&src) {
        Err(e) => out.push(format!("{at}: {e}")),
        Ok(layer) => {
            for m in g.keys() {
                if !layer.contains_key(m) {
                    out.push(format!("{at}: module `{m}` is on no layer"));
                }
            }
            for m in layer.keys() {
                if !g.contains_key(m) {
                    out.push(format!("{at}: layer names `{m}`, which is no module"));
                }
            }
            for (m, deps) in &g {
                for d in deps {
                    if let (Some(lm), Some(ld)) = (layer.get(m), layer.get(d)) {
                        if ld > lm {
                            out.push(format!(
                                "{at}: `{m}` (layer {}) imports `{d}` (layer {}, above it)",
                                lm + 1,
                                ld + 1
                            ));
                        }
                    }
                }
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Function length

/// Functions of more than `limit` lines in `src` (first line `fn` to the closing brace), as
/// (name, first line, lines), unless a comment line just above says `Stays whole:`.
fn long_functions(src: &str, limit: usize, rust: bool) -> Vec<(String, usize, usize)> {
    let blanked = if rust {
        drop_test_items(&blank(src)).0
    } else {
        blank(src)
    };
    let t = blanked.as_bytes();
    let raw: Vec<&str> = src.lines().collect();
    let line_of = |k: usize| t[..k].iter().filter(|&&c| c == b'\n').count();
    let mut out = Vec::new();
    let mut i = 0;
    while i + 3 < t.len() {
        let word = (i == 0 || !is_ident(t[i - 1])) && t[i..].starts_with(b"fn ");
        if !word {
            i += 1;
            continue;
        }
        let mut k = i + 3;
        while k < t.len() && t[k] == b' ' {
            k += 1;
        }
        let s = k;
        while k < t.len() && is_ident(t[k]) {
            k += 1;
        }
        let name = String::from_utf8_lossy(&t[s..k]).to_string();
        if name.is_empty() {
            i = k;
            continue;
        }
        let semi = t[k..].iter().position(|&c| c == b';').map(|p| p + k);
        let open = t[k..].iter().position(|&c| c == b'{').map(|p| p + k);
        let Some(open) = open.filter(|o| semi.is_none_or(|s| s > *o)) else {
            i = k;
            continue;
        };
        let Some(close) = matching_brace(t, open) else {
            break;
        };
        let (first, last) = (line_of(i), line_of(close));
        let lines = last - first + 1;
        if lines > limit && !exempt(&raw, first) {
            out.push((name, first + 1, lines));
        }
        i = k;
    }
    out
}

/// Whether the comment and attribute lines right above line `first` (0-based) hold `Stays whole:`.
fn exempt(raw: &[&str], first: usize) -> bool {
    let mut k = first;
    while k > 0 {
        k -= 1;
        let l = raw[k].trim();
        if l.starts_with("//") || l.starts_with("#[") {
            if l.contains(EXEMPT) {
                return true;
            }
        } else {
            break;
        }
    }
    false
}

fn files_with(dir: &Path, ext: &str, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            files_with(&p, ext, out);
        } else if p.extension().is_some_and(|x| x == ext) {
            out.push(p);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The house

#[test]
fn no_import_circle_and_no_import_from_a_layer_above() {
    let mut breaches = Vec::new();
    for r in crate_roots() {
        breaches.extend(import_breaches(&r));
    }
    assert!(breaches.is_empty(), "{}", breaches.join("\n"));
}

#[test]
fn no_long_function_without_a_reason() {
    let mut found = Vec::new();
    for r in crate_roots() {
        for f in crate_files(&r) {
            let src = std::fs::read_to_string(&f.path).unwrap_or_default();
            for (name, line, n) in long_functions(&src, RUST_LIMIT, true) {
                let at = f
                    .path
                    .strip_prefix(root())
                    .unwrap_or(&f.path)
                    .display()
                    .to_string();
                found.push(format!(
                    "{at}:{line}: fn {name} is {n} lines (limit {RUST_LIMIT})"
                ));
            }
        }
    }
    let mut wgsl = Vec::new();
    files_with(&root().join("shaders"), "wgsl", &mut wgsl);
    assert!(!wgsl.is_empty(), "no WGSL found under shaders/");
    for p in wgsl {
        let src = std::fs::read_to_string(&p).unwrap_or_default();
        for (name, line, n) in long_functions(&src, WGSL_LIMIT, false) {
            let at = p.strip_prefix(root()).unwrap_or(&p).display().to_string();
            found.push(format!(
                "{at}:{line}: fn {name} is {n} lines (limit {WGSL_LIMIT})"
            ));
        }
    }
    assert!(
        found.is_empty(),
        "functions too long (split them where the split names a step, or say `{EXEMPT}` why \
         in their doc):\n{}",
        found.join("\n")
    );
}

#[test]
fn every_crate_root_is_read_with_its_modules() {
    // The checks above would pass vacuously on a crate they failed to read.
    for r in crate_roots() {
        let files = crate_files(&r);
        let tops = files.iter().filter(|f| f.module.len() == 1).count();
        assert!(
            tops >= 2,
            "{}: only {tops} top-level modules read",
            r.display()
        );
    }
    let ingest = crate_files(&root().join("ingest/src/lib.rs"));
    assert!(
        ingest.iter().any(|f| f.module.len() >= 2),
        "ingest's nested modules were not followed"
    );
}

// ---------------------------------------------------------------------------------------------
// The checker's own cases: each rule is seen to fire.

#[test]
fn the_reader_sees_paths_groups_and_supers_and_skips_comments_strings_and_tests() {
    let src = r##"
use crate::region::Region; // crate::comment
use crate::{meta::{A, B}, spline, output::*};
use super::super::grib::x;
use super::sibling;
fn f() { let s = "crate::string"; let r = r#"crate::raw"#; let c = '{'; }
#[cfg(test)]
mod tests { use crate::testonly::X; }
"##;
    let text = drop_test_items(&blank(src)).0;
    let got = imports(&text, 2);
    let want: BTreeSet<String> = ["region", "meta", "spline", "output", "grib"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(got, want);
    // At depth 1 a single super:: reaches the root.
    assert!(imports(&blank("use super::sibling;"), 1).contains("sibling"));
}

#[test]
fn a_circle_and_a_layer_breach_are_found() {
    let mut g = BTreeMap::new();
    let set = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>();
    g.insert("error".to_string(), set(&["output"]));
    g.insert("output".to_string(), set(&["error"]));
    g.insert("meta".to_string(), set(&[]));
    assert_eq!(
        circles(&g),
        vec![vec!["error".to_string(), "output".to_string()]]
    );
    let doc = "//! # Layers\n//!\n//! Bottom first.\n//!\n//! 1. `error`, `output` — bottom\n\
               //! 2. `meta` — the schema\n//!\n//! # Other\n//! 3. `late` — not a layer\n";
    let l = layers(doc).expect("layers read");
    assert_eq!(l.get("error"), Some(&0));
    assert_eq!(l.get("meta"), Some(&1));
    assert!(!l.contains_key("late"));
    assert!(layers("//! nothing here\n").is_err());
    assert!(layers("//! # Layers\n//! 1. `a` — x\n//! 2. `a` — y\n").is_err());
}

#[test]
fn a_long_function_is_found_unless_its_doc_says_why() {
    let body = |name: &str, doc: &str| {
        let mut s = format!("{doc}\nfn {name}() {{\n");
        for k in 0..120 {
            s.push_str(&format!("    let _x{k} = \"}}\";\n"));
        }
        s.push_str("}\n");
        s
    };
    let plain = body("long", "/// Does things.");
    assert_eq!(
        long_functions(&plain, 100, true),
        vec![("long".to_string(), 2, 122)]
    );
    let kept = body("kept", "/// Stays whole: one table.");
    assert!(long_functions(&kept, 100, true).is_empty());
    let test_only = format!("#[cfg(test)]\nmod tests {{\n{}}}\n", body("t", ""));
    assert!(long_functions(&test_only, 100, true).is_empty());
    let wgsl = body("march", "// A WGSL stage.").replace("let _x", "var x");
    assert_eq!(long_functions(&wgsl, 150, false), vec![]);
    assert_eq!(long_functions(&wgsl, 100, false).len(), 1);
}
