//! One process per role and demo name, decided atomically: an exclusive `flock` on
//! `/tmp/companion/NAME.ROLE.lock`, taken before anything of the demo exists and held for
//! the process's life (the kernel drops it when the process ends, however it ends).
//!
//! Looking for a live iceoryx2 node of the same name first and creating one's own afterwards
//! leaves a window in which two demos started at the same moment both find the name free;
//! then one demo's controller could drive the other's plant. A lock has no such window: of
//! two processes asking for it at once, exactly one gets it.
//!
//! The lock files are owner-only (`0600`: another user can neither read the holder's pid nor
//! take the lock first) and removed when their holder ends cleanly (dropping the lock), so
//! that they do not pile up one per demo name. Removing a file another process may have
//! opened is safe because a lock counts only on the file that is at the path: after `flock`
//! succeeds, the holder checks that the path still names the file it locked, and starts over
//! if not (the previous holder removed it in between).
//!
//! `companion hil` takes both roles' locks before it starts its plant (which runs under its
//! parent's locks), so a second `hil`, `plant` or `control` with that name stops at once with
//! [`NameInUse`]; `companion plant` and `companion control` each take their own.
#![allow(unsafe_code)]

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek};
use std::os::fd::AsRawFd;
use std::os::unix::fs::{FileExt, MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The two roles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Publishes measurements, subscribes to commands.
    Plant,
    /// Publishes commands, subscribes to measurements.
    Control,
}

impl Role {
    /// `plant` or `control`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Plant => "plant",
            Self::Control => "control",
        }
    }

    /// The other role.
    pub fn peer(self) -> Self {
        match self {
            Self::Plant => Self::Control,
            Self::Control => Self::Plant,
        }
    }
}

/// A demo with this name is already running.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "a demo named '{name}' is already running (its {role} is process {pid}); stop it or choose another --name"
)]
pub struct NameInUse {
    /// The demo's name.
    pub name: String,
    /// The role found alive.
    pub role: &'static str,
    /// Its process id (0 if unknown).
    pub pid: i32,
}

/// A demo name that is not 1–32 characters of `A–Z a–z 0–9 _ -`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("--name must be 1 to 32 characters of A-Z, a-z, 0-9, '_' and '-', got {0:?}")]
pub struct NameError(pub String);

/// A demo's name, checked once where it is given (`--name`): 1–32 characters of
/// `A–Z a–z 0–9 _ -`, since it names lock files, iceoryx2 services and Zenoh key expressions.
/// Whatever takes one (the lock, the transports) relies on that and checks nothing again.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct DemoName(String);

impl DemoName {
    /// Checks `name`.
    ///
    /// # Errors
    /// [`NameError`]: the name is empty, too long, or has another character.
    pub fn new(name: &str) -> Result<Self, NameError> {
        let ok = !name.is_empty()
            && name.len() <= 32
            && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
        if ok {
            Ok(Self(name.to_string()))
        } else {
            Err(NameError(name.to_string()))
        }
    }

    /// The name.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl std::ops::Deref for DemoName {
    type Target = str;

    fn deref(&self) -> &str {
        &self.0
    }
}

impl std::fmt::Display for DemoName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// Why [`NameLock::acquire`] did not take the lock.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another process holds the lock.
    #[error(transparent)]
    NameInUse(#[from] NameInUse),
    /// The lock file or its folder cannot be made, opened, locked, read or written: `what`
    /// was being done (e.g. `creating /tmp/companion`), `source` the operating system's error.
    #[error("{what}")]
    File {
        /// What was being done, naming the file.
        what: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
}

impl LockError {
    /// The demo found running, if that is the error.
    pub fn name_in_use(&self) -> Option<&NameInUse> {
        match self {
            Self::NameInUse(n) => Some(n),
            _ => None,
        }
    }
}

/// `what` (made only on failure) around an I/O error.
fn file_error(what: impl FnOnce() -> String) -> impl FnOnce(std::io::Error) -> LockError {
    move |source| LockError::File { what: what(), source }
}

/// The folder of the lock files.
pub const LOCK_DIR: &str = "/tmp/companion";

/// A held lock on one role of a demo name (released when dropped).
#[derive(Debug)]
pub struct NameLock {
    file: File,
    /// The demo's name.
    pub name: DemoName,
    /// The role.
    pub role: Role,
}

fn path(name: &str, role: Role) -> PathBuf {
    PathBuf::from(LOCK_DIR).join(format!("{name}.{}.lock", role.as_str()))
}

/// Tries `flock(LOCK_EX | LOCK_NB)`: `Ok(true)` if taken, `Ok(false)` if another process
/// holds it.
fn try_flock(f: &File) -> std::io::Result<bool> {
    // SAFETY: flock takes a file descriptor (valid: `f` is open) and flags; no memory.
    let r = unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if r == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(false)
    } else {
        Err(e)
    }
}

impl NameLock {
    /// Takes the lock of `role` in demo `name`.
    ///
    /// # Errors
    /// [`LockError::NameInUse`] if another process holds it (with its pid when known), or
    /// [`LockError::File`] if the lock file cannot be made.
    pub fn acquire(name: &DemoName, role: Role) -> Result<Self, LockError> {
        std::fs::create_dir_all(LOCK_DIR).map_err(file_error(|| format!("creating {LOCK_DIR}")))?;
        let p = path(name, role);
        let file = loop {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .mode(0o600)
                .open(&p)
                .map_err(file_error(|| format!("opening the lock file {}", p.display())))?;
            if !try_flock(&file).map_err(file_error(|| format!("locking {}", p.display())))? {
                let pid = holder_of_locked(&mut file);
                return Err(NameInUse { name: name.to_string(), role: role.as_str(), pid }.into());
            }
            // The previous holder may have removed the file between our open and our lock:
            // then the lock is on a file nobody else will find; take the one at the path.
            let here = file.metadata().map_err(file_error(|| format!("reading {}", p.display())))?;
            if std::fs::metadata(&p).is_ok_and(|m| m.ino() == here.ino() && m.dev() == here.dev()) {
                break file;
            }
        };
        // A file left by an older version (0644) becomes owner-only too.
        file.set_permissions(std::fs::Permissions::from_mode(0o600))
            .map_err(file_error(|| format!("making {} owner-only", p.display())))?;
        // The holder's pid, for the message of whoever finds the lock taken: one write of a
        // fixed width over whatever was there, so a reader finds either the old content or
        // the whole pid, never an emptied file (the length is set after, for a longer old
        // content of an older version).
        let pid = format!("{:<PID_WIDTH$}\n", std::process::id());
        file.write_all_at(pid.as_bytes(), 0)
            .and_then(|()| file.set_len(pid.len() as u64))
            .map_err(file_error(|| format!("writing {}", p.display())))?;
        Ok(Self { file, name: name.clone(), role })
    }

    /// The pid written in the lock file of `role` in demo `name` (its holder's, or the last
    /// holder's: a lock file outlives its lock).
    ///
    /// # Errors
    /// No such file, or no pid in it ([`std::io::ErrorKind::InvalidData`]).
    pub fn holder(name: &DemoName, role: Role) -> std::io::Result<i32> {
        let mut f = File::open(path(name, role))?;
        holder_of(&mut f)
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidData, "no pid in the lock file"))
    }
}

impl Drop for NameLock {
    /// Removes the lock file, still locked (see the module's doc for why that is safe), then
    /// releases the lock by closing it.
    fn drop(&mut self) {
        let p = path(&self.name, self.role);
        let ours = match (self.file.metadata(), std::fs::metadata(&p)) {
            (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
            _ => false,
        };
        if ours {
            let _ = std::fs::remove_file(&p);
        }
    }
}

/// The width of the pid in a lock file (a Linux pid has at most 7 digits).
const PID_WIDTH: usize = 10;

/// How long a process that found a lock taken waits for its holder's pid to appear.
const PID_WAIT: Duration = Duration::from_millis(200);

/// The pid of the process that holds the lock on `f`: a live pid written in the file. Its
/// holder writes it just after taking the lock, so for a moment the file may still be empty
/// (just created) or carry the pid of an earlier holder that died: then the pid is read
/// again for up to [`PID_WAIT`]. 0 if none appeared by then.
fn holder_of_locked(f: &mut File) -> i32 {
    let start = Instant::now();
    loop {
        let pid = holder_of(f);
        match pid {
            Some(p) if alive(p) => return p,
            _ if start.elapsed() >= PID_WAIT => return pid.unwrap_or(0),
            _ => std::thread::sleep(Duration::from_millis(1)),
        }
    }
}

/// Whether a process of this pid exists (signal 0: nothing is sent).
fn alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 only checks that the process exists; no memory.
    pid > 0
        && (unsafe { libc::kill(pid, 0) } == 0
            || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM))
}

fn holder_of(f: &mut File) -> Option<i32> {
    let mut s = String::new();
    f.rewind().ok()?;
    f.read_to_string(&mut s).ok()?;
    s.trim().parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        assert_eq!(DemoName::new("demo").map(|n| n.to_string()), Ok("demo".to_string()));
        assert_eq!(DemoName::new("a_b-9").unwrap().as_str(), "a_b-9");
        assert!(DemoName::new(&"x".repeat(32)).is_ok());
        for bad in ["", "a/b", &"x".repeat(33)] {
            assert_eq!(DemoName::new(bad), Err(NameError(bad.to_string())), "{bad:?}");
        }
        assert_eq!(
            NameError("bad/name".into()).to_string(),
            r#"--name must be 1 to 32 characters of A-Z, a-z, 0-9, '_' and '-', got "bad/name""#
        );
    }

    #[test]
    fn a_lock_is_held_once_and_released_when_dropped() {
        let name = DemoName::new(&format!("locktest-{}", std::process::id())).unwrap();
        let a = NameLock::acquire(&name, Role::Plant).unwrap();
        // Another open file description of the same file is refused, even in this process.
        let e = NameLock::acquire(&name, Role::Plant).unwrap_err();
        let LockError::NameInUse(n) = &e else { panic!("not NameInUse: {e}") };
        assert_eq!(e.name_in_use(), Some(n));
        assert_eq!(
            e.to_string(),
            format!(
                "a demo named '{name}' is already running (its plant is process {}); stop it or choose another \
                 --name",
                n.pid
            )
        );
        assert_eq!((n.role, n.pid), ("plant", i32::try_from(std::process::id()).unwrap()));
        assert_eq!(NameLock::holder(&name, Role::Plant).unwrap(), n.pid);
        // The other role is another lock.
        let b = NameLock::acquire(&name, Role::Control).unwrap();
        // Owner-only.
        let mode = std::fs::metadata(path(&name, Role::Plant)).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        drop(a);
        // Removed when released.
        assert!(!path(&name, Role::Plant).exists());
        let a = NameLock::acquire(&name, Role::Plant).unwrap();
        drop((a, b));
        for role in [Role::Plant, Role::Control] {
            assert!(!path(&name, role).exists(), "{role:?}");
        }
        // A file left 0644 by an older version is made owner-only.
        std::fs::write(path(&name, Role::Plant), "1").unwrap();
        std::fs::set_permissions(path(&name, Role::Plant), std::fs::Permissions::from_mode(0o644)).unwrap();
        let a = NameLock::acquire(&name, Role::Plant).unwrap();
        let mode = std::fs::metadata(path(&name, Role::Plant)).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        drop(a);
    }

    #[test]
    fn the_loser_of_a_race_names_the_winners_pid() {
        // Users saw "its control is process 0": the loser read the lock file while the winner
        // had created or emptied it but not yet written its pid. Two threads race for one
        // name many times; the loser must always name this process.
        let name = DemoName::new(&format!("lockrace-{}", std::process::id())).unwrap();
        let me = i32::try_from(std::process::id()).unwrap();
        let mut pids = Vec::new();
        for _ in 0..300 {
            let barrier = std::sync::Barrier::new(2);
            let (a, b) = std::thread::scope(|s| {
                let go = || {
                    barrier.wait();
                    NameLock::acquire(&name, Role::Control)
                };
                let a = s.spawn(go);
                let b = s.spawn(go);
                (a.join().unwrap(), b.join().unwrap())
            });
            // The winner holds its lock until both are back: exactly one loses.
            match (&a, &b) {
                (Ok(_), Err(e)) | (Err(e), Ok(_)) => {
                    pids.push(e.name_in_use().expect("NameInUse").pid);
                }
                _ => panic!("not exactly one winner: {:?} {:?}", a.is_ok(), b.is_ok()),
            }
        }
        let wrong: Vec<i32> = pids.iter().copied().filter(|p| *p != me).collect();
        assert!(
            wrong.is_empty(),
            "{} of {} losers named another pid: {:?}",
            wrong.len(),
            pids.len(),
            &wrong[..wrong.len().min(10)]
        );
    }
}
