//! Whose deadline miss: each miss of the real-time loop attributed to the part of the round
//! trip that took its time, from both processes' stamps.
//!
//! A period's round trip, each instant on `CLOCK_MONOTONIC` (one clock for both processes on
//! one machine; the controller stamps its command with when the measurement arrived,
//! `received_ns`, and how long it took, `compute_ns`):
//!
//! ```text
//!   release ──plant── t_pub ─send─ t_sent ──to the controller── received ──compute── sent ──back── taken
//!   └──────────────────────────── deadline (release + --deadline-us) ─────┘
//! ```
//!
//! When the answer to a missed period comes after all (late), the miss is put down to, in
//! this order:
//!
//! - [`MissCause::PlantLate`]: the plant's send of the measurement returned (`t_sent`: the
//!   message and its notification out) more than half the deadline after the release (it was
//!   not scheduled in time, or was held up between its stamp `t_pub` and the end of the send;
//!   [`super::stats::PlantStats::plant_stalls`] counts the worse case of a skipped release);
//! - [`MissCause::ReturnPath`]: the controller *sent* before the deadline, so the time went
//!   on the way back — the transport, or the plant's own wait not waking for it;
//! - [`MissCause::ControllerWake`]: sent after the deadline, and more of the time before
//!   sending went before the controller had the measurement (`received − t_pub`: delivery and
//!   the controller's wake-up, a controller that was stopped or not scheduled) than into its
//!   step;
//! - [`MissCause::ControllerCompute`]: sent after the deadline, most of it in the step;
//! - [`MissCause::ClocksApart`]: the controller's stamp is not on the plant's clock (across
//!   machines, or a controller that does not stamp): a step longer than the whole deadline is
//!   still [`MissCause::ControllerCompute`], the rest cannot be split;
//!
//! A miss before an answered period, never answered itself, gets its cause from that answer's
//! `received_ns`: the controller answers in order, so it had not taken the missed
//! measurement by its deadline (it skipped it as superseded, or its queue of
//! [`BUFFER`](crate::transport::ipc::BUFFER) overwrote it) — or, on a lossy link, its answer
//! was lost (`latency.json` `link_counts` counts those). A miss no later answer follows (by
//! the end of the run, or beyond the [`PENDING`] waiting) is [`MissCause::Unanswered`]: the
//! controller was gone, or the messages were lost.
//! Every miss gets exactly one cause: the counts sum to the run's deadline misses.

use heapless::Deque;
use serde::{Deserialize, Serialize};

use crate::transport::wire::CommandMsg;

/// The misses that wait for their answer at once: a 1 s silence at 1 kHz (longer than any
/// `--chaos` stop); the oldest beyond them counts unanswered.
pub const PENDING: usize = 1024;

/// Why one deadline was missed (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MissCause {
    /// The plant published late.
    PlantLate,
    /// Delivery to the controller and its wake-up.
    ControllerWake,
    /// The controller's step.
    ControllerCompute,
    /// Sent in time: delivery back, or the plant's wait.
    ReturnPath,
    /// The controller's stamps are on another clock.
    ClocksApart,
    /// No answer came.
    Unanswered,
}

/// The deadline misses of a run by cause (`latency.json` `miss_causes`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MissCauses {
    /// [`MissCause::PlantLate`].
    pub plant_late: u64,
    /// [`MissCause::ControllerWake`].
    pub controller_wake: u64,
    /// [`MissCause::ControllerCompute`].
    pub controller_compute: u64,
    /// [`MissCause::ReturnPath`].
    pub return_path: u64,
    /// [`MissCause::ClocksApart`].
    pub clocks_apart: u64,
    /// [`MissCause::Unanswered`].
    pub unanswered: u64,
}

impl MissCauses {
    /// Counts one miss.
    pub fn count(&mut self, cause: MissCause) {
        *match cause {
            MissCause::PlantLate => &mut self.plant_late,
            MissCause::ControllerWake => &mut self.controller_wake,
            MissCause::ControllerCompute => &mut self.controller_compute,
            MissCause::ReturnPath => &mut self.return_path,
            MissCause::ClocksApart => &mut self.clocks_apart,
            MissCause::Unanswered => &mut self.unanswered,
        } += 1;
    }

    /// All of them (the run's deadline misses, once the run is over).
    pub fn total(&self) -> u64 {
        self.plant_late
            + self.controller_wake
            + self.controller_compute
            + self.return_path
            + self.clocks_apart
            + self.unanswered
    }

    /// The misses the controller's process caused (its wake-up and its step).
    pub fn controller(&self) -> u64 {
        self.controller_wake + self.controller_compute
    }
}

/// The missed periods awaiting their answer, oldest first, in a fixed-capacity queue:
/// recording and attributing allocate nothing.
#[derive(Clone, Debug, Default)]
pub struct MissLedger {
    pending: Deque<Period, PENDING>,
}

/// A period as the plant released it (ns, plant's clock).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Period {
    /// Its measurement's `seq`.
    pub seq: u64,
    /// The scheduled release.
    pub release: u64,
    /// The publication's stamp (in the measurement).
    pub t_pub: u64,
    /// When the plant's send returned (the measurement and its notification out).
    pub t_sent: u64,
    /// The deadline of its answer.
    pub deadline: u64,
}

impl MissLedger {
    /// Period `p` missed its deadline: it waits for its answer. With [`PENDING`] misses
    /// already waiting, the oldest is counted unanswered.
    pub fn missed(&mut self, p: Period, causes: &mut MissCauses) {
        if self.pending.is_full() {
            self.pending.pop_front();
            causes.count(MissCause::Unanswered);
        }
        // Not full now.
        let _ = self.pending.push_back(p);
    }

    /// A valid command answering `c.seq` arrived: the missed periods up to it get their
    /// cause — its own from its stamps, the earlier ones from when the controller took this
    /// measurement (it answers in order, so it had not taken those by their deadlines: it
    /// skipped them, its queue overwrote them, or on a lossy link their answers were lost).
    pub fn answered(&mut self, c: &CommandMsg, causes: &mut MissCauses) {
        while let Some(p) = self.pending.front().copied().filter(|p| p.seq <= c.seq) {
            self.pending.pop_front();
            let compute = if p.seq == c.seq { c.compute_ns } else { 0 };
            causes.count(cause(&p, c.received_ns, compute));
        }
    }

    /// The run is over: the misses still waiting are unanswered.
    pub fn finish(&mut self, causes: &mut MissCauses) {
        while self.pending.pop_front().is_some() {
            causes.count(MissCause::Unanswered);
        }
    }
}

/// The cause of a miss answered with the controller's stamps `received` and `compute` (ns).
fn cause(p: &Period, received: u64, compute: u64) -> MissCause {
    let budget = p.deadline.saturating_sub(p.release);
    if p.t_sent.max(p.t_pub).saturating_sub(p.release) > budget / 2 {
        return MissCause::PlantLate;
    }
    if received < p.t_pub {
        // Not the plant's clock (or no stamp).
        return if compute >= budget { MissCause::ControllerCompute } else { MissCause::ClocksApart };
    }
    let sent = received.saturating_add(compute);
    if sent <= p.deadline {
        MissCause::ReturnPath
    } else if received - p.t_pub >= compute {
        MissCause::ControllerWake
    } else {
        MissCause::ControllerCompute
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const US: u64 = 1_000;

    /// Period 5 released at 5 ms, published 10 µs later, deadline 500 µs after the release.
    fn period(seq: u64) -> Period {
        let release = seq * 1_000 * US;
        Period {
            seq,
            release,
            t_pub: release + 10 * US,
            t_sent: release + 12 * US,
            deadline: release + 500 * US,
        }
    }

    fn command(seq: u64, received: u64, compute: u64) -> CommandMsg {
        let mut c = <CommandMsg as zerocopy::FromZeros>::new_zeroed();
        c.seq = seq;
        c.received_ns = received;
        c.compute_ns = compute;
        c
    }

    fn attributed(p: Period, received: u64, compute: u64) -> MissCauses {
        let (mut ledger, mut causes) = (MissLedger::default(), MissCauses::default());
        ledger.missed(p, &mut causes);
        ledger.answered(&command(p.seq, received, compute), &mut causes);
        ledger.finish(&mut causes);
        assert_eq!(causes.total(), 1, "{causes:?}");
        causes
    }

    #[test]
    fn each_part_of_the_round_trip_is_named() {
        let p = period(5);
        // Received 20 µs after publication, 600 µs of step: sent after the deadline.
        assert_eq!(attributed(p, p.t_pub + 20 * US, 600 * US).controller_compute, 1);
        // Received 700 µs late (a stopped controller), 30 µs of step.
        assert_eq!(attributed(p, p.t_pub + 700 * US, 30 * US).controller_wake, 1);
        // Sent 100 µs after publication, well before the deadline: the way back.
        assert_eq!(attributed(p, p.t_pub + 40 * US, 60 * US).return_path, 1);
        // Published 300 µs after the release (more than half the 500 µs): the plant's.
        let late = Period { t_pub: p.release + 300 * US, t_sent: p.release + 302 * US, ..p };
        assert_eq!(attributed(late, late.t_pub + 10 * US, 10 * US).plant_late, 1);
        // Stamped in time but held up in its send for 400 µs (the controller could not have
        // had it before): the plant's, though the stamp says the controller took it late.
        let held = Period { t_sent: p.release + 410 * US, ..p };
        assert_eq!(attributed(held, held.t_sent + 10 * US, 10 * US).plant_late, 1);
        // Another machine's clock: a step over the whole deadline is still the step's.
        assert_eq!(attributed(p, 3, 600 * US).controller_compute, 1);
        assert_eq!(attributed(p, 3, 100 * US).clocks_apart, 1);
    }

    #[test]
    fn the_misses_before_an_answer_are_the_controllers_and_the_rest_unanswered() {
        let (mut ledger, mut causes) = (MissLedger::default(), MissCauses::default());
        for seq in 10..15 {
            ledger.missed(period(seq), &mut causes);
        }
        // The controller, stopped, took 13 at 13.6 ms and answered it (10–12 skipped or
        // overwritten in its queue): all four missed for it.
        ledger.answered(&command(13, 13_600 * US, 20 * US), &mut causes);
        assert_eq!((causes.controller_wake, causes.total()), (4, 4));
        // 14 never answered: counted when the run ends.
        ledger.finish(&mut causes);
        assert_eq!((causes.unanswered, causes.total()), (1, 5));
        // More than PENDING waiting: the oldest are counted unanswered as they fall out.
        for seq in 100..100 + PENDING as u64 + 3 {
            ledger.missed(period(seq), &mut causes);
        }
        assert_eq!(causes.unanswered, 4);
        // An answer older than every waiting miss takes none of them.
        ledger.answered(&command(50, 50_100 * US, 10 * US), &mut causes);
        assert_eq!(causes.total(), 8);
        ledger.finish(&mut causes);
        assert_eq!((causes.unanswered, causes.total()), (4 + PENDING as u64, 8 + PENDING as u64));
    }
}
