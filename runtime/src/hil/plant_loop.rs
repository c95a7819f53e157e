//! The plant's two loops: the real-time loop ([`run_real_time`]: release at absolute times,
//! publish, wait for the command until the deadline, apply it or the hold policy, log,
//! advance) and the lockstep exchange ([`Lockstep`], for `sim::run_loop`: publish, then wait
//! for the answer however long it takes).

use std::sync::atomic::Ordering;

use anyhow::Result;
use companion_core::{Measurement, Pose, Rpr};
use companion_plant::Plant;

use super::config::Timing;
use super::end::PlantEnd;
use super::hold::HoldPolicy;
use super::messages::{report_of, Stamp};
use super::stats::{LiveFigures, PlantStats};
use super::wait::Idler;
use super::watch::{PeerLoss, PeerWatch};
use crate::clock::Clock;
use crate::controller::{StepReport, JOINTS};
use crate::link::PlantLink;
use crate::record::{CommandSource, Row};
use crate::signals::termination_requested;
use crate::sim::{self, Exchange};
use crate::wire::{check_command, flags, CommandMsg, WireError};

/// The plant's side of an exchange: clock, transport, timing, the stamp of its measurements,
/// and what it counts.
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
    /// `r*_ed`, for the true tracking error recorded with each row.
    pub target_in_effector: Pose<f64>,
}

impl<C: Clock, L: PlantLink> PlantSide<'_, C, L> {
    /// Publishes measurement `n` now; returns the publication time.
    #[inline]
    fn publish(&mut self, n: u64, fl: u32, meas: &Measurement<f64, JOINTS>) -> Result<u64> {
        let t_pub = self.clock.now_ns();
        self.link.publish(&self.stamp.message(n, fl, t_pub, meas))?;
        Ok(t_pub)
    }

    /// Takes every waiting command; returns the last one that answers measurement `n`.
    #[inline]
    fn drain(&mut self, n: u64, late_timed: bool) -> Result<Option<CommandMsg>> {
        let mut fresh = None;
        while let Some(c) = self.link.try_receive()? {
            let now = self.clock.now_ns();
            match check_command::<JOINTS>(&c, self.stamp.session, n) {
                Ok(()) => {
                    self.stats.timing(now, &c);
                    self.stats.controller_skipped += u64::from(c.skipped);
                    fresh = Some(c);
                }
                // A command for an earlier period that is also malformed counts as malformed.
                Err(WireError::Stale(_)) if !finite_command(&c) => {
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
        Ok(fresh)
    }
}

/// Whether every velocity of `c` is finite.
fn finite_command(c: &CommandMsg) -> bool {
    let cmd = c.command::<JOINTS>();
    let p = &cmd.platform;
    [p.v, p.v_lat, p.omega, p.v_xi].iter().chain(cmd.joints.iter()).all(|x| x.is_finite())
}

/// How long the plant waits, after its last measurement, for the answer to it (so that the
/// controller sees the end of the run before the plant's ports go away) (ns).
const GOODBYE_NS: u64 = 1_000_000_000;

fn lost(loss: PeerLoss, cycle: u64) -> PlantEnd {
    match loss {
        PeerLoss::Died { pid, silent_ns } => PlantEnd::ControllerDied { pid, cycle, silent_ns },
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
pub fn run_real_time<C: Clock, L: PlantLink>(
    side: &mut PlantSide<'_, C, L>,
    plant: &mut Plant<Rpr<f64>, JOINTS>,
    steps: u64,
    sink: &mut impl FnMut(u64, &Row, bool) -> bool,
) -> Result<PlantEnd> {
    let timing = side.timing;
    let period = timing.period_ns;
    let mut idler = Idler::new(timing.wait, timing.spin_margin_ns);
    let mut policy = HoldPolicy::new(timing.hold_periods);
    let mut start = side.clock.now_ns();
    let mut watch = PeerWatch::new(timing.silence_ns, start);
    let mut last_step = steps;
    let mut end = PlantEnd::Completed;
    let mut answered_last;
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
        let t_pub = side.publish(n, fl, &meas)?;
        let deadline = if n == 0 {
            t_pub + timing.peer_timeout_ns
        } else {
            side.stats.jitter.record(t_pub - release);
            release + timing.deadline_ns
        };
        if t_pub > deadline {
            side.stats.plant_overruns += 1;
        }
        // Wait for command n (not once the controller is known to be gone).
        let mut fresh = None;
        idler.reset();
        let peer_lost = matches!(end, PlantEnd::ControllerDied { .. } | PlantEnd::ControllerGone { .. });
        if !peer_lost {
            loop {
                fresh = side.drain(n, true)?;
                if fresh.is_some() || side.clock.now_ns() >= deadline {
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
        let (report, source) = match fresh {
            Some(c) => {
                stats.fresh += 1;
                let now = side.clock.now_ns();
                if n > 0 {
                    let gap = now - watch.last_heard_ns();
                    stats.longest_command_gap_ns = stats.longest_command_gap_ns.max(gap);
                    if gap > (u64::from(timing.hold_periods) + 1) * period {
                        stats.command_gaps_over_hold += 1;
                    }
                }
                watch.heard(now);
                policy.fresh(report_of(&c))
            }
            None => {
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
        let row = Row { plant: sim::sample(plant, &side.target_in_effector), report, source };
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
        plant.advance(&report.command, side.stamp.dt);
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
}

impl<C: Clock, L: PlantLink> Exchange for Lockstep<'_, C, L> {
    fn exchange(&mut self, n: u64, meas: &Measurement<f64, JOINTS>) -> Result<StepReport> {
        let mut fl = flags::LOCKSTEP;
        if n == self.steps {
            fl |= flags::END_OF_RUN;
        }
        let side = &mut self.side;
        let t_pub = side.publish(n, fl, meas)?;
        side.stats.cycles += 1;
        side.live.cycle.store(n + 1, Ordering::Relaxed);
        let mut idler = Idler::new(side.timing.wait, side.timing.spin_margin_ns);
        let mut watch = PeerWatch::new(side.timing.silence_ns, t_pub);
        loop {
            if let Some(c) = side.drain(n, false)? {
                side.stats.fresh += 1;
                return Ok(report_of(&c));
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
