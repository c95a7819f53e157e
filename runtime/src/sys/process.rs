//! Child processes that never outlive the run that started them, and signals to processes
//! (SIGTERM to hand an interruption on, SIGSTOP/SIGCONT for `--chaos`).
#![allow(unsafe_code)]

use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

/// `cmd` starts its process with SIGINT ignored (the disposition an `exec` keeps) until the
/// program installs a handler of its own. For a child that installs one early but not at once
/// — a Python interpreter, which otherwise turns a terminal's Ctrl-C in its first tens of
/// milliseconds into a `KeyboardInterrupt` traceback: a Ctrl-C then reaches the parent, which
/// hands the interruption on as SIGTERM.
pub fn start_with_sigint_ignored(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: the closure runs in the child between fork and exec and calls only signal(2),
    // which is async-signal-safe; it touches no memory of the parent.
    unsafe {
        cmd.pre_exec(|| {
            if libc::signal(libc::SIGINT, libc::SIG_IGN) == libc::SIG_ERR {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// Kills and reaps a child on drop (a run that fails half-way leaves no process).
#[derive(Debug)]
pub struct ChildGuard(pub Option<Child>);

impl ChildGuard {
    /// Guards `child`.
    pub fn new(child: Child) -> Self {
        Self(Some(child))
    }

    /// The child's process id (0 once it has been reaped).
    pub fn id(&self) -> u32 {
        self.0.as_ref().map_or(0, Child::id)
    }

    /// Waits for the child to exit (up to `timeout`), then kills it if it has not.
    ///
    /// # Errors
    /// Waiting failed (the operating system's error).
    pub fn finish(&mut self, timeout: Duration) -> std::io::Result<Option<ExitStatus>> {
        if let Some(c) = self.0.as_mut() {
            let start = Instant::now();
            loop {
                if let Some(s) = c.try_wait()? {
                    self.0 = None;
                    return Ok(Some(s));
                }
                if start.elapsed() > timeout {
                    let _ = c.kill();
                    let s = c.wait()?;
                    self.0 = None;
                    return Ok(Some(s));
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        Ok(None)
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(c) = self.0.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// `exit code N`, `killed by signal N` or `unknown`.
pub fn exit_text(st: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (st.code(), st.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(sig)) => format!("killed by signal {sig}"),
        _ => "unknown".into(),
    }
}

/// A signal this program sends to another process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// End cleanly (the run is interrupted, its files written).
    Terminate,
    /// Freeze (`--chaos`).
    Stop,
    /// Thaw after [`Signal::Stop`].
    Continue,
}

/// Sends `sig` to process `pid`. Refuses pids that name no single other process (0, 1,
/// negative ones, this process).
///
/// # Errors
/// The pid is refused, or the process does not exist.
pub fn send_signal(pid: i32, sig: Signal) -> std::io::Result<()> {
    let own = i32::try_from(std::process::id()).unwrap_or(0);
    if pid <= 1 || pid == own {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, format!("no signal to pid {pid}")));
    }
    let n = match sig {
        Signal::Terminate => libc::SIGTERM,
        Signal::Stop => libc::SIGSTOP,
        Signal::Continue => libc::SIGCONT,
    };
    // SAFETY: kill takes a pid and a signal number; no memory is passed.
    if unsafe { libc::kill(pid, n) } == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// This process's parent's pid.
pub fn parent_pid() -> i32 {
    i32::try_from(std::os::unix::process::parent_id()).unwrap_or(0)
}
