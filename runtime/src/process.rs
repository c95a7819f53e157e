//! Child processes that never outlive the run that started them.

use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

use anyhow::Result;

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
    /// Waiting failed.
    pub fn finish(&mut self, timeout: Duration) -> Result<Option<ExitStatus>> {
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
