//! What another process's threads are doing, from the kernel's `/proc/PID/task/TID/`: for a
//! peer that is alive but silent (a hung controller or plant), the record of where each of
//! its threads was when the silence was found — running, runnable, asleep (and in which
//! kernel function), or stopped — and how long each has run and waited for a CPU.
//!
//! Linux only; elsewhere, or for a process that is gone, the snapshot is empty. Read once,
//! when a run ends on a hung peer: never on the hot path.

use serde::Serialize;

/// One thread of a process, as the kernel reports it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ThreadState {
    /// The thread id.
    pub tid: i32,
    /// Its name (`comm`).
    pub name: String,
    /// The scheduler state: `R` running or runnable, `S` asleep, `D` in an uninterruptible
    /// wait, `T` stopped (a signal), `t` stopped by a tracer, `Z` a zombie.
    pub state: char,
    /// Where it sleeps (`wchan`: the kernel function; empty when running or not readable).
    pub waits_in: String,
    /// The CPU it last ran on.
    pub last_cpu: Option<u32>,
    /// Time it has run (ns; `schedstat`).
    pub ran_ns: Option<u64>,
    /// Time it has been runnable but waited for a CPU (ns; `schedstat`).
    pub runqueue_wait_ns: Option<u64>,
}

impl ThreadState {
    /// `name (tid N): asleep in futex_wait_queue, ran 1.2 s, waited 3.4 ms for a CPU`.
    pub fn describe(&self) -> String {
        let what = match self.state {
            'R' => "running or runnable".to_string(),
            'S' | 'D' if !self.waits_in.is_empty() => format!("asleep in {}", self.waits_in),
            'S' | 'D' => "asleep".to_string(),
            'T' => "stopped by a signal".to_string(),
            't' => "stopped by a tracer".to_string(),
            'Z' => "a zombie".to_string(),
            c => format!("in state {c}"),
        };
        let times = match (self.ran_ns, self.runqueue_wait_ns) {
            (Some(r), Some(w)) => {
                format!(", ran {:.3} s, waited {:.1} ms for a CPU", r as f64 / 1e9, w as f64 / 1e6)
            }
            _ => String::new(),
        };
        format!("{} (tid {}): {what}{times}", self.name, self.tid)
    }
}

/// The threads of process `pid` now (empty if it is gone or `/proc` cannot be read).
pub fn threads_of(pid: i32) -> Vec<ThreadState> {
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    let mut out: Vec<ThreadState> = dir
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<i32>().ok())
        .filter_map(|tid| thread(pid, tid))
        .collect();
    out.sort_by_key(|t| t.tid);
    out
}

fn thread(pid: i32, tid: i32) -> Option<ThreadState> {
    let base = format!("/proc/{pid}/task/{tid}");
    let stat = std::fs::read_to_string(format!("{base}/stat")).ok()?;
    let (name, state, last_cpu) = parse_stat(&stat)?;
    let waits_in = std::fs::read_to_string(format!("{base}/wchan"))
        .ok()
        .map(|w| w.trim().to_string())
        .filter(|w| w != "0")
        .unwrap_or_default();
    let sched = std::fs::read_to_string(format!("{base}/schedstat")).ok();
    let mut fields = sched.as_deref().unwrap_or("").split_whitespace().map(|f| f.parse::<u64>().ok());
    let (ran_ns, runqueue_wait_ns) = (fields.next().flatten(), fields.next().flatten());
    Some(ThreadState { tid, name, state, waits_in, last_cpu, ran_ns, runqueue_wait_ns })
}

/// `pid (comm) S ppid … processor …` → (comm, state, processor). `comm` may hold spaces and
/// parentheses: it ends at the last `)`. The processor is field 39 (1-based), the 36th after
/// the state.
fn parse_stat(stat: &str) -> Option<(String, char, Option<u32>)> {
    let open = stat.find('(')?;
    let close = stat.rfind(')')?;
    let name = stat.get(open + 1..close)?.to_string();
    let mut rest = stat.get(close + 1..)?.split_whitespace();
    let state = rest.next()?.chars().next()?;
    let last_cpu = rest.nth(35).and_then(|f| f.parse().ok());
    Some((name, state, last_cpu))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stat_line_is_read_past_a_name_with_spaces_and_parentheses() {
        let line = "4242 (my (odd) name) S 1 4242 4242 0 -1 4194560 1 0 0 0 3 1 0 0 20 0 2 0 100 \
                    1000 200 18446744073709551615 1 1 0 0 0 0 0 0 0 0 0 0 17 1 0 0 0 0 0";
        assert_eq!(parse_stat(line), Some(("my (odd) name".to_string(), 'S', Some(1))));
        assert_eq!(parse_stat("garbage"), None);
    }

    /// Checked against a second source: a child stopped with SIGSTOP is `T` in the snapshot,
    /// and `ps` (procps, reading the same kernel's view through its own parser) says `T`
    /// too; continued and asleep in `sleep`, both say `S`.
    #[test]
    fn a_stopped_and_a_sleeping_process_are_told_apart() {
        let mut child = std::process::Command::new("sleep").arg("30").spawn().unwrap();
        let pid = i32::try_from(child.id()).unwrap();
        let ps_field = |pid: i32, field: &str| {
            let out = std::process::Command::new("ps").args(["-o", field, "-p", &pid.to_string()]).output();
            out.ok().and_then(|o| Some(String::from_utf8(o.stdout).ok()?.trim().to_string()))
        };
        let ps = |pid: i32| ps_field(pid, "stat=").and_then(|s| s.chars().next());
        let settle = |want: char| {
            for _ in 0..200 {
                if threads_of(pid).first().map(|t| t.state) == Some(want) {
                    return;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
        };
        settle('S');
        let t = threads_of(pid);
        assert_eq!(t.len(), 1, "{t:?}");
        assert_eq!((t[0].tid, t[0].name.as_str(), t[0].state), (pid, "sleep", 'S'));
        assert!(t[0].describe().starts_with("sleep (tid "), "{}", t[0].describe());
        if let Some(p) = ps(pid) {
            assert_eq!(p, 'S');
        }
        // The processor it last ran on (asleep, it does not move).
        if let Some(psr) = ps_field(pid, "psr=").and_then(|p| p.parse::<u32>().ok()) {
            assert_eq!(threads_of(pid)[0].last_cpu, Some(psr));
        }
        crate::sys::process::send_signal(pid, crate::sys::process::Signal::Stop).unwrap();
        settle('T');
        assert_eq!(threads_of(pid)[0].state, 'T');
        assert!(threads_of(pid)[0].describe().contains("stopped by a signal"));
        if let Some(p) = ps(pid) {
            assert_eq!(p, 'T');
        }
        crate::sys::process::send_signal(pid, crate::sys::process::Signal::Continue).unwrap();
        child.kill().unwrap();
        child.wait().unwrap();
        assert!(threads_of(pid).is_empty(), "a reaped process has no threads");
    }
}
