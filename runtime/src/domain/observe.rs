//! What a long operation tells its user while it runs: steps done, notes and warnings. The
//! command line shows them (a progress bar, lines on stderr); tests and benchmarks pass
//! [`Silent`].

/// Receives the progress and the messages of a run.
pub trait Observer: Sync {
    /// `steps` more steps are done.
    fn advance(&self, _steps: u64) {}
    /// A line for the user.
    fn note(&self, _line: &str) {}
    /// A warning: the run goes on, but something is not as asked.
    fn warn(&self, _line: &str) {}
}

/// Ignores everything.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Observer for Silent {}
