//! `companion hil --chaos SEED`: a soak with faults injected on purpose, and a check that
//! what the programs counted matches what was injected.
//!
//! From the seed, both processes derive the same [`Plan`]:
//!
//! - corrupted commands (another protocol version or session, a sequence number from the
//!   future, a NaN velocity), two per second of the run, and commands held back for 2 to
//!   `hold/2` periods, one every two seconds — sent by the controller's link decorator
//!   ([`super::fault::Injecting`]);
//! - `SIGSTOP`s of either process for 20 ms to 400 ms (under a quarter of `--peer-timeout`,
//!   so that a stopped peer is never taken for a hung one), one every one to three seconds —
//!   the plant's is sent by the controller (`companion hil`, its parent), the controller's by
//!   the plant, each by an [`Agent`] thread that always sends `SIGCONT` after its stop.
//!
//! Faults start two seconds after the epoch the parent gives both processes and end
//! 1.5 s before the end of the run. Afterwards [`check`] compares the counts in the plant's
//! `latency.json` with what was injected: malformed commands by kind exactly; late commands,
//! gaps between fresh commands longer than the hold, the longest such gap and the plant's
//! stalls at least as many (as long) as the faults must cause — measured on the wall clock,
//! so that a plant that skips periods on a loaded machine still counts them; and every row
//! of `timeseries.csv` on disk.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use rand::rngs::ChaCha12Rng;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

use super::config::Timing;
use super::fault::{Corruption, Injected};
use super::stats::InvalidCounts;
use crate::sys::lock::Role;
use crate::sys::process::{send_signal, Signal};
use crate::transport::link::LinkCounts;

/// Faults start this long after the epoch (ns).
pub const FIRST_FAULT_NS: u64 = 2_000_000_000;
/// Faults end this long before the end of the run (ns).
pub const LAST_FAULT_MARGIN_NS: u64 = 1_500_000_000;
/// The shortest `--duration` of a chaos run (s).
pub const MIN_DURATION_S: f64 = 5.0;

/// A planned `SIGSTOP` of one process.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stop {
    /// Who is stopped.
    pub plant: bool,
    /// When, after the epoch (ns).
    pub at_ns: u64,
    /// For how long (ns).
    pub for_ns: u64,
}

/// The faults of a chaos run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plan {
    /// Corrupted commands: `(sequence number, kind)`.
    pub corruptions: Vec<(u64, Corruption)>,
    /// Commands held back: `(sequence number, delay in ns)`.
    pub delays: Vec<(u64, u64)>,
    /// Stops, in time order, never overlapping.
    pub stops: Vec<Stop>,
}

/// Why a chaos run cannot start.
#[derive(Debug, thiserror::Error)]
pub enum ChaosError {
    /// A lockstep run: no deadlines to miss.
    #[error("--chaos needs real time (not --lockstep)")]
    Lockstep,
    /// A run shorter than [`MIN_DURATION_S`].
    #[error("--chaos needs a run of at least {MIN_DURATION_S} s (--duration)")]
    TooShort,
    /// The thread that stops the processes cannot be started.
    #[error("starting the chaos thread")]
    Spawn(#[source] std::io::Error),
}

impl Plan {
    /// The plan of seed `seed` for a run of `steps` periods with `timing`.
    ///
    /// # Errors
    /// A lockstep run (no deadlines to miss), or one shorter than [`MIN_DURATION_S`].
    pub fn new(seed: u64, steps: u64, timing: &Timing) -> Result<Self, ChaosError> {
        let period = timing.period_ns;
        if timing.lockstep || period == 0 {
            return Err(ChaosError::Lockstep);
        }
        let run_ns = steps.saturating_mul(period);
        if (run_ns as f64) < MIN_DURATION_S * 1e9 {
            return Err(ChaosError::TooShort);
        }
        let mut rng = ChaCha12Rng::seed_from_u64(seed);
        let (first, last) = (FIRST_FAULT_NS, run_ns - LAST_FAULT_MARGIN_NS);
        let (first_seq, last_seq) = (first / period, last / period);
        let seconds = (last - first) / 1_000_000_000;
        let kinds = [Corruption::Version, Corruption::Nan, Corruption::Seq, Corruption::Session];
        let mut corruptions: Vec<(u64, Corruption)> = (0..2 * seconds)
            .map(|_| (rng.random_range(first_seq..last_seq), kinds[rng.random_range(0..kinds.len())]))
            .collect();
        corruptions.sort_by_key(|c| c.0);
        corruptions.dedup_by_key(|c| c.0);
        let max_hold = u64::from(timing.hold_periods / 2).max(3);
        let mut delays: Vec<(u64, u64)> = (0..seconds.div_ceil(2))
            .map(|_| (rng.random_range(first_seq..last_seq), rng.random_range(2..=max_hold) * period))
            .collect();
        delays.sort_by_key(|d| d.0);
        delays.dedup_by_key(|d| d.0);
        let longest = (timing.peer_timeout_ns / 4).clamp(20_000_000, 400_000_000);
        let mut stops = Vec::new();
        let mut t = first;
        loop {
            t += rng.random_range(1_000_000_000..3_000_000_000u64);
            let d = rng.random_range(20_000_000..=longest);
            if t + d > last {
                break;
            }
            stops.push(Stop { plant: rng.random_bool(0.5), at_ns: t, for_ns: d });
            t += d;
        }
        Ok(Self { corruptions, delays, stops })
    }

    /// The stops that the process playing `role` performs (on its peer).
    pub fn stops_by(&self, role: Role) -> Vec<Stop> {
        // The controller stops the plant, the plant stops the controller.
        self.stops.iter().copied().filter(|s| s.plant == (role == Role::Control)).collect()
    }
}

/// A stop as it was done (`CLOCK_MONOTONIC`, ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DoneStop {
    /// The plant was stopped (else the controller).
    pub plant: bool,
    /// `SIGSTOP` sent.
    pub start_ns: u64,
    /// `SIGCONT` sent.
    pub end_ns: u64,
}

/// A thread that stops a peer process on schedule.
#[derive(Debug)]
pub struct Agent {
    quit: Arc<AtomicBool>,
    thread: Option<JoinHandle<Vec<DoneStop>>>,
}

/// Sleeps until `t_ns` or until `quit`, whichever is first, in short naps; whether `quit`.
fn nap_until(t_ns: u64, quit: &AtomicBool) -> bool {
    loop {
        if quit.load(Ordering::Acquire) {
            return true;
        }
        let now = crate::sys::rt::monotonic_ns();
        if now >= t_ns {
            return false;
        }
        std::thread::sleep(Duration::from_nanos((t_ns - now).min(20_000_000)));
    }
}

impl Agent {
    /// Starts the thread: it stops process `pid` at `epoch_ns + stop.at_ns` for
    /// `stop.for_ns`, for each of `stops`. It always thaws what it froze.
    ///
    /// # Errors
    /// The thread cannot be started.
    pub fn spawn(stops: Vec<Stop>, pid: i32, epoch_ns: u64) -> Result<Self, ChaosError> {
        let quit = Arc::new(AtomicBool::new(false));
        let q = Arc::clone(&quit);
        let thread = std::thread::Builder::new()
            .name("chaos".into())
            .spawn(move || {
                let mut done = Vec::new();
                for s in stops {
                    if nap_until(epoch_ns + s.at_ns, &q) {
                        break;
                    }
                    let start_ns = crate::sys::rt::monotonic_ns();
                    if send_signal(pid, Signal::Stop).is_err() {
                        break;
                    }
                    // A stop ends on time even when asked to quit.
                    std::thread::sleep(Duration::from_nanos(s.for_ns));
                    let _ = send_signal(pid, Signal::Continue);
                    done.push(DoneStop { plant: s.plant, start_ns, end_ns: crate::sys::rt::monotonic_ns() });
                }
                done
            })
            .map_err(ChaosError::Spawn)?;
        Ok(Self { quit, thread: Some(thread) })
    }

    /// Stops the thread (after the stop under way, if any) and returns what it did.
    pub fn finish(mut self) -> Vec<DoneStop> {
        self.quit.store(true, Ordering::Release);
        self.thread.take().and_then(|t| t.join().ok()).unwrap_or_default()
    }
}

impl Drop for Agent {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::Release);
    }
}

/// What the plant counted, as `latency.json` has it (the part the check reads).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Observed {
    /// How the plant's run ended.
    pub end: String,
    /// Malformed commands dropped, by reason.
    pub invalid_messages: InvalidCounts,
    /// Commands that arrived after their deadline.
    pub late_commands: u64,
    /// Times the robot was stopped.
    pub stop_events: u64,
    /// The longest time between two fresh commands (ns).
    pub longest_command_gap_ns: u64,
    /// Gaps between fresh commands longer than the hold.
    pub command_gaps_over_hold: u64,
    /// Times the plant fell more than a period behind its schedule.
    pub plant_stalls: u64,
    /// Log rows lost.
    pub log_rows_dropped: u64,
    /// The plant's loop: first release and end (`CLOCK_MONOTONIC`, ns).
    pub run_window_ns: (u64, u64),
    /// The controller's stops, as the plant's agent did them.
    pub chaos_stops: Vec<DoneStop>,
    /// What the plant's transport counted (Zenoh; absent on iceoryx2).
    #[serde(default)]
    pub link_counts: Option<LinkCounts>,
}

/// `chaos.json`: the seed, what was injected, what was observed, and every mismatch.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The seed.
    pub seed: u64,
    /// Commands corrupted and held back by the controller.
    pub injected: Injected,
    /// Stops of either process during the plant's loop.
    pub stops: Vec<DoneStop>,
    /// What the plant counted.
    pub observed: Observed,
    /// Complete rows in `timeseries.csv`, and how many the run must have.
    pub rows: (u64, u64),
    /// Commands the controller's transport accepted that the plant's never received: lost in
    /// transit (Zenoh's congestion drop), counted end to end (`None` on iceoryx2).
    pub commands_not_received: Option<u64>,
    /// Each mismatch in words (empty: the counts match).
    pub mismatches: Vec<String>,
}

/// Compares what was injected with what was observed; the report with its mismatches.
/// `stops`: both agents' stops; `rows`: complete rows on disk and rows expected; `sent`: the
/// controller's transport's counts (Zenoh), against the plant's in `observed`.
pub fn check(
    seed: u64,
    timing: &Timing,
    injected: Injected,
    stops: &[DoneStop],
    observed: Observed,
    rows: (u64, u64),
    sent: Option<LinkCounts>,
) -> Report {
    let mut m = Vec::new();
    let not_received = sent.zip(observed.link_counts).map(|(c, p)| c.not_received_by(&p));
    // An injected command the plant did not count may be one the link lost: say so.
    let lost = match not_received {
        Some(n) if n > 0 => format!(" ({n} commands sent were never received by the plant's transport)"),
        _ => String::new(),
    };
    let period = timing.period_ns.max(1);
    let inv = &observed.invalid_messages;
    for (what, got, sent) in [
        ("commands of another protocol version", inv.version, injected.version),
        ("commands of another session", inv.session, injected.session),
        ("commands with a future sequence number", inv.future_seq, injected.future_seq),
        ("commands with a NaN velocity", inv.non_finite, injected.non_finite),
    ] {
        if got != sent {
            m.push(format!("{what}: {sent} injected, {got} counted by the plant{lost}"));
        }
    }
    if inv.joint_count + inv.status > 0 {
        m.push(format!("{} malformed commands of a kind never injected", inv.joint_count + inv.status));
    }
    if observed.late_commands < injected.delayed {
        m.push(format!(
            "{} commands held back past their deadline, only {} late commands counted",
            injected.delayed, observed.late_commands
        ));
    }
    let (start, end) = observed.run_window_ns;
    let during: Vec<DoneStop> =
        stops.iter().copied().filter(|s| s.start_ns >= start && s.end_ns <= end).collect();
    let ns = |s: &DoneStop| s.end_ns - s.start_ns;
    let controller: Vec<u64> = during.iter().filter(|s| !s.plant).map(ns).collect();
    let plant: Vec<u64> = during.iter().filter(|s| s.plant).map(ns).collect();
    // A controller stopped for longer than the hold leaves a gap of about as long between
    // two fresh commands (two periods less at most: the last command before the stop may
    // have come late in its period, the first after it early).
    let hold_ns = (u64::from(timing.hold_periods) + 3) * period;
    let must_gap = controller.iter().filter(|d| **d >= hold_ns).count() as u64;
    if observed.command_gaps_over_hold < must_gap {
        m.push(format!(
            "{must_gap} controller stops longer than the hold, only {} gaps between fresh commands longer than it",
            observed.command_gaps_over_hold
        ));
    }
    if let Some(longest) = controller.iter().max() {
        if observed.longest_command_gap_ns + 2 * period < *longest {
            m.push(format!(
                "the controller was stopped for {:.1} ms, yet the longest gap between fresh commands is {:.1} ms",
                *longest as f64 / 1e6,
                observed.longest_command_gap_ns as f64 / 1e6
            ));
        }
    }
    let must_stall = plant.iter().filter(|d| **d >= 3 * period).count() as u64;
    if observed.plant_stalls < must_stall {
        m.push(format!("{must_stall} plant stops, only {} stalls counted", observed.plant_stalls));
    }
    if observed.end != "completed" {
        m.push(format!("the run did not complete: {}", observed.end));
    }
    if observed.log_rows_dropped > 0 || rows.0 != rows.1 {
        m.push(format!("{} of {} rows on disk ({} dropped)", rows.0, rows.1, observed.log_rows_dropped));
    }
    if let Some(n) = not_received.filter(|n| *n > 0) {
        m.push(format!("{n} commands sent were never received by the plant's transport (lost in transit)"));
    }
    Report {
        seed,
        injected,
        stops: during,
        observed,
        rows,
        commands_not_received: not_received,
        mismatches: m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::hil::WaitMode;

    fn timing() -> Timing {
        Timing {
            period_ns: 1_000_000,
            deadline_ns: 500_000,
            hold_periods: 20,
            wait: WaitMode::Adaptive,
            release: crate::run::hil::config::ReleaseTimer::Sleep,
            spin_margin_ns: 100_000,
            silence_ns: 20_000_000,
            peer_timeout_ns: 2_000_000_000,
            lockstep: false,
            max_command_age: 0,
        }
    }

    #[test]
    fn a_plan_is_the_seeds_and_keeps_its_faults_inside_the_run_apart() {
        let t = timing();
        let a = Plan::new(7, 600_000, &t).unwrap();
        assert_eq!(a, Plan::new(7, 600_000, &t).unwrap());
        assert_ne!(a, Plan::new(8, 600_000, &t).unwrap());
        assert!(
            a.corruptions.len() > 1000 && a.delays.len() > 250 && a.stops.len() > 200,
            "{}",
            a.stops.len()
        );
        let (first, last) = (FIRST_FAULT_NS, 600_000 * t.period_ns - LAST_FAULT_MARGIN_NS);
        assert!(a.corruptions.iter().all(|c| c.0 * t.period_ns >= first && c.0 * t.period_ns < last));
        assert!(a.delays.iter().all(|d| d.1 >= 2 * t.period_ns && d.1 <= 10 * t.period_ns));
        for w in a.stops.windows(2) {
            assert!(w[0].at_ns + w[0].for_ns + 1_000_000_000 <= w[1].at_ns, "{w:?}");
        }
        assert!(a.stops.iter().all(|s| s.for_ns <= 400_000_000 && s.at_ns + s.for_ns <= last));
        assert!(a.stops.iter().any(|s| s.plant) && a.stops.iter().any(|s| !s.plant));
        let by_control = a.stops_by(Role::Control);
        assert!(!by_control.is_empty() && by_control.iter().all(|s| s.plant));
        assert!(Plan::new(7, 4_000, &t).is_err(), "too short");
        assert!(Plan::new(7, 60_000, &Timing { lockstep: true, period_ns: 0, ..t }).is_err());
    }

    #[test]
    fn the_check_finds_every_kind_of_mismatch() {
        let t = timing();
        let injected = Injected { version: 2, non_finite: 1, future_seq: 1, session: 3, delayed: 4 };
        let stops = [
            DoneStop { plant: false, start_ns: 2_000_000_000, end_ns: 2_100_000_000 },
            DoneStop { plant: true, start_ns: 3_000_000_000, end_ns: 3_050_000_000 },
            // Before the run: not counted.
            DoneStop { plant: false, start_ns: 10, end_ns: 400_000_000 },
        ];
        let good = Observed {
            end: "completed".into(),
            invalid_messages: InvalidCounts {
                version: 2,
                session: 3,
                future_seq: 1,
                non_finite: 1,
                ..InvalidCounts::default()
            },
            late_commands: 6,
            stop_events: 1,
            longest_command_gap_ns: 99_000_000,
            command_gaps_over_hold: 1,
            plant_stalls: 1,
            log_rows_dropped: 0,
            run_window_ns: (1_000_000_000, 9_000_000_000),
            chaos_stops: Vec::new(),
            link_counts: Some(LinkCounts { published: 9_000, received: 9_008, ..LinkCounts::default() }),
        };
        let sent = Some(LinkCounts { published: 9_008, received: 9_000, ..LinkCounts::default() });
        let r = check(1, &t, injected, &stops, good.clone(), (801, 801), sent);
        assert!(r.mismatches.is_empty(), "{:?}", r.mismatches);
        assert_eq!((r.stops.len(), r.commands_not_received), (2, Some(0)));
        // A command lost in transit (zenoh's congestion drop): counted and said.
        let lost = Observed {
            invalid_messages: InvalidCounts { version: 1, ..good.invalid_messages },
            link_counts: Some(LinkCounts { received: 9_007, ..good.link_counts.unwrap() }),
            ..good.clone()
        };
        let r = check(1, &t, injected, &stops, lost, (801, 801), sent);
        assert_eq!(r.commands_not_received, Some(1));
        assert_eq!(r.mismatches.len(), 2, "{:#?}", r.mismatches);
        assert!(r.mismatches[0].ends_with("(1 commands sent were never received by the plant's transport)"));
        assert!(r.mismatches[1].contains("lost in transit"), "{:?}", r.mismatches);
        // Over iceoryx2 nothing is counted.
        assert_eq!(
            check(1, &t, injected, &stops, good.clone(), (801, 801), None).commands_not_received,
            None
        );
        let bad = Observed {
            invalid_messages: InvalidCounts { version: 1, ..good.invalid_messages },
            late_commands: 3,
            longest_command_gap_ns: 50_000_000,
            command_gaps_over_hold: 0,
            plant_stalls: 0,
            end: "interrupted at cycle 5".into(),
            ..good
        };
        let r = check(1, &t, injected, &stops, bad, (800, 801), sent);
        assert_eq!(r.mismatches.len(), 7, "{:#?}", r.mismatches);
    }
}
