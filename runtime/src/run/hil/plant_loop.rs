//! The plant's two loops: the real-time loop ([`run_real_time`]: release at absolute times,
//! publish, wait for the command until the deadline, apply it or the hold policy, log,
//! advance) and the lockstep exchange ([`Lockstep`], for `sim::run_loop`: publish, then wait
//! for the answer however long it takes).
//!
//! **The delay.** In real time a command takes effect when it arrives: over period `n` the
//! plant applies the command that was acting until then (the previous one, or a held one)
//! for the first `d` of the period and the fresh command for the rest, where `d` is the time
//! from measurement `n`'s timestamp to the command's arrival, on the plant's clock, scaled to
//! the plant's time (`d = (t_arrival − plant_time_ns) · dt / period`). The next measurement
//! announces that delay, and the controller's law predicts over it. In lockstep the plant
//! announces the scenario's simulated pure delay (0 unless `--delay`), which `sim::run_loop`
//! applies — the same as `companion sim`.
//!
//! **Older answers** (`--max-command-age K`, for a link whose round trip is longer than the
//! deadline): when no answer to measurement `n` came by the deadline, the newest answer to
//! one of `n − K … n − 1` that is newer than the last applied command is applied instead, from
//! when the plant took it (its arrival, or the start of the period if it came after the last
//! deadline). Its delay is then measured from *its own* measurement's timestamp:
//! `d = (t_taken − plant_time_ns(seq)) · dt / period`, which exceeds a period; the next
//! measurement announces it, and the controller predicts over it. Such a period is not a
//! deadline miss (counted as `aged_commands`). With `K = 0` (the default) an answer to an
//! earlier period is late and dropped, as before.

use std::ops::ControlFlow;
use std::sync::atomic::Ordering;

use companion_core::{Command, Measurement, Pose};
use companion_plant::Simulated;

use super::config::Timing;
use super::config::WaitMode;
use super::end::PlantEnd;
use super::hold::HoldPolicy;
use super::messages::{report_of, Stamp};
use super::misses::{MissLedger, Period};
use super::stats::{LiveFigures, PlantStats};
use super::wait::Idler;
use super::watch::{PeerLoss, PeerWatch};
use crate::domain::controller::{StepReport, JOINTS};
use crate::domain::record::{CommandSource, Row, Task};
use crate::run::robot::Robot;
use crate::run::sim::{Exchange, LoopError};
use crate::sys::clock::Clock;
use crate::sys::signals::termination_requested;
use crate::transport::link::{LinkError, PlantLink};
use crate::transport::wire::target::WireSpace;
use crate::transport::wire::{check_command, flags, CommandMsg, MeasurementMsg, Refusal, WireError};

/// The plant's side of an exchange: clock, transport, timing, the stamp of its measurements,
/// and what it counts. The robot (and with it the number of joints and the target's space)
/// is the loop's ([`Robot`]).
#[derive(Debug)]
pub struct PlantSide<'a, C: Clock, L: PlantLink> {
    /// The clock.
    pub clock: &'a C,
    /// The transport.
    pub link: &'a mut L,
    /// Timing options.
    pub timing: Timing,
    /// What every measurement is stamped with.
    pub stamp: Stamp,
    /// Statistics.
    pub stats: &'a mut PlantStats,
    /// Live figures.
    pub live: &'a LiveFigures,
    /// The last measurement published.
    pub last_sent: Option<MeasurementMsg>,
}

/// A fresh command and when it arrived (plant's clock, ns).
type Fresh = (CommandMsg, u64);

/// Publication times of the last measurements, by `seq` modulo its length (a power of two
/// above [`super::config::MAX_COMMAND_AGE`]).
const PUBLISHED: usize = 16;

/// Which answers the plant takes in period `n`: the answer to `n`, or (real time with
/// `--max-command-age`) an older one newer than the last applied.
#[derive(Clone, Copy, Debug)]
struct Wanted {
    /// The period.
    n: u64,
    /// The oldest age accepted (periods).
    max_age: u64,
    /// The `seq` of the last applied command.
    applied: Option<u64>,
}

impl Wanted {
    /// Only the answer to `n`.
    fn current(n: u64) -> Self {
        Self { n, max_age: 0, applied: None }
    }

    /// Whether a late answer to `seq` may still be applied.
    fn takes_older(&self, seq: u64) -> bool {
        self.n - seq <= self.max_age && self.applied.is_none_or(|a| seq > a)
    }
}

impl<C: Clock, L: PlantLink> PlantSide<'_, C, L> {
    /// Publishes measurement `n` now, announcing `delay`; returns the publication time.
    #[inline]
    fn publish<const N: usize, S: WireSpace>(
        &mut self,
        n: u64,
        fl: u32,
        delay: f64,
        meas: &Measurement<f64, N, S>,
    ) -> Result<u64, LinkError> {
        let t_pub = self.clock.now_ns();
        let m = self.stamp.message(n, fl, t_pub, delay, meas);
        self.link.publish(&m)?;
        self.last_sent = Some(m);
        Ok(t_pub)
    }

    /// Takes every waiting command; returns the last one that answers measurement `n` (or,
    /// if none does, the newest older answer that `want` takes), or the controller's refusal
    /// of this plant.
    #[inline]
    fn drain<const N: usize>(
        &mut self,
        want: Wanted,
        mut misses: Option<&mut MissLedger>,
    ) -> Result<Result<Option<Fresh>, Refusal>, LinkError> {
        let n = want.n;
        let mut fresh: Option<Fresh> = None;
        while let Some(c) = self.link.try_receive()? {
            let now = self.clock.now_ns();
            let checked = check_command::<N>(&c, self.stamp.session, n);
            // A valid answer, current or late: the controller is alive now (the watch's news),
            // and the misses it answers get their cause.
            let valid = matches!(checked, Ok(()))
                || matches!(checked, Err(WireError::Stale(seq)) if check_command::<N>(&c, self.stamp.session, seq).is_ok());
            if valid {
                self.stats.last_valid_answer_ns = now;
                if let Some(ledger) = misses.as_deref_mut() {
                    ledger.answered(&c, &mut self.stats.miss_causes);
                }
            }
            match checked {
                Ok(()) => {
                    self.stats.timing(now, &c);
                    self.stats.controller_skipped += u64::from(c.skipped);
                    fresh = Some((c, now));
                }
                // An older answer, itself valid, newer than what is applied and than what this
                // drain found: taken (and the one it supersedes counted late).
                Err(WireError::Stale(seq))
                    if want.takes_older(seq)
                        && check_command::<N>(&c, self.stamp.session, seq).is_ok()
                        && fresh.is_none_or(|(f, _)| f.seq < seq) =>
                {
                    self.stats.timing(now, &c);
                    self.stats.controller_skipped += u64::from(c.skipped);
                    if fresh.is_some() {
                        self.stats.late_commands += 1;
                    }
                    fresh = Some((c, now));
                }
                Err(WireError::Refused(code)) => {
                    let mine = self
                        .last_sent
                        .unwrap_or_else(|| self.stamp.message(n, 0, 0, 0.0, &zero_measurement()));
                    match Refusal::from_command(&c, &mine) {
                        Some(why) => return Ok(Err(why)),
                        None => self.stats.invalid.count(WireError::Status(code)),
                    }
                }
                // A command for an earlier period that is also malformed counts as malformed.
                Err(WireError::Stale(_)) if !finite_command::<N>(&c) => {
                    self.stats.invalid.count(WireError::NonFinite)
                }
                Err(WireError::Stale(_)) => {
                    self.stats.late_commands += 1;
                    if misses.is_some() {
                        self.stats.timing(now, &c);
                    }
                }
                Err(e) => self.stats.invalid.count(e),
            }
        }
        Ok(Ok(fresh))
    }
}

/// A measurement of nothing (only its header is read, to describe a refusal that came before
/// any measurement was published — which a correct controller never sends).
#[cold]
fn zero_measurement() -> Measurement<f64, JOINTS> {
    Measurement {
        t: 0.0,
        base: Pose::identity(),
        steering: 0.0,
        joints: companion_core::nalgebra::SVector::zeros(),
        target: Pose::identity(),
        target_velocity: companion_core::nalgebra::Vector3::zeros(),
    }
}

/// Whether every velocity of `c` is finite.
fn finite_command<const N: usize>(c: &CommandMsg) -> bool {
    let cmd = c.command::<N>();
    let p = &cmd.platform;
    [p.v, p.v_lat, p.omega, p.v_xi].iter().chain(cmd.joints.iter()).all(|x| x.is_finite())
}

/// How long the plant waits, after its last measurement, for the answer to it (so that the
/// controller sees the end of the run before the plant's ports go away) (ns).
const GOODBYE_NS: u64 = 1_000_000_000;

fn lost(loss: PeerLoss, cycle: u64) -> PlantEnd {
    match loss {
        PeerLoss::Died { pid, silent_ns, expired } => {
            PlantEnd::ControllerDied { pid, cycle, silent_ns, expired }
        }
        PeerLoss::Gone => PlantEnd::ControllerGone { cycle },
        PeerLoss::Hung { silent_ns, pid } => PlantEnd::ControllerHung { cycle, silent_ns, pid },
    }
}

/// What the real-time loop carries from one period to the next.
#[derive(Debug)]
struct Cycle<const N: usize> {
    /// Release 0's time, moved on by each stall (ns).
    start: u64,
    /// The run's last step: the scenario's, or earlier once the run ends early.
    last_step: u64,
    /// How the run ends (so far).
    end: PlantEnd,
    /// The command acting at the end of the last period.
    acting: Command<f64, N>,
    /// The last measured delay (s), announced in the next measurement.
    delay: f64,
    /// Publication times of the last measurements ([`PUBLISHED`]).
    published: [u64; PUBLISHED],
    /// The `seq` of the last applied command.
    applied: Option<u64>,
    /// How the loop waits.
    idler: Idler,
    /// Hold, then stop, after misses.
    policy: HoldPolicy<N>,
    /// The controller's liveness.
    watch: PeerWatch,
    /// The missed periods waiting for their answer, to name the cause.
    misses: MissLedger,
}

impl<const N: usize> Cycle<N> {
    fn new(timing: &Timing, steps: u64, now: u64) -> Self {
        Self {
            start: now,
            last_step: steps,
            end: PlantEnd::Completed,
            acting: Command::zero(),
            delay: 0.0,
            published: [0; PUBLISHED],
            applied: None,
            idler: Idler::new(timing.wait, timing.spin_margin_ns)
                .with_release_margin(timing.release_margin_ns()),
            policy: HoldPolicy::new(timing.hold_periods),
            watch: PeerWatch::new(timing.silence_ns, now),
            misses: MissLedger::default(),
        }
    }

    /// Ends the run after step `last` with `why`.
    fn end_after(&mut self, last: u64, why: PlantEnd) {
        self.end = why;
        self.last_step = last;
    }
}

/// The slot of measurement `seq` in [`Cycle::published`].
fn slot(seq: u64) -> usize {
    (seq % PUBLISHED as u64) as usize
}

/// A period's measurement, published: when, and until when its answer is awaited (ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Released {
    /// The scheduled release.
    release: u64,
    /// The publication time (the measurement's stamp).
    t_pub: u64,
    /// When the send returned.
    t_sent: u64,
    /// The deadline for its answer.
    deadline: u64,
}

/// What the plant heard in one period by its deadline.
#[derive(Clone, Copy, Debug, Default)]
struct Heard {
    /// The answer taken (to this period, or an older one under `--max-command-age`).
    fresh: Option<Fresh>,
    /// The controller's refusal of this plant.
    refused: Option<Refusal>,
}

/// What a period applies: the report, where its command came from, and when within the
/// period it takes effect (s).
#[derive(Clone, Copy, Debug)]
struct Applied<const N: usize> {
    report: StepReport<N>,
    source: CommandSource,
    switch_at: f64,
}

impl<C: Clock, L: PlantLink> PlantSide<'_, C, L> {
    /// **Release**: waits for period `n`'s release, skips the releases a stall missed, and
    /// publishes `meas` (its flags: the end of the run, a stopped robot).
    ///
    /// A plant more than a period behind its schedule (not scheduled, or stopped) does not
    /// replay the periods it missed in a burst: it counts a stall and goes on from now.
    fn release<const N: usize, S: WireSpace>(
        &mut self,
        cy: &mut Cycle<N>,
        n: u64,
        meas: &Measurement<f64, N, S>,
    ) -> Result<Released, LinkError> {
        let period = self.timing.period_ns;
        let mut fl = 0;
        if n == cy.last_step {
            fl |= flags::END_OF_RUN;
        }
        if cy.policy.stopped() {
            fl |= flags::STOPPED;
        }
        let mut release = cy.start + n * period;
        cy.idler.until(self.clock, release);
        let now = self.clock.now_ns();
        if n > 0 && now > release + period {
            let behind = now - release;
            let skipped = behind / period;
            cy.start += skipped * period;
            release += skipped * period;
            let st = &mut *self.stats;
            st.plant_stalls += 1;
            st.skipped_releases += skipped;
            st.longest_stall_ns = st.longest_stall_ns.max(behind);
            // Not the controller's silence: this process was not running.
            cy.watch.excuse(behind - period);
        }
        let t_pub = self.publish(n, fl, cy.delay, meas)?;
        let t_sent = self.clock.now_ns();
        cy.published[slot(n)] = t_pub;
        // The handshake's answer (a cold first step) and, at the end of a completed run, the
        // last answer (the controller's confirmation) are awaited up to the peer timeout.
        let patient = n == 0 || (n == cy.last_step && cy.end == PlantEnd::Completed);
        let deadline =
            if patient { t_pub + self.timing.peer_timeout_ns } else { release + self.timing.deadline_ns };
        if n > 0 {
            self.stats.jitter.record(t_pub - release);
        }
        if t_pub > deadline {
            self.stats.plant_overruns += 1;
        }
        Ok(Released { release, t_pub, t_sent, deadline })
    }

    /// **Await the command**: drains and waits until the answer to `n` (or a refusal) came or
    /// the deadline passed — not at all once the controller is known to be gone. Real time
    /// starts when the handshake (`n = 0`) is answered.
    fn await_command<const N: usize>(
        &mut self,
        cy: &mut Cycle<N>,
        n: u64,
        deadline: u64,
    ) -> Result<Heard, LinkError> {
        let mut heard = Heard::default();
        cy.idler.reset(self.clock.now_ns());
        let peer_lost = matches!(cy.end, PlantEnd::ControllerDied { .. } | PlantEnd::ControllerGone { .. });
        if !peer_lost {
            let want = Wanted { n, max_age: u64::from(self.timing.max_command_age), applied: cy.applied };
            loop {
                match self.drain::<N>(want, Some(&mut cy.misses))? {
                    // The answer to `n`, or an older one newer than any found before.
                    Ok(Some(f)) if heard.fresh.is_none_or(|(c, _): Fresh| c.seq <= f.0.seq) => {
                        if heard.fresh.is_some_and(|(c, _)| c.seq < f.0.seq) {
                            self.stats.late_commands += 1;
                        }
                        heard.fresh = Some(f);
                    }
                    Ok(_) => {}
                    Err(why) => heard.refused = Some(why),
                }
                let current = heard.fresh.is_some_and(|(c, _)| c.seq == n);
                if current || heard.refused.is_some() || self.clock.now_ns() >= deadline {
                    break;
                }
                let link = &mut *self.link;
                cy.idler.idle(self.clock, None, deadline, |d| link.wait_event(d))?;
            }
        }
        if n == 0 {
            cy.start = self.clock.now_ns();
            self.stats.run_window_ns.0 = cy.start;
        }
        Ok(heard)
    }

    /// **Apply**: what period `n` applies — the fresh command from its arrival (its delay
    /// measured for the next measurement), or the hold policy's after a miss, or the stop
    /// after a refusal (which ends the run) — counted. `t` is the plant's time (s).
    fn apply<const N: usize>(
        &mut self,
        cy: &mut Cycle<N>,
        n: u64,
        released: Released,
        heard: Heard,
        t: f64,
    ) -> Applied<N> {
        let Released { release, t_pub, t_sent, deadline } = released;
        let timing = self.timing;
        let (period, dt) = (timing.period_ns, self.stamp.dt);
        let stats = &mut *self.stats;
        let mut switch_at = 0.0;
        let (report, source) = match heard {
            Heard { refused: Some(why), .. } => {
                cy.end_after(n, PlantEnd::Refused(why));
                (super::hold::stop_report(), CommandSource::Stopped)
            }
            Heard { fresh: Some((c, t_rx)), refused: None } => {
                stats.fresh += 1;
                if n > 0 {
                    let gap = t_rx.saturating_sub(cy.watch.last_heard_ns());
                    stats.longest_command_gap_ns = stats.longest_command_gap_ns.max(gap);
                    if gap > (u64::from(timing.hold_periods) + 1) * period {
                        stats.command_gaps_over_hold += 1;
                    }
                }
                cy.watch.heard(t_rx);
                if timing.wait.uses_events() && !c.has(flags::NOTIFIES) && !stats.event_fallback {
                    // The controller does not notify: poll instead of sleeping on its event.
                    cy.idler = Idler::new(WaitMode::Hybrid, timing.spin_margin_ns);
                    stats.event_fallback = true;
                }
                if n > 0 {
                    let scale = |ns: u64| ns as f64 * dt / period as f64;
                    switch_at = scale(t_rx.saturating_sub(t_pub)).min(dt * (1.0 - 1e-9));
                    cy.delay = if c.seq == n {
                        switch_at
                    } else {
                        // An older answer: its delay counts from its own measurement.
                        stats.aged_commands += 1;
                        scale(t_rx.saturating_sub(cy.published[slot(c.seq)]))
                    };
                }
                cy.applied = Some(c.seq);
                cy.policy.fresh(report_of::<N>(&c))
            }
            Heard { fresh: None, refused: None } => {
                stats.deadline_misses += 1;
                cy.misses.missed(Period { seq: n, release, t_pub, t_sent, deadline }, &mut stats.miss_causes);
                let was_stopped = cy.policy.stopped();
                let r = cy.policy.missed();
                // A stop event is the hold running out on a moving robot (not the start of a
                // run before the first command).
                if cy.policy.stopped() && !was_stopped && cy.policy.has_commanded() {
                    stats.stop_events += 1;
                    stats.first_stop_t.get_or_insert(t);
                }
                stats.max_consecutive_misses =
                    stats.max_consecutive_misses.max(u64::from(cy.policy.consecutive()));
                r
            }
        };
        Applied { report, source, switch_at }
    }

    /// **Account**: period `n`'s counts (held or stopped, a log row the sink could not keep)
    /// and the live figures.
    fn account<const N: usize>(&mut self, cy: &Cycle<N>, n: u64, source: CommandSource, kept: bool) {
        let stats = &mut *self.stats;
        match source {
            CommandSource::Held => stats.held_periods += 1,
            CommandSource::Stopped => stats.stopped_periods += 1,
            CommandSource::Fresh => {}
        }
        if !kept {
            stats.log_rows_dropped += 1;
        }
        stats.cycles += 1;
        let live = self.live;
        live.cycle.store(n + 1, Ordering::Relaxed);
        live.misses.store(stats.deadline_misses, Ordering::Relaxed);
        live.stopped.store(cy.policy.stopped(), Ordering::Relaxed);
        if n % 256 == 255 {
            // A bucket scan (tens of µs) in the slack before the next release.
            live.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
        }
    }

    /// **Liveness**: after a period without an answer, whether the controller is still there
    /// (a few syscalls, in the degraded state only); and SIGINT/SIGTERM. Either ends the run
    /// after the next step.
    fn look_out<const N: usize>(
        &mut self,
        cy: &mut Cycle<N>,
        n: u64,
        answered: bool,
    ) -> Result<(), LinkError> {
        if !answered && cy.last_step > n + 1 {
            let now = self.clock.now_ns();
            cy.watch.news(self.stats.last_valid_answer_ns);
            if let Some(loss) = cy.watch.check(now, self.timing.peer_timeout_ns, self.link)? {
                cy.end_after(n + 1, lost(loss, n));
            }
        }
        if termination_requested() && cy.last_step > n + 1 {
            cy.end_after(n + 1, PlantEnd::Interrupted { cycle: n + 1 });
        }
        Ok(())
    }
}

/// Runs the real-time loop over steps `0..=steps`. `sink` gets every row (returns `false` if
/// it could not keep it: counted as a dropped log row).
///
/// Each period is five phases, in this order (private methods of [`PlantSide`], each
/// unit-tested on the fake clock): `release` (wait for the release time, publish the
/// measurement), `await_command` (until the deadline), `apply` (the fresh command, or the
/// hold policy's), log the row and `account`, advance the robot, and `look_out` for a lost
/// controller or a signal.
///
/// Step 0 is a handshake: published at once, its command awaited up to the peer timeout (a
/// cold controller's first step, page faults and all, is not a deadline miss). Real time
/// starts when it is answered: release `n` = start + n·period. After the last step the plant
/// waits up to a second for the controller's answer to the last measurement, so that the
/// controller sees the end of the run.
///
/// # Errors
/// A transport failure, or a step the plant refused.
pub fn run_real_time<C: Clock, L: PlantLink, P: Simulated<N, Space: Task + WireSpace>, const N: usize>(
    side: &mut PlantSide<'_, C, L>,
    plant: &mut Robot<'_, P, N>,
    steps: u64,
    sink: &mut impl FnMut(u64, &Row<P::Space, N>, bool) -> bool,
) -> Result<PlantEnd, LoopError> {
    let runqueue_before = crate::sys::rt::runqueue_wait_ns();
    let mut cy = Cycle::<N>::new(&side.timing, steps, side.clock.now_ns());
    let mut answered_last;
    let mut n: u64 = 0;
    loop {
        let meas = plant.measure();
        let released = side.release(&mut cy, n, &meas)?;
        let heard = side.await_command(&mut cy, n, released.deadline)?;
        answered_last = heard.fresh.is_some();
        let applied = side.apply(&mut cy, n, released, heard, plant.time());
        let row = plant.row(&applied.report, applied.source, true);
        let last = n == cy.last_step;
        let kept = sink(n, &row, last);
        side.account(&cy, n, applied.source, kept);
        if last {
            break;
        }
        plant.advance(&cy.acting, &applied.report.command, applied.switch_at, side.stamp.dt)?;
        cy.acting = applied.report.command;
        side.look_out(&mut cy, n, heard.fresh.is_some())?;
        n += 1;
    }
    if !answered_last && matches!(cy.end, PlantEnd::Completed | PlantEnd::Interrupted { .. }) {
        side.goodbye(cy.last_step, &mut cy.watch)?;
    }
    let stats = &mut *side.stats;
    cy.misses.finish(&mut stats.miss_causes);
    stats.run_window_ns.1 = side.clock.now_ns();
    stats.wait = cy.idler.counts();
    stats.runqueue_wait_ns =
        runqueue_before.zip(crate::sys::rt::runqueue_wait_ns()).map(|(a, b)| b.saturating_sub(a));
    side.live.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
    Ok(cy.end)
}

impl<C: Clock, L: PlantLink> PlantSide<'_, C, L> {
    /// Waits up to [`GOODBYE_NS`] for the answer to the last measurement `last` (not applied:
    /// the run is over), while the controller is alive.
    fn goodbye(&mut self, last: u64, watch: &mut PeerWatch) -> Result<(), LinkError> {
        let t0 = self.clock.now_ns();
        loop {
            while let Some(c) = self.link.try_receive()? {
                if c.seq == last && c.session == self.stamp.session {
                    return Ok(());
                }
            }
            let now = self.clock.now_ns();
            if now >= t0 + GOODBYE_NS || watch.check(now, GOODBYE_NS, self.link)?.is_some() {
                return Ok(());
            }
            self.clock.sleep_until_ns(now + 200_000);
        }
    }
}

/// The lockstep exchange: publish, then wait for the answer however long it takes (while the
/// controller is alive and answers within the peer timeout).
#[derive(Debug)]
pub struct Lockstep<'a, C: Clock, L: PlantLink> {
    /// The plant's side.
    pub side: PlantSide<'a, C, L>,
    /// The last step (its measurement carries the end-of-run flag).
    pub steps: u64,
    /// The scenario's simulated pure delay (s), announced in every measurement.
    pub delay: f64,
}

impl<C: Clock, L: PlantLink> Lockstep<'_, C, L> {
    /// Publishes measurement `n` and waits for its answer (see [`Lockstep`]).
    fn exchange_any<const N: usize, S: WireSpace>(
        &mut self,
        n: u64,
        meas: &Measurement<f64, N, S>,
    ) -> Result<ControlFlow<PlantEnd, StepReport<N>>, LinkError> {
        let fl = if n == self.steps { flags::END_OF_RUN } else { 0 };
        let side = &mut self.side;
        let t_pub = side.publish(n, fl, self.delay, meas)?;
        side.stats.cycles += 1;
        side.live.cycle.store(n + 1, Ordering::Relaxed);
        let wait = if side.stats.event_fallback { WaitMode::Hybrid } else { side.timing.wait };
        let mut idler = Idler::new(wait, side.timing.spin_margin_ns);
        let mut watch = PeerWatch::new(side.timing.silence_ns, t_pub);
        loop {
            match side.drain::<N>(Wanted::current(n), None)? {
                Ok(Some((c, _))) => {
                    side.stats.fresh += 1;
                    if wait == WaitMode::Event && !c.has(flags::NOTIFIES) {
                        // The controller does not notify: poll instead of sleeping on its event.
                        side.stats.event_fallback = true;
                    }
                    return Ok(ControlFlow::Continue(report_of::<N>(&c)));
                }
                Ok(None) => {}
                Err(why) => return Ok(ControlFlow::Break(PlantEnd::Refused(why))),
            }
            let now = side.clock.now_ns();
            if let Some(loss) = watch.check(now, side.timing.peer_timeout_ns, side.link)? {
                return Ok(ControlFlow::Break(lost(loss, n)));
            }
            if termination_requested() {
                return Ok(ControlFlow::Break(PlantEnd::Interrupted { cycle: n }));
            }
            let link = &mut *side.link;
            idler.idle(side.clock, None, u64::MAX, |d| link.wait_event(d))?;
        }
    }
}

impl<C: Clock, L: PlantLink, const N: usize, S: WireSpace> Exchange<N, S> for Lockstep<'_, C, L> {
    type End = PlantEnd;

    fn exchange(
        &mut self,
        n: u64,
        meas: &Measurement<f64, N, S>,
    ) -> Result<ControlFlow<PlantEnd, StepReport<N>>, LinkError> {
        self.exchange_any(n, meas)
    }
}

#[cfg(test)]
mod tests;
