//! Real-time process setup and the few system calls the loop needs — the crate's only
//! `unsafe` code, kept small: each call is a plain libc call on valid arguments.
//!
//! What `--rt` does ([`apply`]), each step independent, each failure one warning line:
//!
//! - `mlockall(MCL_CURRENT | MCL_FUTURE)`: no page fault on a code or data page in the loop;
//! - pins the calling thread to one CPU (`sched_setaffinity`), on a 2-core machine one core for
//!   the plant and the other for the controller;
//! - `SCHED_FIFO` at the given priority for the calling thread only (helper threads — the
//!   CSV writer and the progress line — stay `SCHED_OTHER`);
//! - pre-faults the stack (touches 512 KiB below the current frame) so that the loop's first
//!   deep call does not fault.
//!
//! Time: [`monotonic_ns`] reads `CLOCK_MONOTONIC` (through the vDSO: no system call with the
//! `tsc` or `kvm-clock` clock sources); it is the same clock in every process on the machine,
//! which the wire's timestamps rely on. [`sleep_until_ns`] sleeps to an absolute deadline
//! (`clock_nanosleep(TIMER_ABSTIME)`), so sleeping never accumulates drift.
#![allow(unsafe_code)]

/// `CLOCK_MONOTONIC` in nanoseconds.
#[inline]
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// `CLOCK_REALTIME` in nanoseconds since the Unix epoch: the system clock, ROS 2's time
/// (message stamps), which may step; durations are measured with [`monotonic_ns`].
#[inline]
pub fn realtime_ns() -> i64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_REALTIME always exists.
    unsafe { libc::clock_gettime(libc::CLOCK_REALTIME, &mut ts) };
    ts.tv_sec * 1_000_000_000 + ts.tv_nsec
}

/// `CLOCK_MONOTONIC_RAW` in nanoseconds: the hardware clock without NTP's frequency
/// corrections — a second clock to check measurements made with [`monotonic_ns`].
#[inline]
pub fn raw_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC_RAW)
}

/// Clock `id` in nanoseconds.
#[inline]
fn clock_ns(id: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; both clocks used here exist on Linux
    // (CLOCK_MONOTONIC_RAW since 2.6.28).
    unsafe { libc::clock_gettime(id, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleeps until `CLOCK_MONOTONIC` reaches `t_ns` (returns at once if it has), resuming after
/// signals.
pub fn sleep_until_ns(t_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (t_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (t_ns % 1_000_000_000) as libc::c_long,
    };
    loop {
        // SAFETY: `ts` is a valid timespec; the remaining-time pointer may be null with
        // TIMER_ABSTIME.
        let r = unsafe {
            libc::clock_nanosleep(libc::CLOCK_MONOTONIC, libc::TIMER_ABSTIME, &ts, std::ptr::null_mut())
        };
        if r != libc::EINTR {
            return;
        }
        if crate::sys::signals::termination_requested() {
            return;
        }
    }
}

/// What [`apply`] should do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtConfig {
    /// `SCHED_FIFO` priority (1–99).
    pub priority: i32,
    /// The CPU to pin the calling thread to, if any.
    pub cpu: Option<usize>,
    /// Lock all memory.
    pub lock_memory: bool,
    /// Bytes of stack to pre-fault.
    pub prefault_stack: usize,
    /// Threads the calling thread starts afterwards inherit its `SCHED_FIFO` priority (a
    /// process whose library threads carry its messages: the ROS 2 node's RustDDS); otherwise
    /// they get the normal scheduler (`SCHED_RESET_ON_FORK`).
    pub inherited: bool,
}

impl RtConfig {
    /// Priority 80, memory locked, 512 KiB of stack pre-faulted, pinned to `cpu`.
    pub fn with_cpu(cpu: Option<usize>) -> Self {
        Self { priority: 80, cpu, lock_memory: true, prefault_stack: 512 * 1024, inherited: false }
    }
}

/// What [`apply`] achieved: one entry per step that failed, as a warning line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RtReport {
    /// Warnings (a missing privilege, a CPU that does not exist).
    pub warnings: Vec<String>,
    /// Whether `SCHED_FIFO` is in force for the calling thread.
    pub fifo: bool,
    /// Whether memory is locked.
    pub locked: bool,
    /// The CPU the calling thread is pinned to.
    pub pinned: Option<usize>,
}

fn errno_text() -> String {
    std::io::Error::last_os_error().to_string()
}

/// Applies `cfg` to the calling thread (and, for `mlockall`, the process). Never fails: each
/// step that cannot be done adds a warning and the run goes on.
pub fn apply(cfg: &RtConfig) -> RtReport {
    let mut rep = RtReport::default();
    if cfg.lock_memory {
        // SAFETY: mlockall takes flags only.
        let r = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if r == 0 {
            rep.locked = true;
        } else {
            rep.warnings.push(format!("--rt: mlockall failed ({}); memory may page-fault", errno_text()));
        }
    }
    if let Some(cpu) = cfg.cpu {
        let n = online_cpus();
        if cpu >= n.max(1) || cpu >= libc::CPU_SETSIZE as usize {
            rep.warnings.push(format!("--rt: CPU {cpu} does not exist ({n} online); not pinned"));
        } else {
            // SAFETY: an all-zero cpu_set_t is a valid empty set; CPU_SET writes inside it
            // (cpu < CPU_SETSIZE checked above); sched_setaffinity reads `size_of` bytes.
            let r = unsafe {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(cpu, &mut set);
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
            };
            if r == 0 {
                rep.pinned = Some(cpu);
            } else {
                rep.warnings.push(format!("--rt: pinning to CPU {cpu} failed ({})", errno_text()));
            }
        }
    }
    let param = libc::sched_param { sched_priority: cfg.priority };
    // SCHED_RESET_ON_FORK (unless `inherited`): threads and processes started later get the
    // normal scheduler, not this real-time priority. On Linux, pid 0 names the calling thread.
    // SAFETY: `param` is a valid sched_param.
    let policy = if cfg.inherited { libc::SCHED_FIFO } else { libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK };
    let r = unsafe { libc::sched_setscheduler(0, policy, &param) };
    if r == 0 {
        rep.fifo = true;
    } else {
        rep.warnings.push(format!(
            "--rt: SCHED_FIFO priority {} refused ({}); running with the normal scheduler",
            cfg.priority,
            errno_text()
        ));
    }
    if cfg.prefault_stack > 0 {
        prefault_stack(cfg.prefault_stack);
    }
    rep
}

impl RtReport {
    /// The warnings, if any, as one line (`who`: the process's role).
    pub fn warning(&self, who: &str) -> Option<String> {
        (!self.warnings.is_empty()).then(|| format!("{who}: {}", self.warnings.join("; ")))
    }
}

/// Puts the calling thread back on the normal scheduler and every CPU (the end of a real-time
/// section; memory stays locked).
pub fn reset_thread() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: `param` is a valid sched_param; SCHED_OTHER needs priority 0.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) };
    let n = online_cpus().min(libc::CPU_SETSIZE as usize);
    // SAFETY: as in `apply`: a zeroed set, CPU_SET below CPU_SETSIZE.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for cpu in 0..n {
            libc::CPU_SET(cpu, &mut set);
        }
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

/// Touches `bytes` of stack below the current frame so later calls find it mapped (and, after
/// `mlockall`, locked).
#[inline(never)]
fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 16 * 1024;
    fn touch(left: usize) {
        let mut buf = [0u8; CHUNK];
        std::hint::black_box(&mut buf);
        if left > CHUNK {
            touch(left - CHUNK);
        }
        std::hint::black_box(&buf);
    }
    touch(bytes);
}

/// The online CPUs of the machine (not of the calling thread's affinity mask, which
/// `std::thread::available_parallelism` reports once a thread is pinned).
pub fn online_cpus() -> usize {
    // SAFETY: sysconf takes a constant and has no other effect.
    let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
    usize::try_from(n).ok().filter(|n| *n > 0).unwrap_or(1)
}

/// The kernel's real-time throttling (`sched_rt_runtime_us` / `sched_rt_period_us`), if readable:
/// a `SCHED_FIFO` thread that never sleeps is paused for the rest of each period once it has
/// used the runtime, whenever a normal task waits on its CPU.
pub fn rt_throttling() -> Option<(i64, i64)> {
    let read = |p: &str| std::fs::read_to_string(p).ok()?.trim().parse::<i64>().ok();
    Some((read("/proc/sys/kernel/sched_rt_runtime_us")?, read("/proc/sys/kernel/sched_rt_period_us")?))
}

/// The machine's CPU pressure: the share of the last 10 s in which some runnable task waited
/// for a CPU (`/proc/pressure/cpu`, "some avg10", in %), if the kernel reports it. Reads the
/// file into a buffer on the stack: a few system calls, no allocation.
pub fn cpu_pressure() -> Option<f64> {
    use std::io::Read;
    let mut buf = [0u8; 256];
    let mut f = std::fs::File::open("/proc/pressure/cpu").ok()?;
    let n = f.read(&mut buf).ok()?;
    parse_pressure(buf.get(..n)?)
}

/// "some avg10=X ..." → X.
fn parse_pressure(text: &[u8]) -> Option<f64> {
    let text = std::str::from_utf8(text).ok()?;
    let line = text.lines().find(|l| l.starts_with("some "))?;
    let field = line.split_whitespace().find_map(|f| f.strip_prefix("avg10="))?;
    field.parse().ok()
}

/// How long the calling thread has been runnable but waiting for a CPU since it started (ns):
/// the kernel's own account (`/proc/thread-self/schedstat`, its second field, `run_delay`),
/// if it keeps one. A thread that sleeps does not accrue it; a thread that wants to run while
/// others hold the CPUs does — so it tells a starved loop from one that overslept its own
/// wait. Reads into a buffer on the stack: a few system calls, no allocation.
pub fn runqueue_wait_ns() -> Option<u64> {
    use std::io::Read;
    let mut buf = [0u8; 128];
    let mut f = std::fs::File::open("/proc/thread-self/schedstat").ok()?;
    let n = f.read(&mut buf).ok()?;
    parse_schedstat(buf.get(..n)?)
}

/// "on-CPU run_delay timeslices" → run_delay.
fn parse_schedstat(text: &[u8]) -> Option<u64> {
    std::str::from_utf8(text).ok()?.split_whitespace().nth(1)?.parse().ok()
}

/// Sets the calling thread's timer slack to 1 ns (threads it creates afterwards inherit it).
///
/// Linux lets a normal thread's timed sleep end up to 50 µs late by default, so that wake-ups
/// can be merged; for `--wait hybrid|event` that is 50 µs of every cycle's slack. On this
/// project's VMs it moved the median lateness of a 1 kHz `clock_nanosleep` from ~80 µs to
/// ~27 µs. (`SCHED_FIFO` threads have no slack anyway.) Never fails: without it, waits are
/// only later.
pub fn tight_timer_slack() {
    // SAFETY: PR_SET_TIMERSLACK takes one integer argument and touches no memory.
    let _ = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) };
}

/// Waits until `fd` is readable or `timeout` has passed; `true` if it is readable. A signal
/// ends the wait early (`false`: the caller re-checks).
///
/// This is how a transport's event is waited for with a short timeout: `ppoll` times out on
/// a high-resolution timer (within the timer slack). A blocking read with `SO_RCVTIMEO` —
/// how iceoryx2's `Listener::timed_wait` waits on its Unix socket — rounds its timeout up to
/// whole scheduler ticks: asked for 50 µs to 2 ms it returned after 8 ms on this project's
/// machines (`CONFIG_HZ=250`), so every missed deadline cost the plant 8 ms of its schedule.
///
/// # Errors
/// `ppoll` failed (not for a signal).
pub fn wait_readable(
    fd: &iceoryx2::prelude::FileDescriptor,
    timeout: std::time::Duration,
) -> std::io::Result<bool> {
    // SAFETY: the descriptor is borrowed from its owner for this call only: it is polled, not
    // stored or closed (what `native_handle` asks).
    let raw = unsafe { fd.native_handle() };
    let mut p = libc::pollfd { fd: raw, events: libc::POLLIN, revents: 0 };
    let ts = libc::timespec {
        tv_sec: timeout.as_secs() as libc::time_t,
        tv_nsec: libc::c_long::from(timeout.subsec_nanos()),
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask.
    let r = unsafe { libc::ppoll(&mut p, 1, &ts, std::ptr::null()) };
    if r < 0 {
        let e = std::io::Error::last_os_error();
        return if e.raw_os_error() == Some(libc::EINTR) { Ok(false) } else { Err(e) };
    }
    Ok(r > 0 && p.revents & libc::POLLIN != 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_clock_moves_forward_and_sleep_reaches_deadline() {
        let a = monotonic_ns();
        sleep_until_ns(a + 2_000_000);
        let b = monotonic_ns();
        assert!(b >= a + 2_000_000, "slept {} ns", b - a);
        // A deadline in the past returns at once (no assertion on time: only that it returns).
        sleep_until_ns(a);
    }

    #[test]
    fn cpu_pressure_is_read_from_the_kernels_line() {
        let text = b"some avg10=98.03 avg60=98.21 avg300=96.91 total=5320524078\nfull avg10=0.00 avg60=0.00";
        assert_eq!(parse_pressure(text), Some(98.03));
        assert_eq!(parse_pressure(b"full avg10=1.00"), None);
        assert_eq!(parse_pressure(b"some avg60=1.00"), None);
        // Whatever the machine, a reading is a percentage.
        if let Some(p) = cpu_pressure() {
            assert!((0.0..=100.0).contains(&p), "{p}");
        }
    }

    #[test]
    fn the_runqueue_wait_is_the_schedstat_lines_second_field() {
        assert_eq!(parse_schedstat(b"5795492 2999649 12\n"), Some(2_999_649));
        assert_eq!(parse_schedstat(b"5795492"), None);
        assert_eq!(parse_schedstat(b"a b c"), None);
    }

    /// The second method: a thread made to share one CPU with a busy one waits for it. Pinned
    /// to the same CPU, a thread that spins for 200 ms of its own CPU time has, by then, been
    /// kept waiting by the busy one — the kernel splits one CPU between the two, so the wait
    /// comes near the CPU time; asked here only for a fifth of it (a lower bound that a
    /// loaded machine only makes truer).
    #[test]
    fn a_thread_sharing_its_cpu_with_a_busy_one_accrues_runqueue_wait() {
        if runqueue_wait_ns().is_none() {
            eprintln!("SKIPPED: this kernel keeps no schedstat");
            return;
        }
        let cpu = current_cpu();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let busy = {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let _ = pin_to(cpu);
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    core::hint::spin_loop();
                }
            })
        };
        let waited = std::thread::spawn(move || {
            let _ = pin_to(cpu);
            let before = runqueue_wait_ns().unwrap();
            let cpu0 = thread_cpu_ns();
            while thread_cpu_ns() - cpu0 < 200_000_000 {
                core::hint::spin_loop();
            }
            runqueue_wait_ns().unwrap() - before
        })
        .join()
        .unwrap();
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        busy.join().unwrap();
        assert!(waited >= 40_000_000, "waited {waited} ns for the CPU in 200 ms of CPU time");
    }

    fn current_cpu() -> usize {
        // SAFETY: sched_getcpu takes no arguments.
        usize::try_from(unsafe { libc::sched_getcpu() }).unwrap_or(0)
    }

    fn pin_to(cpu: usize) -> bool {
        // SAFETY: a zeroed cpu_set_t is a valid empty set; CPU_SET writes within it.
        unsafe {
            let mut set: libc::cpu_set_t = core::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) == 0
        }
    }

    fn thread_cpu_ns() -> u64 {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: ts is a valid timespec to write.
        unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        u64::try_from(ts.tv_sec).unwrap_or(0) * 1_000_000_000 + u64::try_from(ts.tv_nsec).unwrap_or(0)
    }

    #[test]
    fn the_timer_slack_becomes_one_nanosecond() {
        let slack = std::thread::spawn(|| {
            tight_timer_slack();
            // SAFETY: PR_GET_TIMERSLACK takes no pointer and returns the slack in ns.
            unsafe { libc::prctl(libc::PR_GET_TIMERSLACK) }
        })
        .join()
        .unwrap();
        assert_eq!(slack, 1);
    }

    #[test]
    fn apply_without_privileges_never_fails() {
        // Whatever the privileges, apply returns a report; an absurd CPU only warns.
        let rep = apply(&RtConfig {
            priority: 1,
            cpu: Some(100_000),
            lock_memory: false,
            prefault_stack: 64 * 1024,
            inherited: false,
        });
        assert!(rep.warnings.iter().any(|w| w.contains("CPU 100000")));
        // Back to the normal scheduler so the test harness is not left real-time.
        reset_thread();
        // Pinning does not change what the machine has, and reset gives every CPU back.
        let n = online_cpus();
        let rep = apply(&RtConfig {
            priority: 1,
            cpu: Some(0),
            lock_memory: false,
            prefault_stack: 0,
            inherited: false,
        });
        assert_eq!(online_cpus(), n);
        reset_thread();
        if rep.pinned.is_some() {
            let back = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
            assert_eq!(back, n, "reset_thread restores every CPU");
        }
    }

    #[test]
    fn a_descriptor_is_readable_once_written_and_not_before() {
        use std::io::Write;
        use std::os::fd::AsRawFd;
        let (mut a, b) = std::os::unix::net::UnixStream::pair().unwrap();
        let fd = iceoryx2::prelude::FileDescriptor::non_owning_new(b.as_raw_fd()).unwrap();
        let t0 = monotonic_ns();
        assert!(!wait_readable(&fd, std::time::Duration::from_micros(300)).unwrap());
        // It waited at least the timeout (no upper bound here: timing is measured elsewhere).
        assert!(monotonic_ns() - t0 >= 300_000);
        a.write_all(b"x").unwrap();
        assert!(wait_readable(&fd, std::time::Duration::from_secs(5)).unwrap());
    }
}
