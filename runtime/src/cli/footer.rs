//! The ends of `-h` and `--help`: where the rest is — the whole text of each flag, the exit
//! codes, and the book's chapter to read (`runtime/tests/help.rs` checks that it exists).

use super::exit;

/// The last line of `-h`: where the rest is.
pub fn short_after(chapter: &str) -> String {
    format!("Exit codes and the whole text of each flag: --help. The book: docs/book/src/{chapter}")
}

/// The end of `--help`: the exit codes, then the book's chapter to read.
pub fn long_after(chapter: &str) -> String {
    format!("{}\n\nThe book's chapter (in the repository): docs/book/src/{chapter}", exit::help())
}
