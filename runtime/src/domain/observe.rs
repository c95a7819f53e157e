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

/// An error and its causes on one line, `outer: inner: …` (as the command line prints an
/// error), for a message to an [`Observer`].
#[derive(Clone, Copy, Debug)]
pub struct Causes<'a>(pub &'a (dyn std::error::Error + 'static));

impl std::fmt::Display for Causes<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)?;
        let mut cause = self.0.source();
        while let Some(c) = cause {
            write!(f, ": {c}")?;
            cause = c.source();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("writing x.json")]
    struct Outer(#[source] std::io::Error);

    #[test]
    fn causes_are_printed_outer_first() {
        let e = Outer(std::io::Error::other("disk full"));
        assert_eq!(Causes(&e).to_string(), "writing x.json: disk full");
    }
}
