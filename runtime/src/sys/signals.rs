//! SIGINT and SIGTERM end a run cleanly: a handler (installed by `signal-hook`) records the
//! signal in an atomic, and the loops poll [`termination_requested`] (one atomic load per
//! cycle) and finish the run with its files written.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use anyhow::{Context, Result};

/// The last termination signal received (0: none), shared with the handlers.
static FLAG: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

fn flag() -> &'static Arc<AtomicUsize> {
    FLAG.get_or_init(|| Arc::new(AtomicUsize::new(0)))
}

/// Installs the SIGINT and SIGTERM handlers (idempotent: installing twice registers the
/// same flag twice, which is harmless).
///
/// # Errors
/// The operating system refused a handler.
pub fn install_termination_handler() -> Result<()> {
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let value = sig as usize;
        signal_hook::flag::register_usize(sig, Arc::clone(flag()), value)
            .with_context(|| format!("installing the handler of signal {sig}"))?;
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
