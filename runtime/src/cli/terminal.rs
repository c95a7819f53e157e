//! The terminal as the library's observer: a progress bar, notes and warnings on stderr.

use std::io::IsTerminal;

use companion_runtime::domain::observe::Observer;
use indicatif::{ProgressBar, ProgressStyle};

/// The terminal as an [`Observer`]: a progress bar (when there is one), notes and warnings
/// on stderr.
#[derive(Debug)]
pub struct Terminal {
    bar: Option<ProgressBar>,
    notes: bool,
}

impl Terminal {
    /// Notes and warnings on stderr, no bar.
    pub fn lines() -> Self {
        Self { bar: None, notes: true }
    }

    /// Warnings only.
    pub fn warnings_only() -> Self {
        Self { bar: None, notes: false }
    }

    /// A bar of `len` steps (hidden when stderr is not a terminal or `hidden`).
    pub fn bar(len: u64, hidden: bool) -> Self {
        let bar = if hidden || !std::io::stderr().is_terminal() {
            ProgressBar::hidden()
        } else {
            let pb = ProgressBar::new(len);
            pb.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} steps ({eta})",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            pb
        };
        Self { bar: Some(bar), notes: true }
    }

    /// A bar of `len` items named `unit` with the time left (hidden when stderr is not a
    /// terminal or `hidden`).
    pub fn bar_of(len: u64, unit: &str, hidden: bool) -> Self {
        let bar = if hidden || !std::io::stderr().is_terminal() {
            ProgressBar::hidden()
        } else {
            let pb = ProgressBar::new(len);
            pb.set_style(
                ProgressStyle::with_template(&format!(
                    "{{spinner}} [{{elapsed_precise}}] {{wide_bar}} {{pos}}/{{len}} {unit} ({{per_sec}}, {{eta}} left)"
                ))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            pb
        };
        Self { bar: Some(bar), notes: true }
    }

    /// The same without notes (warnings only).
    pub fn without_notes(self) -> Self {
        Self { notes: false, ..self }
    }

    /// Removes the bar.
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }

    fn line(&self, text: &str) {
        match &self.bar {
            Some(b) => b.suspend(|| eprintln!("{text}")),
            None => eprintln!("{text}"),
        }
    }
}

impl Observer for Terminal {
    fn advance(&self, steps: u64) {
        if let Some(b) = &self.bar {
            b.inc(steps);
        }
    }

    fn note(&self, line: &str) {
        if self.notes {
            self.line(line);
        }
    }

    fn warn(&self, line: &str) {
        self.line(&format!("warning: {line}"));
    }
}
