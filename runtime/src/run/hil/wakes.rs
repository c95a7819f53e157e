//! Why the controller took a measurement late: what it was doing when the measurement
//! arrived, from its own timestamps (`latency.json`'s `controller_wake` misses say *that* the
//! controller had the measurement late; this says *why*).
//!
//! The controller's loop looks at the transport (a drain of `receive()`), and when it finds
//! nothing it takes one idle step ([`Step`]: a spin iteration, a wait on the event, a sleep on
//! a timer) and looks again. Each look is stamped (`CLOCK_MONOTONIC`, one vDSO read, no system
//! call). A measurement carries its publication stamp `t_pub` (the plant's, on the same
//! clock); the controller takes it at `t_rx`. Its *wake* is `t_rx − t_pub` of the oldest
//! period not answered since the last answer (a wake that comes after several have arrived
//! answers only the newest: the older ones are missed too; one the transport's queue
//! overwrote meanwhile is dated from the newest's stamp less the periods between). A wake
//! longer than half the deadline is *late*,
//! and put down to what happened between the last look that found nothing (`prev`) and the
//! look that found it:
//!
//! ```text
//!        prev look ── idle step (spin | event | timer) ──  look ── drain: t_rx
//!   t_pub ≤ prev:  it was stamped, but not there to take        → published late (the plant's
//!                                                                  send came long after its stamp)
//!   prev < t_pub:  it arrived during the step:
//!                    the previous answer's work (step, send)   → busy
//!                    a spin iteration                          → preempted (runnable, not running)
//!                    an event wait that returned late          → asleep on the event
//!                    an event wait that returned in time       → preempted (after the wake)
//!                    a timer sleep (hybrid)                    → asleep on a timer
//!   look < t_pub:  it arrived after the look, taken late       → preempted (in the drain)
//! ```
//!
//! Each late wake also counts the periods the plant will miss because of it (the skipped
//! older measurements, never answered, and the newest if its answer goes out after
//! `t_pub + deadline`): a count of the controller's misses made apart from the plant's
//! (`latency.json` `controller_wake + controller_compute`). The two need not match: the
//! plant's deadline runs from the release, a little before `t_pub`; the plant puts a period
//! down to its own late release before anything else; and it takes a command that came after
//! the deadline as fresh when it looked for it no sooner itself (a plant not scheduled). In
//! 16 short runs on a loaded machine the controller's count was never the smaller (`companion
//! latency --repeat` prints both). A period missed although the wake was in time is the step's
//! ([`LateWakes::long_step`]); older measurements taken in time with a newer one were
//! published late, bunched ([`LateWakes::bunched`]: the plant's misses).

use serde::{Deserialize, Serialize};

use crate::domain::histogram::{LatencyHistogram, Percentiles};

/// What the controller did between two looks at the transport.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Step {
    /// Answered the previous measurement (its step and send; the loop's checks).
    #[default]
    Work,
    /// One spin iteration.
    Spin,
    /// A wait on the transport's event, which returned at `woke_ns`.
    Event {
        /// When the wait returned (ns).
        woke_ns: u64,
    },
    /// A sleep on a timer (hybrid's sleep to the margin, or its nap), which returned at
    /// `woke_ns`.
    Timer {
        /// When the sleep returned (ns).
        woke_ns: u64,
    },
}

/// Why a wake was late (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WakeCause {
    /// Stamped before the last look that found nothing: sent late by the plant.
    PublishedLate,
    /// Arrived while the controller answered the previous one.
    Busy,
    /// Arrived while the controller was runnable but not running (spinning, receiving, or
    /// just woken).
    Preempted,
    /// Arrived while the controller waited on the event, which woke it late.
    AsleepOnEvent,
    /// Arrived while the controller slept on a timer.
    AsleepOnTimer,
}

/// Late wakes of one cause and the periods the plant missed through them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WakeCount {
    /// Late wakes.
    pub wakes: u64,
    /// The periods missed through them.
    pub missed: u64,
}

impl WakeCount {
    fn add(&mut self, missed: u64) {
        self.wakes += 1;
        self.missed += missed;
    }

    fn sum(self, o: Self) -> Self {
        Self { wakes: self.wakes + o.wakes, missed: self.missed + o.missed }
    }
}

/// The controller's late wakes by cause (`controller.json` `late_wakes`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LateWakes {
    /// [`WakeCause::PublishedLate`].
    pub published_late: WakeCount,
    /// [`WakeCause::Busy`].
    pub busy: WakeCount,
    /// [`WakeCause::Preempted`].
    pub preempted: WakeCount,
    /// [`WakeCause::AsleepOnEvent`].
    pub asleep_on_event: WakeCount,
    /// [`WakeCause::AsleepOnTimer`].
    pub asleep_on_timer: WakeCount,
    /// Periods missed although the wake was in time (a long step or send; `wakes` counts the
    /// answers).
    pub long_step: WakeCount,
    /// Measurements that came bunched with a newer one, taken in time: the plant published
    /// the older ones late (its misses, not the controller's; `wakes` counts the drains).
    pub bunched: WakeCount,
}

impl LateWakes {
    /// The periods missed through the controller, all causes (to compare with the plant's
    /// `controller_wake + controller_compute`).
    pub fn missed(&self) -> u64 {
        self.causes().iter().map(|(_, c)| c.missed).sum::<u64>() + self.long_step.missed
    }

    /// The late wakes, all causes.
    pub fn wakes(&self) -> u64 {
        self.causes().iter().map(|(_, c)| c.wakes).sum()
    }

    /// Each cause with its name (`latency.json` spelling), in the module docs' order.
    pub fn causes(&self) -> [(&'static str, WakeCount); 5] {
        [
            ("published_late", self.published_late),
            ("busy", self.busy),
            ("preempted", self.preempted),
            ("asleep_on_event", self.asleep_on_event),
            ("asleep_on_timer", self.asleep_on_timer),
        ]
    }

    /// These and `o`'s, cause by cause (several runs').
    #[must_use]
    pub fn sum(&self, o: &Self) -> Self {
        Self {
            published_late: self.published_late.sum(o.published_late),
            busy: self.busy.sum(o.busy),
            preempted: self.preempted.sum(o.preempted),
            asleep_on_event: self.asleep_on_event.sum(o.asleep_on_event),
            asleep_on_timer: self.asleep_on_timer.sum(o.asleep_on_timer),
            long_step: self.long_step.sum(o.long_step),
            bunched: self.bunched.sum(o.bunched),
        }
    }

    /// The cause with the most missed periods (`None`: none missed).
    pub fn main_cause(&self) -> Option<&'static str> {
        let mut all = self.causes().to_vec();
        all.push(("long_step", self.long_step));
        all.into_iter().filter(|(_, c)| c.missed > 0).max_by_key(|(_, c)| c.missed).map(|(n, _)| n)
    }

    fn count(&mut self, cause: WakeCause, missed: u64) {
        match cause {
            WakeCause::PublishedLate => &mut self.published_late,
            WakeCause::Busy => &mut self.busy,
            WakeCause::Preempted => &mut self.preempted,
            WakeCause::AsleepOnEvent => &mut self.asleep_on_event,
            WakeCause::AsleepOnTimer => &mut self.asleep_on_timer,
        }
        .add(missed);
    }
}

/// One drain that found new measurements, as the controller answered it (ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Took {
    /// `t_pub` of the oldest period not answered since the last answer.
    pub first_pub: u64,
    /// `t_pub` of the newest (the one answered).
    pub last_pub: u64,
    /// The periods since the last answer, the newest included (the ones it superseded, and
    /// the ones the transport's queue overwrote).
    pub count: u64,
    /// The look that found them.
    pub look: u64,
    /// When the newest was taken.
    pub received: u64,
    /// The step's time, to the send.
    pub compute: u64,
}

/// The classification of one late wake (see the module docs); `step` happened between
/// `prev` (the last look that found nothing) and `t.look`.
pub fn cause(t: &Took, prev: u64, step: Step) -> WakeCause {
    if t.first_pub <= prev {
        return WakeCause::PublishedLate;
    }
    if t.first_pub > t.look {
        return WakeCause::Preempted;
    }
    match step {
        Step::Work => WakeCause::Busy,
        Step::Spin => WakeCause::Preempted,
        Step::Event { woke_ns } | Step::Timer { woke_ns } => {
            // Most of the wake before the wait returned: it woke late; most after: it was not
            // run once woken.
            let asleep = woke_ns.saturating_sub(t.first_pub);
            if asleep < t.received.saturating_sub(woke_ns) {
                WakeCause::Preempted
            } else if matches!(step, Step::Event { .. }) {
                WakeCause::AsleepOnEvent
            } else {
                WakeCause::AsleepOnTimer
            }
        }
    }
}

/// The controller's wake log: every wake's length, the late ones by cause. Recording
/// allocates nothing (the histogram is allocated once).
#[derive(Clone, Debug)]
pub struct WakeLog {
    /// The deadline after publication (ns): a wake over half of it is late.
    deadline_ns: u64,
    /// The last look that found nothing, and what happened since.
    prev: u64,
    step: Step,
    /// Every wake, `t_rx − t_pub` of the oldest new measurement (ns).
    pub wake: LatencyHistogram,
    /// The late ones.
    pub late: LateWakes,
}

impl Default for WakeLog {
    /// A log that judges nothing until [`WakeLog::judge_against`] a deadline.
    fn default() -> Self {
        Self::new(0)
    }
}

impl WakeLog {
    /// A log for a run whose answers are due `deadline_ns` after each release (0: wakes are
    /// not recorded; lockstep has no deadline).
    pub fn new(deadline_ns: u64) -> Self {
        Self {
            deadline_ns,
            prev: 0,
            step: Step::Work,
            wake: LatencyHistogram::new(),
            late: LateWakes::default(),
        }
    }

    /// From now on, judges wakes against `deadline_ns` (allocates nothing).
    pub fn judge_against(&mut self, deadline_ns: u64) {
        self.deadline_ns = deadline_ns;
    }

    /// A look at `look` found nothing; then the loop took `step`.
    #[inline]
    pub fn idled(&mut self, look: u64, step: Step) {
        self.prev = look;
        self.step = step;
    }

    /// A look found new measurements and the controller answered them (`t`); `timed`: the
    /// run's real time had started (the handshake is not a wake).
    #[inline]
    pub fn took(&mut self, t: &Took, timed: bool) {
        if timed && self.deadline_ns > 0 {
            let wake = t.received.saturating_sub(t.first_pub);
            self.wake.record(wake);
            let sent = t.received.saturating_add(t.compute);
            let skipped = t.count.saturating_sub(1);
            let newest = u64::from(sent > t.last_pub.saturating_add(self.deadline_ns));
            if wake > self.deadline_ns / 2 {
                self.late.count(cause(t, self.prev, self.step), skipped + newest);
            } else {
                if skipped > 0 {
                    // Taken in time although older ones waited: the plant published them
                    // late, bunched with this one.
                    self.late.bunched.add(skipped);
                }
                if newest > 0 {
                    self.late.long_step.add(1);
                }
            }
        }
        self.prev = t.look;
        self.step = Step::Work;
    }
}

/// `controller.json` `wakes`: what the controller's log says.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct WakeReport {
    /// Every wake (ns).
    pub wake_ns: Percentiles,
    /// The late ones (over half the deadline) by cause.
    pub late_wakes: LateWakes,
    /// The deadline they were judged against (ns).
    pub deadline_ns: u64,
}

impl WakeLog {
    /// The report.
    pub fn report(&self) -> WakeReport {
        WakeReport { wake_ns: self.wake.percentiles(), late_wakes: self.late, deadline_ns: self.deadline_ns }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const US: u64 = 1_000;

    /// Measurement published at 1 ms, found by the look at `look`, taken 1 µs later, a 20 µs
    /// step.
    fn took(look: u64) -> Took {
        Took {
            first_pub: 1_000 * US,
            last_pub: 1_000 * US,
            count: 1,
            look,
            received: look + US,
            compute: 20 * US,
        }
    }

    #[test]
    fn each_step_names_its_cause() {
        let t = took(1_400 * US);
        // Stamped before the previous look that found nothing: the plant sent it late.
        assert_eq!(cause(&t, 1_100 * US, Step::Spin), WakeCause::PublishedLate);
        // Arrived during a spin iteration that lasted 400 µs: preempted.
        assert_eq!(cause(&t, 999 * US, Step::Spin), WakeCause::Preempted);
        // During the previous answer's work.
        assert_eq!(cause(&t, 900 * US, Step::Work), WakeCause::Busy);
        // An event wait that returned 390 µs after the publication: woken late.
        assert_eq!(cause(&t, 900 * US, Step::Event { woke_ns: 1_390 * US }), WakeCause::AsleepOnEvent);
        // One that returned 10 µs after it, then 390 µs before the look: not run once woken.
        assert_eq!(cause(&t, 900 * US, Step::Event { woke_ns: 1_010 * US }), WakeCause::Preempted);
        assert_eq!(cause(&t, 900 * US, Step::Timer { woke_ns: 1_390 * US }), WakeCause::AsleepOnTimer);
        // Arrived after the look that found it: the drain itself was held up.
        let mut late_drain = took(990 * US);
        late_drain.received = 1_400 * US;
        assert_eq!(cause(&late_drain, 900 * US, Step::Spin), WakeCause::Preempted);
    }

    #[test]
    fn the_log_counts_late_wakes_and_the_periods_they_cost() {
        let mut log = WakeLog::new(500 * US);
        // The handshake is not a wake.
        log.took(&took(5_000 * US), false);
        assert_eq!(log.wake.count(), 0);
        // In time: recorded, not late.
        log.idled(1_000 * US - 1, Step::Spin);
        log.took(&took(1_002 * US), true);
        assert_eq!((log.wake.count(), log.late.wakes()), (1, 0));
        // 300 µs late on the event: late, but answered by the deadline (1 ms + 500 µs).
        log.idled(900 * US, Step::Event { woke_ns: 1_299 * US });
        log.took(&took(1_300 * US), true);
        assert_eq!(log.late.asleep_on_event, WakeCount { wakes: 1, missed: 0 });
        // Preempted 2.1 ms while spinning: three measurements waiting, the newest answered
        // 1.1 ms after its publication: all three missed.
        log.idled(900 * US, Step::Spin);
        let t = Took { first_pub: 1_000 * US, last_pub: 3_000 * US, count: 3, ..took(3_100 * US) };
        log.took(&t, true);
        assert_eq!(log.late.preempted, WakeCount { wakes: 1, missed: 2 });
        // A step of 600 µs after an in-time wake: the step's miss.
        log.idled(999 * US, Step::Spin);
        log.took(&Took { compute: 600 * US, ..took(1_001 * US) }, true);
        assert_eq!(log.late.long_step, WakeCount { wakes: 1, missed: 1 });
        assert_eq!((log.late.wakes(), log.late.missed()), (2, 3));
        assert_eq!(log.late.main_cause(), Some("preempted"));
        // Two taken 100 µs after the older one's publication (the plant sent it 900 µs late):
        // in time, the older one missed, the plant's.
        log.idled(1_099 * US, Step::Spin);
        let t = Took { first_pub: 1_000 * US, last_pub: 1_050 * US, count: 2, ..took(1_100 * US) };
        log.took(&t, true);
        assert_eq!(log.late.bunched, WakeCount { wakes: 1, missed: 1 });
        assert_eq!((log.late.wakes(), log.late.missed()), (2, 3), "not the controller's");
        assert_eq!(log.wake.count(), 5);
        // After an answer, the next step starts as the answer's work.
        log.took(&Took { first_pub: 10_000 * US, last_pub: 10_000 * US, ..took(10_700 * US) }, true);
        assert_eq!(log.late.busy, WakeCount { wakes: 1, missed: 1 });
    }
}
