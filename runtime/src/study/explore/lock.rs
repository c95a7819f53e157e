//! The shard lock: one process at a time on an exploration's output folder.
//!
//! Two processes on one folder (a job array task resubmitted while the first still runs, a
//! command typed twice) would both append to `journal.csv`, and the first to finish would
//! remove the journal under the other. So a run holds an exclusive `flock(2)` on the folder's
//! `explore.json` (the file every run writes first and never removes) from before it reads
//! anything until it returns; a second run on the same folder is refused at once with
//! [`Busy`]. The kernel releases the lock when the holder exits, however it exits (a kill,
//! `scancel`, a power cut of the holder's node), so there is no stale lock to remove by hand.
//!
//! [`merge`](super::merge) takes the same lock shared while it reads a shard, which tells a
//! shard still running (lock held) from one that died unfinished (lock free).
//!
//! On Linux, `flock` on NFS is emulated by the server's POSIX locks (NFSv4, or v3 with
//! `lockd`); Lustre needs the `flock` mount option. Where the file system has no locks at
//! all the run goes on unlocked and says so ([`Lock::Unsupported`]).

// One libc call on a file descriptor the `File` owns (std's `File::try_lock` is newer than
// the workspace's minimum Rust).
#![allow(unsafe_code)]

use std::fs::File;
use std::io;
use std::os::fd::AsRawFd as _;
use std::path::PathBuf;

/// Another process holds the lock of an exploration's output folder: it is running there.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Busy {
    /// The folder.
    pub folder: PathBuf,
}

impl std::fmt::Display for Busy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "another process is running this exploration in {} (it holds the lock on its explore.json); \
             not started. Wait for it to end (or stop it) and run the command again to resume",
            self.folder.display()
        )
    }
}

impl std::error::Error for Busy {}

/// What trying to lock a file gave.
#[derive(Debug, PartialEq, Eq)]
pub enum Lock {
    /// Locked: held until the file is closed.
    Held,
    /// Another open file (this process's or another's) holds a conflicting lock.
    Busy,
    /// The file system does not support locks.
    Unsupported,
}

/// Tries to lock `file` without waiting: exclusively, or shared (`exclusive = false`).
///
/// # Errors
/// The system call failed for another reason than a conflicting or unsupported lock.
pub fn try_lock(file: &File, exclusive: bool) -> io::Result<Lock> {
    let op = if exclusive { libc::LOCK_EX } else { libc::LOCK_SH } | libc::LOCK_NB;
    loop {
        // SAFETY: flock on a descriptor `file` keeps open for the duration of the call.
        if unsafe { libc::flock(file.as_raw_fd(), op) } == 0 {
            return Ok(Lock::Held);
        }
        let e = io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EINTR) => {}
            Some(libc::EWOULDBLOCK) => return Ok(Lock::Busy),
            Some(libc::ENOLCK | libc::EOPNOTSUPP | libc::ENOSYS) => return Ok(Lock::Unsupported),
            _ => return Err(e),
        }
    }
}
