//! The state a study's parallel runs share behind a [`Mutex`], and the one error taking it
//! can give: a run that panicked while holding it ([`Poisoned`]).

use std::sync::{Mutex, MutexGuard};

/// A lock of a study's shared state is poisoned: a thread panicked while holding it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{what} poisoned")]
pub struct Poisoned {
    /// Which lock (`lock`, `journal lock`).
    pub what: &'static str,
}

/// The state behind `m`, or [`Poisoned`] (named `what`).
///
/// # Errors
/// A thread panicked while holding the lock.
pub fn lock<'a, T>(m: &'a Mutex<T>, what: &'static str) -> Result<MutexGuard<'a, T>, Poisoned> {
    m.lock().map_err(|_| Poisoned { what })
}

/// The state `m` held, or [`Poisoned`].
///
/// # Errors
/// A thread panicked while holding the lock.
pub fn into_inner<T>(m: Mutex<T>) -> Result<T, Poisoned> {
    m.into_inner().map_err(|_| Poisoned { what: "lock" })
}
