//! `companion … -h` is for people: one line per flag, none of its lines wider than 100
//! characters; `--help` has the whole text of every flag `-h` lists and ends with the book's
//! chapter to read, which exists. Every command is found from the `Commands:` lists of the
//! help itself (the hidden `latency-peer` aside), so a new one is held to the same rules.

use std::path::Path;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_companion");

/// The widest line `-h` may print, in characters.
const WIDTH: usize = 100;

/// The output of `companion <command…> <flag>`, which must succeed.
fn help(command: &[String], flag: &str) -> String {
    let out = Command::new(BIN).args(command).arg(flag).output().unwrap();
    assert!(out.status.success(), "companion {} {flag} failed: {out:?}", command.join(" "));
    String::from_utf8(out.stdout).unwrap()
}

/// The non-blank lines of the section `title` (`Options:`, `Arguments:`, `Commands:`) of a help
/// text, up to the next line that is not indented (the next section, or the text after them).
fn section<'a>(text: &'a str, title: &str) -> Vec<&'a str> {
    text.lines()
        .skip_while(|l| *l != title)
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .take_while(|l| l.starts_with(' '))
        .collect()
}

/// Every command: `[]` (companion itself), then each entry of each `Commands:` list but `help`.
fn commands() -> Vec<Vec<String>> {
    let mut all = vec![Vec::new()];
    let mut i = 0;
    while i < all.len() {
        let text = help(&all[i], "-h");
        for line in section(&text, "Commands:") {
            let name = line.split_whitespace().next().unwrap().to_string();
            if name != "help" {
                let mut c = all[i].clone();
                c.push(name);
                all.push(c);
            }
        }
        i += 1;
    }
    all
}

/// The flag or argument an entry line of `Options:` or `Arguments:` names (`--out`, `--help`
/// for `-h, --help`, `<DIR>...`), or `None` for a line that is not an entry's first: the
/// continuation of a flag's help, which starts further in.
fn entry(line: &str) -> Option<&str> {
    let rest = line.strip_prefix("  ")?;
    let rest = match rest.strip_prefix("    ") {
        Some(long_only) => long_only,
        None => rest,
    };
    let mut words = rest.split(' ');
    let first = words.next()?;
    if first.len() == 3 && first.starts_with('-') && first.ends_with(',') {
        return words.next().filter(|w| w.starts_with("--"));
    }
    (first.starts_with('-') || first.starts_with('<') || first.starts_with('[')).then_some(first)
}

/// The titles of the sections that list flags or arguments: `Arguments:`, `Options:` and any
/// `help_heading` of a group of flags — every unindented line ending in `:` but `Commands:`
/// and the exit codes' list.
fn flag_sections(text: &str) -> Vec<&str> {
    text.lines()
        .filter(|l| !l.starts_with(' ') && l.ends_with(':'))
        .filter(|l| !matches!(*l, "Commands:" | "Exit codes:") && !l.starts_with("Usage:"))
        .collect()
}

/// The flags and arguments a help text lists, in order.
fn entries(text: &str) -> Vec<String> {
    flag_sections(text).iter().flat_map(|s| section(text, s)).filter_map(entry).map(str::to_string).collect()
}

#[test]
fn every_command_is_found() {
    let found: Vec<String> = commands().iter().map(|c| c.join(" ")).collect();
    for c in ["", "hil", "sim", "plant", "control", "explore", "explore merge", "tune", "latency", "certs"] {
        assert!(found.iter().any(|f| f == c), "`companion {c}` not found among {found:?}");
    }
}

#[test]
fn short_help_gives_one_line_per_flag_of_at_most_100_characters() {
    for command in commands() {
        let name = format!("companion {}", command.join(" "));
        let text = help(&command, "-h");
        for line in text.lines() {
            let n = line.chars().count();
            assert!(n <= WIDTH, "`{name} -h`: a line of {n} characters (at most {WIDTH}):\n{line}");
        }
        for title in flag_sections(&text) {
            for line in section(&text, title) {
                assert!(
                    entry(line).is_some(),
                    "`{name} -h`: a flag's help goes on over a second line (one line per flag):\n{line}"
                );
            }
        }
        for line in section(&text, "Commands:") {
            assert!(
                line.starts_with("  ") && !line.starts_with("   "),
                "`{name} -h`: a command's entry goes on over a second line:\n{line}"
            );
        }
        assert!(entries(&text).iter().any(|e| e == "--help"), "`{name} -h` lists no flags:\n{text}");
    }
}

#[test]
fn long_help_has_every_flag_and_ends_with_the_books_chapter() {
    let repository = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for command in commands() {
        let name = format!("companion {}", command.join(" "));
        let short = help(&command, "-h");
        let long = help(&command, "--help");
        assert_eq!(entries(&short), entries(&long), "`{name}`: -h and --help list different flags");
        let last = long.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("");
        let chapter = last
            .split_whitespace()
            .find(|w| w.starts_with("docs/book/src/") && w.ends_with(".md"))
            .unwrap_or_else(|| panic!("`{name} --help` does not end with the book's chapter:\n{last}"));
        assert!(repository.join(chapter).is_file(), "`{name} --help` names {chapter}, which does not exist");
        assert!(
            short.contains(chapter),
            "`{name} -h` does not name the chapter its --help names ({chapter})"
        );
    }
}
