//! The module graph of a crate, read from its source, and the cycles in it.
//!
//! "No module cycles" means: for every module `P`, the graph whose nodes are `P`'s own items
//! and each of `P`'s child modules (with everything below it) has no cycle. A reference from
//! module `A` to module `B` is an edge between the children of their deepest common ancestor
//! that contain them (or that ancestor's own items, when `A` or `B` is the ancestor itself),
//! so `hil::plant` using `hil::report` and `hil::report` using `hil::plant` is a cycle in
//! `hil`'s graph, and so is `hil::plant` using an item defined in `hil` while `hil` calls
//! `hil::plant`. A parent declaring a child (`mod x;`) is not a reference.
//!
//! References are read from code, not comments or strings: paths that start with `crate::`,
//! `super::`, `self::` or the name of a child module (in `use` trees and in expressions).
//! Test modules (`#[cfg(test)] mod …`, inline or in their own file) are left out: test code
//! may reach anywhere.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path from the crate root (`[]` is the root).
pub type ModPath = Vec<String>;

/// One module: its file and its code (comments, strings and test modules removed).
#[derive(Clone, Debug)]
pub struct Module {
    /// The file.
    pub file: PathBuf,
    /// The code.
    pub code: String,
    /// Its child modules.
    pub children: Vec<String>,
}

/// The modules of a crate, from its root file.
///
/// # Errors
/// A declared module's file cannot be read.
pub fn read_crate(root_file: &Path) -> Result<BTreeMap<ModPath, Module>, String> {
    let mut out = BTreeMap::new();
    read_module(root_file, Vec::new(), true, &mut out)?;
    Ok(out)
}

fn read_module(
    file: &Path,
    path: ModPath,
    dir_owner: bool,
    out: &mut BTreeMap<ModPath, Module>,
) -> Result<(), String> {
    let text = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
    let code = strip(&text);
    let children = declared_modules(&code);
    let dir = if dir_owner {
        file.parent().map(Path::to_path_buf).unwrap_or_default()
    } else {
        file.with_extension("")
    };
    for child in &children {
        let mut p = path.clone();
        p.push(child.clone());
        let flat = dir.join(format!("{child}.rs"));
        if flat.exists() {
            read_module(&flat, p, false, out)?;
        } else {
            read_module(&dir.join(child).join("mod.rs"), p, true, out)?;
        }
    }
    out.insert(path, Module { file: file.to_path_buf(), code, children });
    Ok(())
}

/// The text without comments, string and char literals, and `#[cfg(test)]` modules.
pub fn strip(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let mut depth = 0;
            while i < b.len() {
                if b[i..].starts_with(b"/*") {
                    depth += 1;
                    i += 2;
                } else if b[i..].starts_with(b"*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if b[i] == b'"' || (b[i] == b'r' && b.get(i + 1).is_some_and(|c| *c == b'"' || *c == b'#')) {
            // A string (raw or not): skipped whole.
            let raw = b[i] == b'r';
            let mut hashes = 0;
            if raw {
                i += 1;
                while b.get(i) == Some(&b'#') {
                    hashes += 1;
                    i += 1;
                }
            }
            i += 1;
            while i < b.len() {
                if !raw && b[i] == b'\\' {
                    i += 2;
                    continue;
                }
                if b[i] == b'"' && b[i + 1..].iter().take(hashes).filter(|c| **c == b'#').count() == hashes {
                    i += 1 + hashes;
                    break;
                }
                i += 1;
            }
            out.push_str("\"\"");
        } else if b[i] == b'\'' && b.get(i + 2) == Some(&b'\'') {
            i += 3;
        } else if b[i] == b'\'' && b.get(i + 1) == Some(&b'\\') {
            // An escaped char literal.
            i += 2;
            while i < b.len() && b[i] != b'\'' {
                i += 1;
            }
            i += 1;
        } else {
            let c = text[i..].chars().next().unwrap_or(' ');
            out.push(c);
            i += c.len_utf8();
        }
    }
    remove_test_modules(&out)
}

/// Removes `#[cfg(test)] mod x { … }` blocks and `#[cfg(test)] mod x;` lines.
fn remove_test_modules(code: &str) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at + "#[cfg(test)]".len()..];
        let trimmed = after.trim_start();
        let decl =
            trimmed.strip_prefix("pub(crate) ").or_else(|| trimmed.strip_prefix("pub ")).unwrap_or(trimmed);
        if !decl.starts_with("mod ") {
            out.push_str("#[cfg(test)]");
            rest = after;
            continue;
        }
        let start = after.len() - trimmed.len();
        let semi = trimmed.find(';');
        let brace = trimmed.find('{');
        match (semi, brace) {
            (Some(s), b) if b.is_none_or(|b| s < b) => rest = &after[start + s + 1..],
            (_, Some(b)) => {
                let body = &trimmed[b..];
                let mut depth = 0usize;
                let mut end = body.len();
                for (k, ch) in body.char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = k + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                rest = &after[start + b + end..];
            }
            _ => rest = "",
        }
    }
    out.push_str(rest);
    out
}

fn is_ident(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// `mod x;` declarations (file modules) of a module's code.
fn declared_modules(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for stmt in code.split(';') {
        let words: Vec<&str> = stmt.split_whitespace().collect();
        if let Some(k) = words.iter().position(|w| *w == "mod") {
            let vis_ok = words[..k].iter().all(|w| w.starts_with("pub") || w.starts_with('#'));
            if vis_ok && k + 2 == words.len() && is_ident(words[k + 1]) {
                out.push(words[k + 1].to_string());
            }
        }
    }
    out
}

/// Every path of a `use` tree, e.g. `crate::{a::X, b::{c, d}}` → `crate::a::X`,
/// `crate::b::c`, `crate::b::d`.
fn expand_use(tree: &str) -> Vec<String> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = tree.find('{') else {
        return vec![tree.split(" as ").next().unwrap_or("").to_string()];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let mut parts = Vec::new();
    let mut depth = 0;
    let mut start = 0;
    for (k, ch) in inner.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| expand_use(p).into_iter().map(move |q| format!("{prefix}{q}")))
        .collect()
}

/// The paths a module's code refers to (as written).
fn referenced_paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    // `use` trees.
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before_ok =
            at == 0 || !rest.as_bytes()[at - 1].is_ascii_alphanumeric() && rest.as_bytes()[at - 1] != b'_';
        let after = &rest[at + 4..];
        let end = after.find(';').unwrap_or(after.len());
        if before_ok {
            out.extend(expand_use(&after[..end]));
        }
        rest = &after[end.min(after.len())..];
    }
    // Paths in expressions and types: `a::b::c` runs of identifiers joined by `::`.
    let bytes = code.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_alphabetic() || bytes[i] == b'_' {
            let start = i;
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_' || bytes[i] == b':')
            {
                i += 1;
            }
            let word = code[start..i].trim_end_matches(':');
            let prev_colon = start >= 2 && &code[start - 2..start] == "::";
            if word.contains("::") && !prev_colon {
                out.push(word.to_string());
            }
        } else {
            i += 1;
        }
    }
    out
}

/// The module a path written in module `from` refers to (the deepest module it names), if
/// it is one of this crate's.
fn resolve(path: &str, from: &ModPath, modules: &BTreeMap<ModPath, Module>) -> Option<ModPath> {
    let segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let (mut at, mut rest) = match segs.first().copied() {
        Some("crate") => (Vec::new(), &segs[1..]),
        Some("self") => (from.clone(), &segs[1..]),
        Some("super") => {
            let mut at = from.clone();
            let mut k = 0;
            while segs.get(k) == Some(&"super") {
                at.pop();
                k += 1;
            }
            (at, &segs[k..])
        }
        Some(first) if modules.get(from).is_some_and(|m| m.children.iter().any(|c| c == first)) => {
            (from.clone(), &segs[..])
        }
        _ => return None,
    };
    while let Some(seg) = rest.first() {
        let Some(m) = modules.get(&at) else { break };
        if m.children.iter().any(|c| c == seg) {
            at.push((*seg).to_string());
            rest = &rest[1..];
        } else {
            break;
        }
    }
    Some(at)
}

/// The edges of the graph of module `parent`: `(from, to)` where each is a child's name or
/// `"self"` for `parent`'s own items, with one example reference each.
pub type Edges = BTreeMap<(String, String), String>;

/// Every graph of the crate: for each module, the edges between its own items and its
/// children.
pub fn graphs(modules: &BTreeMap<ModPath, Module>) -> BTreeMap<ModPath, Edges> {
    let mut out: BTreeMap<ModPath, Edges> = BTreeMap::new();
    for (from, m) in modules {
        for path in referenced_paths(&m.code) {
            let Some(to) = resolve(&path, from, modules) else { continue };
            if &to == from {
                continue;
            }
            let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
            let side = |p: &ModPath| p.get(common).cloned().unwrap_or_else(|| "self".to_string());
            let (a, b) = (side(from), side(&to));
            if a != b {
                let parent = from[..common].to_vec();
                out.entry(parent)
                    .or_default()
                    .entry((a, b))
                    .or_insert_with(|| format!("{} uses {path}", m.file.display()));
            }
        }
    }
    out
}

/// The cycles of every graph, each as `parent: a → b → a (a uses …; b uses …)`.
pub fn cycles(modules: &BTreeMap<ModPath, Module>) -> Vec<String> {
    let mut found = Vec::new();
    for (parent, edges) in graphs(modules) {
        let nodes: BTreeSet<&String> = edges.keys().flat_map(|(a, b)| [a, b]).collect();
        let next =
            |n: &String| -> Vec<&String> { edges.keys().filter(|(a, _)| a == n).map(|(_, b)| b).collect() };
        // Depth-first search for a back edge from each node.
        let mut reported: BTreeSet<Vec<String>> = BTreeSet::new();
        for start in &nodes {
            let mut stack: Vec<(String, Vec<String>)> = vec![((*start).clone(), vec![(*start).clone()])];
            let mut seen = BTreeSet::new();
            while let Some((n, trail)) = stack.pop() {
                for m in next(&n) {
                    if m == *start {
                        let mut key = trail.clone();
                        key.sort();
                        if reported.insert(key) {
                            let mut c = trail.clone();
                            c.push((*start).clone());
                            let why: Vec<&str> =
                                c.windows(2).map(|w| edges[&(w[0].clone(), w[1].clone())].as_str()).collect();
                            let name =
                                if parent.is_empty() { "crate".to_string() } else { parent.join("::") };
                            found.push(format!("{name}: {} ({})", c.join(" → "), why.join("; ")));
                        }
                    } else if seen.insert(m.clone()) {
                        let mut t = trail.clone();
                        t.push(m.clone());
                        stack.push((m.clone(), t));
                    }
                }
            }
        }
    }
    found
}

/// A crate's layers: the children of its root, each with the layers it may use.
pub type Layers<'a> = &'a [(&'a str, &'a [&'a str])];

/// Every dependency between the root's children that `layers` does not allow, as
/// `a → b (a uses …)`, and every child of the root that is not a layer (`x: not a layer`),
/// so a module added at the root cannot slip past the check. The root's own items (its
/// `mod` declarations aside) count as a child `self` and must not use anything.
pub fn layer_violations(modules: &BTreeMap<ModPath, Module>, layers: Layers<'_>) -> Vec<String> {
    let mut found = Vec::new();
    let may = |a: &str, b: &str| layers.iter().any(|(l, uses)| *l == a && uses.contains(&b));
    if let Some(root) = modules.get(&Vec::new()) {
        for child in &root.children {
            if !layers.iter().any(|(l, _)| l == child) {
                found.push(format!("{child}: not a layer"));
            }
        }
    }
    if let Some(edges) = graphs(modules).get(&Vec::new()) {
        for ((a, b), why) in edges {
            if !may(a, b) {
                found.push(format!("{a} → {b} ({why})"));
            }
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    fn crate_of(files: &[(&str, &str)]) -> BTreeMap<ModPath, Module> {
        // One folder per call: the tests run in parallel.
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("companion-modgraph-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for (name, text) in files {
            let p = dir.join(name);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        }
        let m = read_crate(&dir.join("lib.rs")).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        m
    }

    #[test]
    fn a_two_module_cycle_is_found_and_a_chain_is_not() {
        let m = crate_of(&[
            ("lib.rs", "pub mod a;\npub mod b;\npub mod c;\n"),
            ("a.rs", "use crate::b::B;\npub struct A;\n"),
            ("b.rs", "pub struct B;\nfn f() { let _ = crate::c::C; }\n"),
            ("c.rs", "// use crate::a::A; (a comment is not a reference)\npub struct C;\nconst S: &str = \"crate::a::A\";\n#[cfg(test)]\nmod tests {\n    use crate::a::A;\n}\n"),
        ]);
        assert!(cycles(&m).is_empty(), "{:?}", cycles(&m));
        let m = crate_of(&[
            ("lib.rs", "pub mod a;\npub mod b;\n"),
            ("a.rs", "use crate::b::B;\npub struct A;\n"),
            ("b.rs", "pub struct B;\nfn f() -> crate::a::A { crate::a::A }\n"),
        ]);
        let c = cycles(&m);
        assert_eq!(c.len(), 1, "{c:?}");
        assert!(c[0].starts_with("crate: a → b → a"), "{c:?}");
    }

    #[test]
    fn a_child_using_its_parents_items_while_the_parent_uses_it_is_a_cycle() {
        let m = crate_of(&[
            ("lib.rs", "pub mod hil;\n"),
            (
                "hil/mod.rs",
                "pub mod plant;\npub mod wait;\npub struct Args;\npub fn run() { plant::run() }\n",
            ),
            ("hil/plant.rs", "use super::{Args, wait::idle};\npub fn run() {}\n"),
            ("hil/wait.rs", "pub fn idle() {}\n"),
        ]);
        let c = cycles(&m);
        assert_eq!(c.len(), 1, "{c:?}");
        assert!(c[0].starts_with("hil: "), "{c:?}");
        assert!(c[0].contains("plant") && c[0].contains("self"), "{c:?}");
    }

    #[test]
    fn cycles_through_submodules_count_at_the_common_ancestor() {
        let m = crate_of(&[
            ("lib.rs", "pub mod x;\npub mod y;\n"),
            ("x/mod.rs", "pub mod inner;\n"),
            ("x/inner.rs", "use crate::y::Y;\npub struct I;\n"),
            ("y.rs", "pub struct Y;\npub fn f(_: crate::x::inner::I) {}\n"),
        ]);
        let c = cycles(&m);
        assert_eq!(c.len(), 1, "{c:?}");
        assert!(c[0].starts_with("crate: x → y → x") || c[0].starts_with("crate: y → x → y"), "{c:?}");
    }

    #[test]
    fn a_layer_using_one_after_it_is_reported_and_one_before_it_is_not() {
        let m = crate_of(&[
            ("lib.rs", "pub mod low;\npub mod high;\npub mod stray;\n"),
            ("low/mod.rs", "pub mod clock;\n"),
            ("low/clock.rs", "pub fn now() {}\n"),
            ("high/mod.rs", "pub mod run;\n"),
            ("high/run.rs", "pub fn go() { crate::low::clock::now() }\n"),
            ("stray.rs", "pub fn s() {}\n"),
        ]);
        let layers: Layers<'_> = &[("low", &[]), ("high", &["low"])];
        assert_eq!(layer_violations(&m, layers), vec!["stray: not a layer".to_string()]);
        let m = crate_of(&[
            ("lib.rs", "pub mod low;\npub mod high;\n"),
            ("low/mod.rs", "pub fn now() { let _ = crate::high::X; }\n"),
            ("high/mod.rs", "pub struct X;\n"),
        ]);
        let v = layer_violations(&m, layers);
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].starts_with("low → high ("), "{v:?}");
    }
}
