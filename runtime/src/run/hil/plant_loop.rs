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

use std::sync::atomic::Ordering;

use anyhow::Result;
use companion_core::{Command, Measurement, Pose, Spatial};

use super::config::Timing;
use super::config::WaitMode;
use super::end::PlantEnd;
use super::hold::HoldPolicy;
use super::messages::{report_of, Stamp};
use super::robot::Robot;
use super::stats::{LiveFigures, PlantStats};
use super::wait::Idler;
use super::watch::{PeerLoss, PeerWatch};
use crate::domain::controller::{StepReport, JOINTS};
use crate::domain::record::CommandSource;
use crate::run::sim::Exchange;
use crate::run::spatial::SpatialExchange;
use crate::sys::clock::Clock;
use crate::sys::signals::termination_requested;
use crate::transport::link::PlantLink;
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
    ) -> Result<u64> {
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
        late_timed: bool,
    ) -> Result<Result<Option<Fresh>, Refusal>> {
        let n = want.n;
        let mut fresh: Option<Fresh> = None;
        while let Some(c) = self.link.try_receive()? {
            let now = self.clock.now_ns();
            match check_command::<N>(&c, self.stamp.session, n) {
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
                    if late_timed {
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
        PeerLoss::Hung { silent_ns } => PlantEnd::ControllerHung { cycle, silent_ns },
    }
}

/// Runs the real-time loop over steps `0..=steps`. `sink` gets every row (returns `false` if
/// it could not keep it: counted as a dropped log row).
///
/// Step 0 is a handshake: published at once, its command awaited up to the peer timeout (a
/// cold controller's first step, page faults and all, is not a deadline miss). Real time
/// starts when it is answered: release `n` = start + n·period.
///
/// A plant that finds itself more than a period behind its schedule (it was not scheduled,
/// or was stopped) does not replay the periods it missed in a burst: it counts a stall, skips
/// the missed releases and goes on from now (simulated time then lags the wall clock by the
/// skipped periods). After the last step it waits up to a second for the controller's answer
/// to the last measurement, so that the controller sees the end of the run.
///
/// # Errors
/// A transport failure.
pub fn run_real_time<C: Clock, L: PlantLink, const N: usize, R: Robot<N>>(
    side: &mut PlantSide<'_, C, L>,
    plant: &mut R,
    steps: u64,
    sink: &mut impl FnMut(u64, &R::Row, bool) -> bool,
) -> Result<PlantEnd> {
    let timing = side.timing;
    let period = timing.period_ns;
    let dt = side.stamp.dt;
    let mut idler = Idler::new(timing.wait, timing.spin_margin_ns);
    let mut policy = HoldPolicy::new(timing.hold_periods);
    let mut start = side.clock.now_ns();
    let mut watch = PeerWatch::new(timing.silence_ns, start);
    let mut last_step = steps;
    let mut end = PlantEnd::Completed;
    let mut answered_last;
    // The command acting at the end of the last period, and the last measured delay (s).
    let mut acting = Command::<f64, N>::zero();
    let mut delay = 0.0;
    let mut published = [0_u64; PUBLISHED];
    let mut applied = None;
    let mut n: u64 = 0;
    loop {
        let mut release = start + n * period;
        let meas = plant.measure();
        let mut fl = 0;
        if n == last_step {
            fl |= flags::END_OF_RUN;
        }
        if policy.stopped() {
            fl |= flags::STOPPED;
        }
        idler.until(side.clock, release);
        let now = side.clock.now_ns();
        if n > 0 && now > release + period {
            // A stall: skip the releases missed and go on from now.
            let behind = now - release;
            let skipped = behind / period;
            start += skipped * period;
            release += skipped * period;
            let st = &mut *side.stats;
            st.plant_stalls += 1;
            st.skipped_releases += skipped;
            st.longest_stall_ns = st.longest_stall_ns.max(behind);
        }
        let t_pub = side.publish(n, fl, delay, &meas)?;
        let slot = |seq: u64| (seq % PUBLISHED as u64) as usize;
        published[slot(n)] = t_pub;
        // The handshake's answer (a cold first step) and, at the end of a completed run, the
        // last answer (the controller's confirmation) are awaited up to the peer timeout.
        let patient = n == 0 || (n == last_step && end == PlantEnd::Completed);
        let deadline = if patient { t_pub + timing.peer_timeout_ns } else { release + timing.deadline_ns };
        if n > 0 {
            side.stats.jitter.record(t_pub - release);
        }
        if t_pub > deadline {
            side.stats.plant_overruns += 1;
        }
        // Wait for command n (not once the controller is known to be gone).
        let mut fresh = None;
        let mut refused = None;
        idler.reset();
        let peer_lost = matches!(end, PlantEnd::ControllerDied { .. } | PlantEnd::ControllerGone { .. });
        if !peer_lost {
            let want = Wanted { n, max_age: u64::from(timing.max_command_age), applied };
            loop {
                match side.drain::<N>(want, true)? {
                    // The answer to `n`, or an older one newer than any found before.
                    Ok(Some(f)) if fresh.is_none_or(|(c, _): Fresh| c.seq <= f.0.seq) => {
                        if fresh.is_some_and(|(c, _)| c.seq < f.0.seq) {
                            side.stats.late_commands += 1;
                        }
                        fresh = Some(f);
                    }
                    Ok(_) => {}
                    Err(why) => refused = Some(why),
                }
                let current = fresh.is_some_and(|(c, _)| c.seq == n);
                if current || refused.is_some() || side.clock.now_ns() >= deadline {
                    break;
                }
                let link = &mut *side.link;
                idler.idle(side.clock, None, deadline, |d| link.wait_event(d))?;
            }
        }
        if n == 0 {
            start = side.clock.now_ns();
            side.stats.run_window_ns.0 = start;
        }
        answered_last = fresh.is_some();
        let stats = &mut *side.stats;
        // Within period n, the fresh command takes effect when it arrived (from the start at
        // n = 0, whose arrival starts the clock).
        let mut switch_at = 0.0;
        let (report, source) = match (fresh, refused) {
            (_, Some(why)) => {
                end = PlantEnd::Refused(why);
                last_step = n;
                (super::hold::stop_report(), CommandSource::Stopped)
            }
            (Some((c, t_rx)), None) => {
                stats.fresh += 1;
                if n > 0 {
                    let gap = t_rx.saturating_sub(watch.last_heard_ns());
                    stats.longest_command_gap_ns = stats.longest_command_gap_ns.max(gap);
                    if gap > (u64::from(timing.hold_periods) + 1) * period {
                        stats.command_gaps_over_hold += 1;
                    }
                }
                watch.heard(t_rx);
                if timing.wait.uses_events() && !c.has(flags::NOTIFIES) && !stats.event_fallback {
                    // The controller does not notify: poll instead of sleeping on its event.
                    idler = Idler::new(WaitMode::Hybrid, timing.spin_margin_ns);
                    stats.event_fallback = true;
                }
                if n > 0 {
                    let scale = |ns: u64| ns as f64 * dt / period as f64;
                    switch_at = scale(t_rx.saturating_sub(t_pub)).min(dt * (1.0 - 1e-9));
                    delay = if c.seq == n {
                        switch_at
                    } else {
                        // An older answer: its delay counts from its own measurement.
                        stats.aged_commands += 1;
                        scale(t_rx.saturating_sub(published[slot(c.seq)]))
                    };
                }
                applied = Some(c.seq);
                policy.fresh(report_of::<N>(&c))
            }
            (None, None) => {
                stats.deadline_misses += 1;
                let was_stopped = policy.stopped();
                let r = policy.missed();
                // A stop event is the hold running out on a moving robot (not the start of a
                // run before the first command).
                if policy.stopped() && !was_stopped && policy.has_commanded() {
                    stats.stop_events += 1;
                    stats.first_stop_t.get_or_insert(plant.time());
                }
                stats.max_consecutive_misses =
                    stats.max_consecutive_misses.max(u64::from(policy.consecutive()));
                r
            }
        };
        match source {
            CommandSource::Held => stats.held_periods += 1,
            CommandSource::Stopped => stats.stopped_periods += 1,
            CommandSource::Fresh => {}
        }
        let row = plant.row(&report, source);
        let last = n == last_step;
        if !sink(n, &row, last) {
            stats.log_rows_dropped += 1;
        }
        stats.cycles += 1;
        let live = side.live;
        live.cycle.store(n + 1, Ordering::Relaxed);
        live.misses.store(stats.deadline_misses, Ordering::Relaxed);
        live.stopped.store(policy.stopped(), Ordering::Relaxed);
        if last {
            break;
        }
        plant.advance(&acting, &report.command, switch_at, dt)?;
        acting = report.command;
        if n % 256 == 255 {
            // A bucket scan (tens of µs) in the slack before the next release.
            live.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
        }
        // A silent controller: is it still there? (Degraded state only: a few syscalls.)
        if fresh.is_none() && last_step > n + 1 {
            let now = side.clock.now_ns();
            if let Some(loss) = watch.check(now, timing.peer_timeout_ns, side.link)? {
                end = lost(loss, n);
                last_step = n + 1;
            }
        }
        if termination_requested() && last_step > n + 1 {
            end = PlantEnd::Interrupted { cycle: n + 1 };
            last_step = n + 1;
        }
        n += 1;
    }
    if !answered_last && matches!(end, PlantEnd::Completed | PlantEnd::Interrupted { .. }) {
        side.goodbye(last_step, &mut watch)?;
    }
    let stats = &mut *side.stats;
    stats.run_window_ns.1 = side.clock.now_ns();
    stats.wait = idler.counts();
    side.live.p99_ns.store(stats.round_trip.quantile(0.99), Ordering::Relaxed);
    Ok(end)
}

impl<C: Clock, L: PlantLink> PlantSide<'_, C, L> {
    /// Waits up to [`GOODBYE_NS`] for the answer to the last measurement `last` (not applied:
    /// the run is over), while the controller is alive.
    fn goodbye(&mut self, last: u64, watch: &mut PeerWatch) -> Result<()> {
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

/// The controller was lost during a lockstep exchange.
#[derive(Clone, Copy, Debug, thiserror::Error)]
#[error("{}", .0.describe())]
pub struct Lost(pub PlantEnd);

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
    ) -> Result<StepReport<N>> {
        let fl = if n == self.steps { flags::END_OF_RUN } else { 0 };
        let side = &mut self.side;
        let t_pub = side.publish(n, fl, self.delay, meas)?;
        side.stats.cycles += 1;
        side.live.cycle.store(n + 1, Ordering::Relaxed);
        let wait = if side.stats.event_fallback { WaitMode::Hybrid } else { side.timing.wait };
        let mut idler = Idler::new(wait, side.timing.spin_margin_ns);
        let mut watch = PeerWatch::new(side.timing.silence_ns, t_pub);
        loop {
            match side.drain::<N>(Wanted::current(n), false)? {
                Ok(Some((c, _))) => {
                    side.stats.fresh += 1;
                    if wait == WaitMode::Event && !c.has(flags::NOTIFIES) {
                        // The controller does not notify: poll instead of sleeping on its event.
                        side.stats.event_fallback = true;
                    }
                    return Ok(report_of::<N>(&c));
                }
                Ok(None) => {}
                Err(why) => return Err(Lost(PlantEnd::Refused(why)).into()),
            }
            let now = side.clock.now_ns();
            if let Some(loss) = watch.check(now, side.timing.peer_timeout_ns, side.link)? {
                return Err(Lost(lost(loss, n)).into());
            }
            if termination_requested() {
                return Err(Lost(PlantEnd::Interrupted { cycle: n }).into());
            }
            let link = &mut *side.link;
            idler.idle(side.clock, None, u64::MAX, |d| link.wait_event(d))?;
        }
    }
}

impl<C: Clock, L: PlantLink> Exchange for Lockstep<'_, C, L> {
    fn exchange(&mut self, n: u64, meas: &Measurement<f64, JOINTS>) -> Result<StepReport> {
        self.exchange_any(n, meas)
    }
}

impl<C: Clock, L: PlantLink, const N: usize> SpatialExchange<N> for Lockstep<'_, C, L> {
    fn exchange(&mut self, n: u64, meas: &Measurement<f64, N, Spatial>) -> Result<StepReport<N>> {
        self.exchange_any(n, meas)
    }
}
