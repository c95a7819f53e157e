//! Waiting: for a point in time (the plant's release) and for a message (one idle step at a
//! time, between two `receive()` calls), in the four `--wait` modes. One [`Idler`] per loop
//! does both, so that the adaptive mode sees every spin of its process.
//!
//! ## Adaptive waiting (the default)
//!
//! Busy-polling has the lowest latency while the process has a CPU to itself, and is the
//! worst choice when it has not: a spinner that the scheduler preempts loses whole time
//! slices (milliseconds), so on a 2-CPU machine with other work 70–84 % of 500 µs deadlines
//! were missed, where sleeping on the iceoryx2 event missed under 1 %.
//!
//! A spinner keeps its CPU only while nothing else wants one. The HIL's two processes
//! spinning take two CPUs; every other thread that wakes — the plant's log writer every
//! 50 ms, the kernel's workers, any other program — then has to preempt one of them, and if
//! that is the controller when a measurement comes, the measurement waits until it runs
//! again. On the 2-vCPU machines this project runs on, otherwise idle, that was most of
//! `adaptive`'s misses: 29–33 of 34–38 in 10 s runs were the controller's, woken late, while
//! `event` had none of the controller's (issue 39; `controller.json` names the cause of each
//! late wake, [`super::wakes`]). So `adaptive` spins only where spinning leaves a CPU free:
//! on a machine of fewer than [`MIN_CPUS_TO_SPIN`] CPUs it waits on the event throughout
//! (reported as [`WaitCounts::no_spare_cpu`]), like `event`.
//!
//! With CPUs to spare it spins and watches the gaps between two consecutive spin iterations
//! (one clock read each, no system call), and the gap between the last one and a message's
//! arrival (the preemption during which the message came: the one that costs a deadline).
//! A gap longer than [`PREEMPTED_NS`] means the process was preempted while spinning; it then
//! waits like `event` (sleeping on the notification, the sender always notifies in this
//! mode) for a back-off that starts at [`BACKOFF_MIN_NS`] and doubles with each further
//! preemption up to [`BACKOFF_MAX_NS`]. When a back-off ends it tries spinning again — unless
//! the kernel reports CPU pressure (`/proc/pressure/cpu`: tasks waiting for a CPU more than
//! [`PRESSURE_LIMIT`] % of the last 10 s, read once per back-off): then spinning would take a
//! CPU others wait for, and it waits on the event for another back-off. It starts the same
//! way: spinning unless the machine is under pressure. A spin phase that runs [`CLEAN_NS`]
//! without a preemption resets the back-off. The counts are reported ([`WaitCounts`]).

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::config::WaitMode;
use super::wakes::Step;
use crate::sys::clock::Clock;
use crate::transport::link::LinkError;

/// After this long spinning without a message, hybrid waiting naps instead (ns).
pub const SPIN_BUDGET_NS: u64 = 200_000;
/// The nap of hybrid waiting once the spin budget is spent (ns).
pub const NAP_NS: u64 = 50_000;
/// The longest single event wait (ns): the caller re-checks its timeouts at least this often.
pub const MAX_EVENT_WAIT_NS: u64 = 10_000_000;
/// Adaptive: a gap between two spin iterations longer than this means the spinner was
/// preempted (an iteration takes well under a microsecond; an interrupt tens of them) (ns).
pub const PREEMPTED_NS: u64 = 200_000;
/// Adaptive: the first back-off to event waiting after a preemption (ns).
pub const BACKOFF_MIN_NS: u64 = 500_000_000;
/// Adaptive: the longest back-off (ns).
pub const BACKOFF_MAX_NS: u64 = 8_000_000_000;
/// Adaptive: a spin phase this long without a preemption resets the back-off (ns).
pub const CLEAN_NS: u64 = 10_000_000_000;
/// Adaptive: CPU pressure ("some avg10", %) above which it does not try spinning.
pub const PRESSURE_LIMIT: f64 = 10.0;
/// Adaptive: the fewest online CPUs on which it spins — one for each of the two loops and
/// one for everything else.
pub const MIN_CPUS_TO_SPIN: usize = 3;

/// Where the adaptive mode reads the CPU pressure (%; `None`: not reported).
pub type PressureSource = fn() -> Option<f64>;

/// What the adaptive mode did (all zero in the other modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WaitCounts {
    /// Preemptions noticed while spinning.
    pub preemptions: u64,
    /// Switches from spinning to event waiting.
    pub fallbacks: u64,
    /// Time spent in event waiting phases (ns), up to the last switch or wait.
    pub event_phase_ns: u64,
    /// Back-offs prolonged (or a start in event waiting) because of CPU pressure.
    pub pressure_holds: u64,
    /// Fewer than [`MIN_CPUS_TO_SPIN`] CPUs: it waited on the event throughout.
    pub no_spare_cpu: bool,
}

/// The adaptive mode's state.
#[derive(Clone, Copy, Debug)]
struct Adaptive {
    /// Event waiting until this time (0: spinning).
    event_until_ns: u64,
    /// The current event phase started at (ns).
    event_since_ns: u64,
    /// The next back-off (ns).
    backoff_ns: u64,
    /// The current spin phase started at (ns).
    spin_since_ns: u64,
    /// The previous spin iteration of the current wait (0: none yet).
    last_spin_ns: u64,
    /// Whether the first wait happened (the start decides by the CPUs and the pressure).
    started: bool,
    /// The machine's online CPUs.
    cpus: usize,
    pressure: PressureSource,
    counts: WaitCounts,
}

impl Adaptive {
    fn new() -> Self {
        Self {
            event_until_ns: 0,
            event_since_ns: 0,
            backoff_ns: BACKOFF_MIN_NS,
            spin_since_ns: 0,
            last_spin_ns: 0,
            started: false,
            cpus: crate::sys::rt::online_cpus(),
            pressure: crate::sys::rt::cpu_pressure,
            counts: WaitCounts::default(),
        }
    }

    fn pressured(&self) -> bool {
        (self.pressure)().is_some_and(|p| p > PRESSURE_LIMIT)
    }

    /// Whether to wait on the event now (else spin).
    #[inline]
    fn event_phase(&mut self, now: u64) -> bool {
        if !self.started {
            self.started = true;
            self.spin_since_ns = now;
            if self.cpus < MIN_CPUS_TO_SPIN {
                // No CPU to spare: the event for good.
                self.counts.no_spare_cpu = true;
                self.event_since_ns = now;
                self.event_until_ns = u64::MAX;
                return true;
            }
            if self.pressured() {
                self.counts.pressure_holds += 1;
                self.event_since_ns = now;
                self.event_until_ns = now + self.backoff_ns;
                return true;
            }
        }
        if self.event_until_ns == 0 {
            return false;
        }
        if now < self.event_until_ns {
            return true;
        }
        self.counts.event_phase_ns += now - self.event_since_ns;
        self.event_since_ns = now;
        if self.pressured() {
            // Others wait for a CPU: another back-off on the event.
            self.counts.pressure_holds += 1;
            self.event_until_ns = now + self.backoff_ns;
            return true;
        }
        // The back-off is over: spin again.
        self.event_until_ns = 0;
        self.spin_since_ns = now;
        self.last_spin_ns = 0;
        false
    }

    /// One spin iteration at `now`: a long gap since the previous one is a preemption.
    #[inline]
    fn spun(&mut self, now: u64) {
        let gap = if self.last_spin_ns == 0 { 0 } else { now.saturating_sub(self.last_spin_ns) };
        self.last_spin_ns = now;
        if gap <= PREEMPTED_NS {
            return;
        }
        self.counts.preemptions += 1;
        if now.saturating_sub(self.spin_since_ns) >= CLEAN_NS {
            self.backoff_ns = BACKOFF_MIN_NS;
        }
        let backoff = self.backoff_ns;
        self.event_since_ns = now;
        self.event_until_ns = now + backoff;
        self.backoff_ns = (backoff * 2).min(BACKOFF_MAX_NS);
        self.counts.fallbacks += 1;
        self.last_spin_ns = 0;
    }
}

/// How a loop waits: for its release time and between two empty `receive()` calls.
#[derive(Clone, Copy, Debug)]
pub struct Idler {
    mode: WaitMode,
    margin_ns: u64,
    spin_start: Option<u64>,
    adaptive: Adaptive,
    /// What the last idle step was ([`Idler::last_step`]).
    step: Step,
    /// Where the mode sleeps to a release time (`event`, `adaptive` on the event): how long
    /// before it to wake and spin the rest (`--release-timer margin`; 0: sleep to it).
    release_margin_ns: u64,
}

impl Idler {
    /// An idler for `mode`; `margin_ns` is the hybrid spin margin.
    pub fn new(mode: WaitMode, margin_ns: u64) -> Self {
        Self {
            mode,
            margin_ns,
            spin_start: None,
            adaptive: Adaptive::new(),
            step: Step::Work,
            release_margin_ns: 0,
        }
    }

    /// The same, waking `margin_ns` before a release it sleeps to and spinning the rest.
    #[must_use]
    pub fn with_release_margin(mut self, margin_ns: u64) -> Self {
        self.release_margin_ns = margin_ns;
        self
    }

    /// The same, reading the CPU pressure from `source` (tests).
    #[must_use]
    pub fn with_pressure(mut self, source: PressureSource) -> Self {
        self.adaptive.pressure = source;
        self
    }

    /// The same, on a machine of `cpus` online CPUs (tests).
    #[must_use]
    pub fn with_cpus(mut self, cpus: usize) -> Self {
        self.adaptive.cpus = cpus;
        self
    }

    /// A message arrived (or the plant starts to wait for one) at `now`: the next wait starts
    /// afresh. While adaptive waiting spins, a gap since its last spin iteration is a
    /// preemption like one between two iterations: the one that matters most, since the
    /// message came while the process was not running.
    #[inline]
    pub fn reset(&mut self, now: u64) {
        self.spin_start = None;
        if self.mode == WaitMode::Adaptive {
            self.adaptive.spun(now);
        }
        self.adaptive.last_spin_ns = 0;
    }

    /// What the last idle step was: a spin iteration, or a wait on the event or a timer and
    /// when it returned (for the controller's [wake log](super::wakes)).
    #[inline]
    pub fn last_step(&self) -> Step {
        self.step
    }

    /// What the adaptive mode did so far.
    pub fn counts(&self) -> WaitCounts {
        self.adaptive.counts
    }

    /// Waits until `t_ns`: spinning on the clock (`spin`, and `adaptive` while it spins),
    /// sleeping to the absolute time (`event`, and `adaptive` after a preemption; to the
    /// release margin before it, if one is set, and spinning the rest), or sleeping until the
    /// hybrid margin before it and spinning the rest (`hybrid`).
    #[inline]
    pub fn until<C: Clock>(&mut self, clock: &C, t_ns: u64) {
        let now = clock.now_ns();
        match self.mode {
            WaitMode::Spin => {}
            WaitMode::Event => clock.sleep_until_ns(t_ns.saturating_sub(self.release_margin_ns)),
            WaitMode::Hybrid => {
                if now + self.margin_ns < t_ns {
                    clock.sleep_until_ns(t_ns - self.margin_ns);
                }
            }
            WaitMode::Adaptive => {
                if self.adaptive.event_phase(now) {
                    clock.sleep_until_ns(t_ns.saturating_sub(self.release_margin_ns));
                } else {
                    self.adaptive.last_spin_ns = 0;
                    loop {
                        let now = clock.now_ns();
                        // (A preemption past the release counts too.)
                        self.adaptive.spun(now);
                        if now >= t_ns {
                            return;
                        }
                        if self.adaptive.event_until_ns != 0 {
                            // Preempted: sleep the rest.
                            clock.sleep_until_ns(t_ns.saturating_sub(self.release_margin_ns));
                            break;
                        }
                        clock.spin_hint();
                    }
                }
            }
        }
        while clock.now_ns() < t_ns {
            clock.spin_hint();
        }
    }

    /// One idle step. `expected_ns`: when the message should arrive (hybrid sleeps until
    /// `margin` before it), `limit_ns`: never block past this time; `event_wait(timeout)`
    /// waits on the transport's event (event mode, and adaptive after a preemption).
    ///
    /// # Errors
    /// The event wait failed ([`Link::wait_event`](crate::transport::link::Link::wait_event)'s
    /// error).
    #[inline]
    pub fn idle<C: Clock>(
        &mut self,
        clock: &C,
        expected_ns: Option<u64>,
        limit_ns: u64,
        event_wait: impl FnOnce(Duration) -> Result<(), LinkError>,
    ) -> Result<(), LinkError> {
        let now = clock.now_ns();
        let event = || Duration::from_nanos(limit_ns.saturating_sub(now).clamp(1_000, MAX_EVENT_WAIT_NS));
        self.step = Step::Spin;
        match self.mode {
            WaitMode::Spin => clock.spin_hint(),
            WaitMode::Event => {
                event_wait(event())?;
                self.step = Step::Event { woke_ns: clock.now_ns() };
            }
            WaitMode::Hybrid => {
                if let Some(e) = expected_ns {
                    if now + self.margin_ns < e {
                        clock.sleep_until_ns((e - self.margin_ns).min(limit_ns));
                        self.step = Step::Timer { woke_ns: clock.now_ns() };
                        return Ok(());
                    }
                }
                let start = *self.spin_start.get_or_insert(now);
                if now - start > SPIN_BUDGET_NS {
                    clock.sleep_until_ns((now + NAP_NS).min(limit_ns));
                    self.step = Step::Timer { woke_ns: clock.now_ns() };
                } else {
                    clock.spin_hint();
                }
            }
            WaitMode::Adaptive => {
                if self.adaptive.event_phase(now) {
                    event_wait(event())?;
                    self.step = Step::Event { woke_ns: clock.now_ns() };
                } else {
                    self.adaptive.spun(now);
                    if self.adaptive.event_until_ns == 0 {
                        clock.spin_hint();
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sys::clock::FakeClock;

    fn calm() -> Option<f64> {
        Some(0.5)
    }

    fn busy() -> Option<f64> {
        Some(60.0)
    }

    #[test]
    fn until_reaches_the_time_in_every_mode() {
        for mode in [WaitMode::Spin, WaitMode::Event, WaitMode::Hybrid, WaitMode::Adaptive] {
            let c = FakeClock::new(0, 100);
            Idler::new(mode, 100_000).with_pressure(calm).with_cpus(4).until(&c, 1_000_000);
            assert!(c.now_ns() >= 1_000_000 && c.now_ns() < 1_000_200, "{mode:?}: {}", c.now_ns());
        }
    }

    /// A fake clock that jumps by `ns` at its first spin after `at` (the process was
    /// preempted).
    struct Preempting {
        inner: FakeClock,
        at: u64,
        ns: u64,
    }

    impl Clock for Preempting {
        fn now_ns(&self) -> u64 {
            self.inner.now_ns()
        }
        fn sleep_until_ns(&self, t_ns: u64) {
            self.inner.sleep_until_ns(t_ns);
        }
        fn spin_hint(&self) {
            if self.inner.now_ns() >= self.at && self.inner.now_ns() < self.at + 1_000 {
                self.inner.advance(self.ns);
            }
            self.inner.spin_hint();
        }
    }

    /// A clock that counts its sleeps and where they ended.
    struct Sleeps {
        inner: FakeClock,
        woke: std::cell::Cell<Option<u64>>,
    }

    impl Clock for Sleeps {
        fn now_ns(&self) -> u64 {
            self.inner.now_ns()
        }
        fn sleep_until_ns(&self, t_ns: u64) {
            self.inner.sleep_until_ns(t_ns);
            self.woke.set(Some(self.inner.now_ns()));
        }
        fn spin_hint(&self) {
            self.inner.spin_hint();
        }
    }

    #[test]
    fn a_release_margin_wakes_before_the_release_and_spins_the_rest() {
        for (mode, margin, woke) in [
            (WaitMode::Event, 0, Some(1_000_000)),
            (WaitMode::Event, 100_000, Some(900_000)),
            (WaitMode::Spin, 100_000, None),
        ] {
            let c = Sleeps { inner: FakeClock::new(0, 100), woke: std::cell::Cell::new(None) };
            Idler::new(mode, 0).with_release_margin(margin).until(&c, 1_000_000);
            assert_eq!(c.woke.get(), woke, "{mode:?} margin {margin}");
            assert!(c.now_ns() >= 1_000_000 && c.now_ns() < 1_000_100, "{mode:?}: {}", c.now_ns());
        }
        // Adaptive on the event (under CPU pressure) sleeps to the margin too.
        let c = Sleeps { inner: FakeClock::new(0, 100), woke: std::cell::Cell::new(None) };
        Idler::new(WaitMode::Adaptive, 0)
            .with_pressure(busy)
            .with_cpus(4)
            .with_release_margin(50_000)
            .until(&c, 1_000_000);
        assert_eq!(c.woke.get(), Some(950_000));
    }

    #[test]
    fn hybrid_sleeps_to_the_margin_then_spins_then_naps() {
        let c = FakeClock::new(0, 1_000);
        let mut idler = Idler::new(WaitMode::Hybrid, 100_000);
        let no_event = |_d: Duration| -> Result<(), LinkError> { panic!("no event in hybrid mode") };
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 900_000);
        // Spinning: 1 µs per step while within the budget.
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 901_000);
        c.advance(SPIN_BUDGET_NS + 1);
        idler.idle(&c, Some(1_000_000), u64::MAX, no_event).unwrap();
        assert_eq!(c.now_ns(), 901_000 + SPIN_BUDGET_NS + 1 + NAP_NS);
        // Never past the limit.
        let limit = c.now_ns() + 10;
        idler.idle(&c, None, limit, no_event).unwrap();
        assert_eq!(c.now_ns(), limit);
    }

    #[test]
    fn event_waits_are_bounded_by_the_limit() {
        let c = FakeClock::new(0, 1);
        let mut idler = Idler::new(WaitMode::Event, 0);
        let mut asked = Duration::ZERO;
        idler
            .idle(&c, None, 300_000, |d| {
                asked = d;
                Ok(())
            })
            .unwrap();
        assert_eq!(asked, Duration::from_micros(300));
        idler
            .idle(&c, None, u64::MAX, |d| {
                asked = d;
                Ok(())
            })
            .unwrap();
        assert_eq!(asked, Duration::from_nanos(MAX_EVENT_WAIT_NS));
    }

    /// One idle step of `idler`; whether it waited on the event.
    fn step(idler: &mut Idler, c: &FakeClock) -> bool {
        let mut waited = false;
        idler
            .idle(c, None, u64::MAX, |_| {
                waited = true;
                Ok(())
            })
            .unwrap();
        waited
    }

    #[test]
    fn adaptive_spins_until_preempted_then_waits_on_the_event_then_spins_again() {
        let c = FakeClock::new(1_000_000, 1_000);
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(4);
        // Spinning: short gaps are not preemptions.
        for _ in 0..100 {
            assert!(!step(&mut idler, &c));
        }
        assert_eq!(idler.counts(), WaitCounts::default());
        // A gap of a time slice: preempted, event waiting for the first back-off.
        c.advance(3_000_000);
        assert!(!step(&mut idler, &c));
        assert_eq!((idler.counts().preemptions, idler.counts().fallbacks), (1, 1));
        assert!(step(&mut idler, &c));
        c.advance(BACKOFF_MIN_NS / 2);
        assert!(step(&mut idler, &c));
        // A message between two waits resets the gap measure, not the phase.
        idler.reset(c.now_ns());
        assert!(step(&mut idler, &c));
        // After the back-off: spinning again; the time in the event phase is counted.
        c.advance(BACKOFF_MIN_NS);
        assert!(!step(&mut idler, &c));
        assert!(idler.counts().event_phase_ns >= BACKOFF_MIN_NS, "{:?}", idler.counts());
        assert_eq!(idler.counts().pressure_holds, 0);
        // Preempted again soon: twice the back-off.
        c.advance(3_000_000);
        step(&mut idler, &c);
        assert_eq!(idler.counts().fallbacks, 2);
        c.advance(BACKOFF_MIN_NS + 1);
        assert!(step(&mut idler, &c), "the second back-off is longer");
        c.advance(BACKOFF_MIN_NS);
        assert!(!step(&mut idler, &c));
        // A gap across a message (the loop's own work) is not a preemption.
        idler.reset(c.now_ns());
        c.advance(3_000_000);
        assert!(!step(&mut idler, &c));
        assert_eq!(idler.counts().fallbacks, 2);
    }

    #[test]
    fn adaptive_waits_on_the_event_throughout_without_a_cpu_to_spare() {
        let c = FakeClock::new(1_000_000, 1_000);
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(2);
        for _ in 0..5 {
            assert!(step(&mut idler, &c));
            c.advance(BACKOFF_MAX_NS);
        }
        let n = idler.counts();
        assert!(n.no_spare_cpu);
        assert_eq!((n.preemptions, n.fallbacks, n.pressure_holds), (0, 0, 0));
        // It sleeps to a release as `event` does.
        let before = c.now_ns();
        idler.until(&c, before + 5_000_000);
        assert_eq!(c.now_ns(), before + 5_000_000);
        // Three CPUs: it spins.
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(3);
        assert!(!step(&mut idler, &c));
        assert!(!idler.counts().no_spare_cpu);
    }

    #[test]
    fn adaptive_counts_the_preemption_during_which_the_message_came() {
        let c = FakeClock::new(1_000_000, 1_000);
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(4);
        for _ in 0..10 {
            assert!(!step(&mut idler, &c));
        }
        // Not run for 2 ms; the message is there when it runs again: a preemption, and the
        // next wait is on the event.
        c.advance(2_000_000);
        idler.reset(c.now_ns());
        assert_eq!((idler.counts().preemptions, idler.counts().fallbacks), (1, 1));
        assert!(step(&mut idler, &c));
        // A message found while spinning normally is not one.
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(4);
        step(&mut idler, &c);
        idler.reset(c.now_ns() + 1_000);
        assert_eq!(idler.counts().preemptions, 0);
        // Waiting for a release, preempted past it: counted although the release has come.
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(4);
        let p = Preempting { inner: FakeClock::new(0, 1_000), at: 500_000, ns: 3_000_000 };
        idler.until(&p, 1_000_000);
        assert_eq!(idler.counts().fallbacks, 1);
    }

    #[test]
    fn adaptive_waits_for_the_release_by_sleeping_once_preempted() {
        let c = FakeClock::new(0, 1_000);
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(calm).with_cpus(4);
        idler.until(&c, 2_000_000);
        assert!(c.now_ns() >= 2_000_000 && c.now_ns() < 2_001_000);
        assert_eq!(idler.counts().fallbacks, 0);
        // Preempted: the next idle step waits on the event.
        step(&mut idler, &c);
        c.advance(1_000_000);
        step(&mut idler, &c);
        assert_eq!(idler.counts().fallbacks, 1);
        let before = c.now_ns();
        idler.until(&c, before + 5_000_000);
        assert_eq!(c.now_ns(), before + 5_000_000, "slept to the release in one go");
    }

    #[test]
    fn adaptive_does_not_spin_while_others_wait_for_a_cpu() {
        let c = FakeClock::new(1_000_000, 1_000);
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(busy).with_cpus(4);
        // Under pressure from the start: event waiting, back-off after back-off.
        assert!(step(&mut idler, &c));
        c.advance(BACKOFF_MIN_NS);
        assert!(step(&mut idler, &c));
        c.advance(BACKOFF_MIN_NS);
        assert!(step(&mut idler, &c));
        assert_eq!((idler.counts().pressure_holds, idler.counts().fallbacks), (3, 0));
        assert_eq!(idler.counts().event_phase_ns, 2 * BACKOFF_MIN_NS);
        // No pressure figure (an older kernel): spin.
        let mut idler = Idler::new(WaitMode::Adaptive, 0).with_pressure(|| None).with_cpus(4);
        assert!(!step(&mut idler, &c));
    }
}
