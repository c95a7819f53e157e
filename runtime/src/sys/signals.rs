//! SIGINT and SIGTERM end a run cleanly: a handler (installed by `signal-hook`) records the
//! signal in an atomic, and the loops poll [`termination_requested`] (one atomic load per
//! cycle) and finish the run with its files written.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

/// The last termination signal received (0: none), shared with the handlers.
static FLAG: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

fn flag() -> &'static Arc<AtomicUsize> {
    FLAG.get_or_init(|| Arc::new(AtomicUsize::new(0)))
}

/// The operating system refused the handler of a signal.
#[derive(Debug, thiserror::Error)]
#[error("installing the handler of signal {signal}")]
pub struct HandlerRefused {
    /// The signal's number.
    pub signal: i32,
    /// The operating system's error.
    #[source]
    pub source: std::io::Error,
}

/// Installs the SIGINT and SIGTERM handlers (idempotent: installing twice registers the
/// same flag twice, which is harmless).
///
/// # Errors
/// [`HandlerRefused`]: the operating system refused a handler.
pub fn install_termination_handler() -> Result<(), HandlerRefused> {
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let value = sig as usize;
        signal_hook::flag::register_usize(sig, Arc::clone(flag()), value)
            .map_err(|source| HandlerRefused { signal: sig, source })?;
    }
    Ok(())
}

/// The last termination signal received (0: none, or no handler installed). One atomic load;
/// never allocates (the flag is made by [`install_termination_handler`]).
fn last_signal() -> usize {
    FLAG.get().map_or(0, |f| f.load(Ordering::Acquire))
}

/// Whether SIGINT or SIGTERM arrived since [`install_termination_handler`].
#[inline]
pub fn termination_requested() -> bool {
    last_signal() != 0
}

/// The last termination signal received (0 if none).
pub fn termination_signal() -> i32 {
    i32::try_from(last_signal()).unwrap_or(0)
}
