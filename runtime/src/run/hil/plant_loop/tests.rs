//! The real-time cycle's phases, each on a fake clock and a scripted controller.

use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

use super::*;
use crate::domain::controller::JOINTS;
use crate::run::hil::messages::answer;
use crate::run::hil::misses::MissCauses;
use crate::sys::clock::FakeClock;
use crate::transport::link::{Link, LinkError, PeerState};
use crate::transport::wire::target::space;
use crate::transport::wire::{platform, CommandHeader, ControllerIdentity};

const MS: u64 = 1_000_000;
const SESSION: u64 = 77;

/// A controller that answers each measurement after the delay its script gives (`None`: not
/// at all), on a fake clock.
struct Scripted {
    clock: Rc<FakeClock>,
    script: VecDeque<Option<u64>>,
    inbox: Vec<(u64, CommandMsg)>,
    sent: Vec<MeasurementMsg>,
    peer: PeerState,
    /// How each answer is stamped: its step took `compute` and it was sent `back` before it
    /// arrives (ns); `None`: not stamped (`received_ns` 0).
    stamps: Option<(u64, u64)>,
}

impl Scripted {
    fn new(clock: &Rc<FakeClock>, script: &[Option<u64>]) -> Self {
        Self {
            clock: clock.clone(),
            script: script.iter().copied().collect(),
            inbox: Vec::new(),
            sent: Vec::new(),
            peer: PeerState::Alive(1),
            stamps: None,
        }
    }

    /// Queues an answer to `m` arriving at `at`.
    fn answer_at(&mut self, at: u64, m: &MeasurementMsg) {
        let identity = ControllerIdentity {
            platform: platform::UNICYCLE,
            joint_count: 3,
            space: space::PLANAR,
            arm_hash: 0,
            scenario_hash: 0,
            max_dt: 0.1,
        };
        let (compute, back) = self.stamps.unwrap_or((0, at));
        let received_ns = at - back - compute;
        let header = CommandHeader { identity, flags: flags::NOTIFIES, received_ns, skipped: 0, delay: 0.0 };
        let mut report = StepReport::<JOINTS>::zero(None);
        report.command.platform.v = 1.0 + m.seq as f64;
        let mut c = answer(m, &header, &report);
        c.compute_ns = compute;
        self.inbox.push((at, c));
        self.inbox.sort_by_key(|(t, _)| *t);
    }
}

impl Link for Scripted {
    type Tx = MeasurementMsg;
    type Rx = CommandMsg;
    fn publish(&mut self, m: &MeasurementMsg) -> Result<(), LinkError> {
        self.sent.push(*m);
        if let Some(Some(after)) = self.script.pop_front() {
            self.answer_at(self.clock.now_ns() + after, m);
        }
        Ok(())
    }
    fn try_receive(&mut self) -> Result<Option<CommandMsg>, LinkError> {
        match self.inbox.first() {
            Some((at, _)) if *at <= self.clock.now_ns() => Ok(Some(self.inbox.remove(0).1)),
            _ => Ok(None),
        }
    }
    fn wait_event(&mut self, d: Duration) -> Result<(), LinkError> {
        self.clock.advance(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        Ok(())
    }
    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        Ok(self.peer)
    }
}

/// 1 kHz, a 500 µs deadline, 2 periods of hold, spinning (the fake clock moves 1 µs a spin).
fn timing() -> Timing {
    Timing {
        period_ns: MS,
        deadline_ns: MS / 2,
        hold_periods: 2,
        wait: WaitMode::Spin,
        release: crate::run::hil::config::ReleaseTimer::Sleep,
        spin_margin_ns: 100_000,
        silence_ns: 20 * MS,
        peer_timeout_ns: 2_000 * MS,
        lockstep: false,
        max_command_age: 0,
    }
}

fn stamp() -> Stamp {
    Stamp {
        session: SESSION,
        scenario_hash: 0,
        arm_hash: 0,
        period_ns: MS,
        dt: 1e-3,
        flags: 0,
        platform: platform::UNICYCLE,
        hold_periods: 2,
    }
}

/// Runs `f` with a plant side on `link` and a fresh cycle of 10 steps started at the clock's
/// now.
fn with_side<T>(
    clock: &Rc<FakeClock>,
    link: &mut Scripted,
    stats: &mut PlantStats,
    f: impl FnOnce(&mut PlantSide<'_, FakeClock, Scripted>, &mut Cycle<JOINTS>) -> T,
) -> T {
    let live = LiveFigures::default();
    let mut side = PlantSide {
        clock: &**clock,
        link,
        timing: timing(),
        stamp: stamp(),
        stats,
        live: &live,
        last_sent: None,
    };
    let mut cy = Cycle::new(&side.timing, 10, clock.now_ns());
    f(&mut side, &mut cy)
}

#[test]
fn release_publishes_at_the_release_and_awaits_until_the_deadline() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[]);
    let mut stats = PlantStats::default();
    let (r0, r1) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let r0 = side.release(cy, 0, &zero_measurement()).unwrap();
        let r1 = side.release(cy, 1, &zero_measurement()).unwrap();
        (r0, r1)
    });
    // The handshake at once, awaited up to the peer timeout; period 1 at its release.
    assert_eq!(r0, Released { release: 0, t_pub: 0, t_sent: 0, deadline: 2_000 * MS });
    assert!((MS..MS + 2_000).contains(&r1.t_pub), "{r1:?}");
    assert_eq!(r1.deadline, MS + MS / 2);
    assert_eq!(link.sent.iter().map(|m| m.seq).collect::<Vec<_>>(), [0, 1]);
    assert_eq!((stats.plant_stalls, stats.skipped_releases, stats.plant_overruns), (0, 0, 0));
}

#[test]
fn a_stall_skips_the_missed_releases_once_and_the_last_step_says_so() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[]);
    let mut stats = PlantStats::default();
    let (r, start) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        clock.advance(5 * MS + 300_000);
        cy.last_step = 1;
        let r = side.release(cy, 1, &zero_measurement()).unwrap();
        (r, cy.start)
    });
    // 4.3 ms behind release 1: four releases skipped, the schedule moved on by 4 periods.
    assert_eq!((stats.plant_stalls, stats.skipped_releases), (1, 4));
    assert_eq!(stats.longest_stall_ns, 4 * MS + 300_000);
    assert_eq!(start, 4 * MS);
    // The last step of a run going to its end: flagged, its answer awaited up to the peer
    // timeout (the controller's confirmation), not the deadline.
    assert!(link.sent[0].has(flags::END_OF_RUN));
    assert_eq!(r.deadline, r.t_pub + 2_000 * MS);
}

#[test]
fn await_takes_the_answer_that_comes_before_the_deadline() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[Some(0), Some(200_000)]);
    let mut stats = PlantStats::default();
    let (heard, now) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let r = side.release(cy, 0, &zero_measurement()).unwrap();
        side.await_command(cy, 0, r.deadline).unwrap();
        let r = side.release(cy, 1, &zero_measurement()).unwrap();
        let heard = side.await_command(cy, 1, r.deadline).unwrap();
        (heard, clock.now_ns())
    });
    let (c, t_rx) = heard.fresh.expect("answered");
    assert_eq!(c.seq, 1);
    assert!(heard.refused.is_none());
    // Taken when it came (the spin's 1 µs step), and the wait ended there, not at the deadline.
    let t_pub = link.sent[1].plant_time_ns;
    assert!((t_pub + 200_000..t_pub + 202_000).contains(&t_rx), "{t_rx} vs {t_pub}");
    assert!(now < t_pub + 300_000, "{now}");
}

#[test]
fn await_gives_up_at_the_deadline_and_the_late_answer_counts_late_in_the_next_period() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    // Period 1's answer comes 700 µs after it: after its deadline, before period 2's.
    let mut link = Scripted::new(&clock, &[Some(0), Some(700_000), Some(100_000)]);
    let mut stats = PlantStats::default();
    let (h1, h2, deadline1, after1) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let r = side.release(cy, 0, &zero_measurement()).unwrap();
        side.await_command(cy, 0, r.deadline).unwrap();
        let r1 = side.release(cy, 1, &zero_measurement()).unwrap();
        let h1 = side.await_command(cy, 1, r1.deadline).unwrap();
        let after1 = clock.now_ns();
        let r2 = side.release(cy, 2, &zero_measurement()).unwrap();
        let h2 = side.await_command(cy, 2, r2.deadline).unwrap();
        (h1, h2, r1.deadline, after1)
    });
    assert!(h1.fresh.is_none() && h1.refused.is_none());
    assert!(after1 >= deadline1, "{after1} < {deadline1}");
    assert_eq!(h2.fresh.map(|(c, _)| c.seq), Some(2));
    assert_eq!(stats.late_commands, 1);
}

/// The causes four late answers and a missing one get, through the phases: stamped by the
/// scripted controller as a long step, a late wake-up, a late way back; unstamped; none.
#[test]
fn each_miss_is_put_down_to_the_part_of_the_round_trip_that_took_its_time() {
    type Count = fn(&MissCauses) -> u64;
    let cases: [(Option<(u64, u64)>, Count); 4] = [
        // 700 µs after publication: a 600 µs step, received 100 µs in.
        (Some((600_000, 0)), |c| c.controller_compute),
        // A 50 µs step, received 650 µs in.
        (Some((50_000, 0)), |c| c.controller_wake),
        // Sent 150 µs in, 550 µs on the way back.
        (Some((50_000, 550_000)), |c| c.return_path),
        (None, |c| c.clocks_apart),
    ];
    for (stamps, count) in cases {
        let clock = Rc::new(FakeClock::new(0, 1_000));
        // Period 1's answer comes 700 µs after it (its deadline is at 500 µs); 2 is answered
        // in time; 3 never.
        let mut link = Scripted::new(&clock, &[Some(0), Some(700_000), Some(100_000), None]);
        link.stamps = stamps;
        let mut stats = PlantStats::default();
        with_side(&clock, &mut link, &mut stats, |side, cy| {
            for n in 0..5 {
                let r = side.release(cy, n, &zero_measurement()).unwrap();
                let h = side.await_command(cy, n, r.deadline).unwrap();
                side.apply(cy, n, r, h, n as f64 * 1e-3);
            }
            cy.misses.finish(&mut side.stats.miss_causes);
        });
        let c = stats.miss_causes;
        assert_eq!((stats.deadline_misses, c.total()), (3, 3), "{stamps:?}: {c:?}");
        // 1 late with its cause; 3 and 4 unanswered.
        assert_eq!((count(&c), c.unanswered), (1, 2), "{stamps:?}: {c:?}");
    }
}

#[test]
fn apply_switches_at_the_arrival_and_announces_that_delay_next() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[Some(0), Some(250_000)]);
    let mut stats = PlantStats::default();
    let (a, delay, applied, flagged) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let r = side.release(cy, 0, &zero_measurement()).unwrap();
        let h = side.await_command(cy, 0, r.deadline).unwrap();
        side.apply(cy, 0, r, h, 0.0);
        let r = side.release(cy, 1, &zero_measurement()).unwrap();
        let h = side.await_command(cy, 1, r.deadline).unwrap();
        let a = side.apply(cy, 1, r, h, 1e-3);
        side.release(cy, 2, &zero_measurement()).unwrap();
        (a, cy.delay, cy.applied, side.last_sent.map(|m| m.delay))
    });
    assert_eq!(a.source, CommandSource::Fresh);
    assert_eq!(a.report.command.platform.v, 2.0, "the answer to measurement 1");
    // 250 µs of a 1 ms period of 1 ms: the command acts from 2.5e-4 s (the spin's 1 µs step).
    assert!((a.switch_at - 2.5e-4).abs() <= 2e-6, "{}", a.switch_at);
    assert_eq!(delay, a.switch_at);
    assert_eq!(flagged, Some(delay), "measurement 2 announces it");
    assert_eq!(applied, Some(1));
    assert_eq!(stats.fresh, 2);
}

#[test]
fn misses_hold_the_last_command_for_the_hold_then_stop_the_robot() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[Some(0), None, None, None, None]);
    let mut stats = PlantStats::default();
    let sources = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let mut sources = Vec::new();
        for n in 0..5 {
            let r = side.release(cy, n, &zero_measurement()).unwrap();
            let h = side.await_command(cy, n, r.deadline).unwrap();
            let a = side.apply(cy, n, r, h, n as f64 * 1e-3);
            side.account(cy, n, a.source, true);
            sources.push((a.source, a.report.command.platform.v));
        }
        sources
    });
    use CommandSource::{Fresh, Held, Stopped};
    assert_eq!(sources, [(Fresh, 1.0), (Held, 1.0), (Held, 1.0), (Stopped, 0.0), (Stopped, 0.0)]);
    assert_eq!((stats.deadline_misses, stats.held_periods, stats.stopped_periods), (4, 2, 2));
    assert_eq!((stats.stop_events, stats.max_consecutive_misses), (1, 4));
    assert_eq!(stats.first_stop_t, Some(3e-3));
    assert_eq!(stats.cycles, 5);
    // The measurement after the stop says so.
    assert!(!link.sent[3].has(flags::STOPPED) && link.sent[4].has(flags::STOPPED));
}

#[test]
fn a_refusal_stops_the_robot_and_ends_the_run_at_its_step() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[]);
    let mut stats = PlantStats::default();
    let why = Refusal::JointCount { plant: 3, controller: 6 };
    let (a, end, last) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        let a = side.apply(
            cy,
            4,
            Released { release: 0, t_pub: 0, t_sent: 0, deadline: 0 },
            Heard { fresh: None, refused: Some(why) },
            4e-3,
        );
        (a, cy.end, cy.last_step)
    });
    assert_eq!(a.source, CommandSource::Stopped);
    assert_eq!(a.report.command, Command::zero());
    assert_eq!((end, last), (PlantEnd::Refused(why), 4));
}

#[test]
fn account_counts_the_period_and_publishes_the_live_figures() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[]);
    let mut stats = PlantStats { deadline_misses: 3, ..PlantStats::default() };
    let live = LiveFigures::default();
    let mut side = PlantSide {
        clock: &*clock,
        link: &mut link,
        timing: timing(),
        stamp: stamp(),
        stats: &mut stats,
        live: &live,
        last_sent: None,
    };
    let cy = Cycle::<JOINTS>::new(&side.timing, 10, 0);
    side.account(&cy, 6, CommandSource::Held, false);
    assert_eq!((stats.held_periods, stats.log_rows_dropped, stats.cycles), (1, 1, 1));
    assert_eq!(live.cycle.load(Ordering::Relaxed), 7);
    assert_eq!(live.misses.load(Ordering::Relaxed), 3);
}

#[test]
fn look_out_ends_the_run_after_the_next_step_when_the_controller_is_gone() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut link = Scripted::new(&clock, &[]);
    link.peer = PeerState::Absent;
    let mut stats = PlantStats::default();
    let (quiet, gone) = with_side(&clock, &mut link, &mut stats, |side, cy| {
        // Silent for less than the silence interval: not even looked at.
        clock.advance(10 * MS);
        side.look_out(cy, 5, false).unwrap();
        let quiet = (cy.end, cy.last_step);
        clock.advance(15 * MS);
        side.look_out(cy, 6, false).unwrap();
        (quiet, (cy.end, cy.last_step))
    });
    assert_eq!(quiet, (PlantEnd::Completed, 10));
    assert_eq!(gone, (PlantEnd::ControllerGone { cycle: 6 }, 7));
}

/// Runs periods `1..=periods` through release, await and look-out (the cycle long enough);
/// `stall`: a period after which this process is not scheduled for 600 ms.
fn run_periods(
    link: &mut Scripted,
    clock: &Rc<FakeClock>,
    periods: u64,
    stall: Option<u64>,
) -> (PlantEnd, u64) {
    let mut stats = PlantStats::default();
    let end = with_side(clock, link, &mut stats, |side, cy| {
        cy.last_step = periods + 10;
        let r = side.release(cy, 0, &zero_measurement()).unwrap();
        side.await_command(cy, 0, r.deadline).unwrap();
        for n in 1..=periods {
            if stall == Some(n) {
                clock.advance(600 * MS);
            }
            let r = side.release(cy, n, &zero_measurement()).unwrap();
            let heard = side.await_command(cy, n, r.deadline).unwrap();
            side.look_out(cy, n, heard.fresh.is_some()).unwrap();
            if cy.end != PlantEnd::Completed {
                break;
            }
        }
        cy.end
    });
    (end, stats.late_commands)
}

/// A controller that answers every measurement, but after its deadline (1.2 ms: each answer
/// lands in the next period, too old to apply), is alive: its late answers are news to the
/// peer watch, and 2.5 s of them (past the 2 s peer timeout) do not end the run. One that
/// answers nothing for as long is found hung at the timeout.
#[test]
fn a_controller_that_answers_late_is_alive_and_a_silent_one_is_hung() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let script: Vec<Option<u64>> =
        std::iter::once(Some(0)).chain(std::iter::repeat_n(Some(1_200_000), 2_600)).collect();
    let mut late = Scripted::new(&clock, &script);
    let (end, late_commands) = run_periods(&mut late, &clock, 2_500, None);
    assert_eq!(end, PlantEnd::Completed);
    assert!(late_commands >= 2_400, "{late_commands}");

    let clock = Rc::new(FakeClock::new(0, 1_000));
    let mut silent = Scripted::new(&clock, &[Some(0)]);
    let (end, _) = run_periods(&mut silent, &clock, 2_500, None);
    assert!(matches!(end, PlantEnd::ControllerHung { .. }), "{end:?}");
}

/// The plant's own stall (600 ms not scheduled) is not the controller's silence: a
/// controller silent for 1.6 s around it, 2.2 s of wall time, is not hung (the 2 s timeout
/// counts 1.6 s); without the stall the same silence of 2.2 s would be.
#[test]
fn the_plants_own_stall_is_not_the_controllers_silence() {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    // Answers in time, then nothing for periods 1..=1600, then in time again.
    let script: Vec<Option<u64>> = std::iter::once(Some(0))
        .chain(std::iter::repeat_n(None, 1_600))
        .chain(std::iter::repeat_n(Some(100_000), 500))
        .collect();
    let mut link = Scripted::new(&clock, &script);
    let (end, _) = run_periods(&mut link, &clock, 2_000, Some(800));
    assert_eq!(end, PlantEnd::Completed);

    let clock = Rc::new(FakeClock::new(0, 1_000));
    let script: Vec<Option<u64>> = std::iter::once(Some(0))
        .chain(std::iter::repeat_n(None, 2_200))
        .chain(std::iter::repeat_n(Some(100_000), 100))
        .collect();
    let mut link = Scripted::new(&clock, &script);
    let (end, _) = run_periods(&mut link, &clock, 2_250, None);
    assert!(matches!(end, PlantEnd::ControllerHung { .. }), "{end:?}");
}
