//! The documentation's links and anchors: `scripts/check_links.py` passes on the repository's
//! README and book, and — so that a checker that passes everything would fail here — it fails
//! on small trees with one known fault each, naming the file, the line and the fault, while
//! a tree of links that only look broken (in code, repeated headings, explicit ids, line
//! ranges) passes.
//!
//! Needs `python3` (standard library only), which `scripts/setup` installs.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The checker's verdict on `root`: whether it passed, and what it printed.
fn check(root: &Path) -> (bool, String) {
    let script = repository().join("scripts/check_links.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg("--root")
        .arg(root)
        .output()
        .unwrap_or_else(|e| panic!("python3 {}: {e} (scripts/setup installs python3)", script.display()));
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "check_links.py neither passed nor failed (exit {:?}):\n{text}",
        out.status.code()
    );
    (out.status.success(), text)
}

/// A fresh folder with `files` (path, content) in it; removed when dropped.
struct Tree(PathBuf);

impl Tree {
    fn new(name: &str, files: &[(&str, &str)]) -> Self {
        let dir = std::env::temp_dir().join(format!("companion-docs-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for (path, content) in files {
            let p = dir.join(path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, content).unwrap();
        }
        Self(dir)
    }
}

impl Drop for Tree {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn every_link_and_anchor_of_the_readme_and_the_book_resolves() {
    let (ok, text) = check(&repository());
    assert!(ok, "broken links in the documentation:\n{text}");
    assert!(text.contains("all resolve"), "{text}");
}

#[test]
fn links_that_only_look_broken_pass() {
    let tree = Tree::new(
        "fine",
        &[
            (
                "README.md",
                "# Top\n\n\
                 ## Top\n\n\
                 ## `sim --arm`: spatial runs (§5)\n\n\
                 <a id=\"kept\"></a>\n\
                 [second](#top-1) [code](#sim---arm-spatial-runs-5) [id](#kept) [folder](src)\n\
                 [lines](src/lib.rs#L2-L3) ![image](docs/a.svg) [ref]: docs/chapter.md#sub-part\n\n\
                 `[in a span](#nowhere)` <!-- [in a comment](#nowhere) -->\n\n\
                 ```sh\n[in a fence](#nowhere)\n```\n\n\
                 1. a step\n\n   ```text\n   [in a list's fence](#nowhere)\n   ```\n",
            ),
            ("src/lib.rs", "a\nb\nc\n"),
            ("docs/a.svg", "<svg/>"),
            ("docs/chapter.md", "# Chapter\n\n## Sub part\n\n[back](../README.md#top)\n"),
        ],
    );
    let (ok, text) = check(&tree.0);
    assert!(ok, "a tree with no broken link failed:\n{text}");
}

#[test]
fn each_kind_of_broken_link_fails_and_is_named() {
    let faults: [(&str, &str, &str); 7] = [
        (
            "a file that does not exist",
            "[x](docs/gone.md)\n",
            "README.md:3: link 'docs/gone.md': no such file",
        ),
        ("an anchor no heading has", "[x](#nowhere)\n", "README.md:3: link '#nowhere': no heading or id"),
        (
            "an anchor of another file",
            "[x](docs/chapter.md#intro)\n",
            "no heading or id '#intro' in docs/chapter.md",
        ),
        ("a repeated heading's number", "[x](#top-2)\n", "link '#top-2': no heading or id"),
        ("an absolute path", "[x](/docs/chapter.md)\n", "link '/docs/chapter.md': an absolute path"),
        ("a line beyond the file", "[x](src/lib.rs#L9)\n", "link 'src/lib.rs#L9': src/lib.rs has 4 lines"),
        // GitHub lowercases `É`, mdBook keeps it: the link would work on one of them only.
        (
            "an anchor only GitHub has",
            "## Écart\n\n[x](#écart)\n",
            "'#écart' is GitHub's anchor, not mdBook's",
        ),
    ];
    for (what, line, expected) in faults {
        let readme = format!("# Top\n\n{line}");
        let tree = Tree::new(
            "broken",
            &[
                ("README.md", &readme),
                ("src/lib.rs", "a\nb\nc\n"),
                ("docs/chapter.md", "# Chapter\n\n## Top\n"),
            ],
        );
        let (ok, text) = check(&tree.0);
        assert!(!ok, "{what}: the checker passed:\n{text}");
        assert!(text.contains(expected), "{what}: the checker did not say {expected:?}:\n{text}");
        assert!(text.contains("1 broken of"), "{what}: more than the one fault reported:\n{text}");
    }
}

#[test]
fn the_books_summary_must_list_every_chapter_and_only_chapters_that_exist() {
    let unlisted = Tree::new(
        "unlisted",
        &[
            ("docs/book/src/SUMMARY.md", "# Summary\n\n- [One](one.md)\n"),
            ("docs/book/src/one.md", "# One\n"),
            ("docs/book/src/two.md", "# Two\n"),
        ],
    );
    let (ok, text) = check(&unlisted.0);
    assert!(!ok && text.contains("does not list the chapter docs/book/src/two.md"), "{text}");

    let missing = Tree::new(
        "missing",
        &[
            ("docs/book/src/SUMMARY.md", "# Summary\n\n- [One](one.md)\n- [Two](two.md)\n"),
            ("docs/book/src/one.md", "# One\n"),
        ],
    );
    let (ok, text) = check(&missing.0);
    assert!(!ok && text.contains("docs/book/src/SUMMARY.md:4: link 'two.md': no such file"), "{text}");
}
