use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

use companion_core::{PaperRun, PlatformKind};
use companion_plant::PaperTrajectory;

use super::*;
use crate::domain::observe::Silent;
use crate::domain::scenario::Scenario;
use crate::run::hil::fault::{Corruption, Injecting};
use crate::run::hil::handshake::controller_hash;
use crate::run::hil::messages::Stamp;
use crate::sys::clock::FakeClock;
use crate::transport::link::{Link, LinkError, PeerState};
use crate::transport::wire::{platform, refusal, CommandMsg};

/// A plant whose measurements arrive at given times on a fake clock.
struct Fake {
    inbox: VecDeque<(u64, MeasurementMsg)>,
    sent: Vec<CommandMsg>,
    clock: Rc<FakeClock>,
    peer: PeerState,
    checks: u32,
    /// `(at, ns)`: the first receive at or after `at` is held up for `ns` (the process was
    /// preempted in it).
    stall: Option<(u64, u64)>,
}

impl Link for Fake {
    type Tx = CommandMsg;
    type Rx = MeasurementMsg;
    fn publish(&mut self, c: &CommandMsg) -> Result<(), LinkError> {
        self.sent.push(*c);
        Ok(())
    }
    fn try_receive(&mut self) -> Result<Option<MeasurementMsg>, LinkError> {
        if let Some((at, ns)) = self.stall {
            if self.clock.now_ns() >= at {
                self.clock.advance(ns);
                self.stall = None;
            }
        }
        match self.inbox.front() {
            Some((at, _)) if *at <= self.clock.now_ns() => Ok(self.inbox.pop_front().map(|x| x.1)),
            _ => Ok(None),
        }
    }
    fn wait_event(&mut self, d: Duration) -> Result<(), LinkError> {
        self.clock.advance(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        Ok(())
    }
    fn peer_state(&mut self) -> Result<PeerState, LinkError> {
        self.checks += 1;
        Ok(self.peer)
    }
}

fn scenario() -> Scenario {
    Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
        .duration(30.0)
        .build()
        .unwrap()
}

fn options() -> ServeOptions {
    ServeOptions {
        wait: WaitMode::Spin,
        spin_margin_ns: 100_000,
        silence_ns: 20_000_000,
        peer_timeout_ns: 2_000_000_000,
        startup_timeout_ns: 20_000_000_000,
        forward_interrupt: false,
        delay_compensation: true,
        deadline_ns: 500_000,
    }
}

fn fake(peer: PeerState) -> (Rc<FakeClock>, Fake) {
    let clock = Rc::new(FakeClock::new(0, 1_000));
    let link =
        Fake { inbox: VecDeque::new(), sent: Vec::new(), clock: clock.clone(), peer, checks: 0, stall: None };
    (clock, link)
}

/// A plant's stamp: real time at 1 kHz holding 20 periods, or lockstep.
fn stamp(s: &Scenario, lockstep: bool) -> Stamp {
    Stamp {
        session: 77,
        scenario_hash: controller_hash(&s.controller),
        arm_hash: crate::run::hil::handshake::arm_hash(),
        period_ns: if lockstep { 0 } else { 1_000_000 },
        dt: s.dt,
        flags: if lockstep { flags::LOCKSTEP } else { 0 },
        platform: platform::UNICYCLE,
        hold_periods: 20,
    }
}

fn meas_msg(s: &Scenario, seq: u64, fl: u32) -> MeasurementMsg {
    let plant = crate::run::sim::build_plant(s).unwrap();
    stamp(s, false).message(seq, fl, seq * 1_000_000, 0.0, &plant.measure())
}

fn run(
    link: &mut Fake,
    clock: &FakeClock,
    s: &Scenario,
    opt: &ServeOptions,
) -> (Result<ControlEnd, ServeError>, ControlStats) {
    let mut st = ControlStats::default();
    let r = serve(clock, link, &s.controller, opt, &mut st, &Silent);
    (r, st)
}

#[test]
fn answers_the_newest_measurement_and_echoes_its_ids() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    // Two measurements waiting at once: only the newer one is answered.
    link.inbox.push_back((5_000_000, meas_msg(&s, 1, 0)));
    link.inbox.push_back((5_000_000, meas_msg(&s, 2, flags::END_OF_RUN)));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(link.sent.len(), 2);
    assert_eq!((link.sent[0].seq, link.sent[1].seq), (0, 2));
    assert_eq!(link.sent[1].skipped, 1);
    assert_eq!(link.sent[1].session, 77);
    assert_eq!(link.sent[1].plant_time_ns, 2_000_000);
    assert_eq!((link.sent[1].platform, link.sent[1].scenario_hash), (1, controller_hash(&s.controller)));
    assert_eq!((st.answered, st.skipped), (2, 1));
}

#[test]
fn an_injection_at_a_skipped_measurement_goes_out_with_the_next_answer() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    link.inbox.push_back((5_000_000, meas_msg(&s, 1, 0)));
    link.inbox.push_back((5_000_000, meas_msg(&s, 2, 0)));
    link.inbox.push_back((6_000_000, meas_msg(&s, 3, flags::END_OF_RUN)));
    let mut link = Injecting::new(link, vec![(1, Corruption::Session), (0, Corruption::Nan)]);
    let mut st = ControlStats::default();
    serve(clock.as_ref(), &mut link, &s.controller, &options(), &mut st, &Silent).unwrap();
    // Answers 0, 2, 3; NaN before answer 0; seq 1 was skipped, so its corruption goes
    // before answer 2; each exactly once.
    let sent = link.into_inner().sent;
    let seen: Vec<_> = sent.iter().map(|c| (c.seq, c.session == 77, c.v.is_nan())).collect();
    assert_eq!(
        seen,
        vec![(0, true, true), (0, true, false), (2, false, false), (2, true, false), (3, true, false)]
    );
}

#[test]
fn a_dead_plant_is_noticed_after_the_silence_threshold() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Dead(4242));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    let (end, _) = run(&mut link, clock.as_ref(), &s, &options());
    match end.unwrap() {
        ControlEnd::PlantDied { pid, last_seq, silent_ns, expired } => {
            assert_eq!((pid, last_seq, expired), (4242, Some(0), false));
            assert!((20_000_000..21_000_000).contains(&silent_ns), "{silent_ns}");
        }
        e => panic!("{e:?}"),
    }
    assert_eq!(link.checks, 1);
}

#[test]
fn a_plant_the_controller_cannot_serve_is_refused_on_the_wire_and_in_the_error() {
    let s = scenario();
    type Spoil = fn(&mut MeasurementMsg);
    let cases: [(Spoil, u32, &str); 7] = [
        (|m| m.scenario_hash ^= 1, refusal::SCENARIO, "scenario mismatch"),
        (|m| m.platform = platform::CAR, refusal::PLATFORM, "the plant is car-like"),
        (|m| m.joint_count = 4, refusal::JOINT_COUNT, "the plant has 4 joints"),
        (|m| m.version = 3, refusal::VERSION, "the plant speaks version 3, the controller version 4"),
        (|m| m.space = 2, refusal::SPACE, "the plant's target is spatial (SE(3))"),
        (|m| m.arm_hash ^= 1, refusal::ARM, "arm mismatch: the plant's arm is 0x"),
        (|m| m.dt = 1.0, refusal::PERIOD, "dt = 1 s"),
    ];
    for (spoil, code, text) in cases {
        let (clock, mut link) = fake(PeerState::Alive(1));
        let mut m = meas_msg(&s, 0, 0);
        spoil(&mut m);
        link.inbox.push_back((0, m));
        let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
        let e = end.unwrap_err();
        let ServeError::Refused(Refused(why)) = &e else { panic!("{e}") };
        let why = *why;
        assert!(e.to_string().contains(text), "{e}");
        // The plant gets the refusal, answering its measurement, and reads the same reason.
        assert_eq!(link.sent.len(), 1);
        let c = link.sent[0];
        assert_eq!((c.status, c.seq, c.session), (code, 0, 77));
        assert_eq!(c.command::<3>(), companion_core::Command::zero());
        assert_eq!(crate::transport::wire::Refusal::from_command(&c, &m), Some(why));
        assert_eq!(st.answered, 0);
    }
}

#[test]
fn the_joint_guard_comes_from_the_plants_announcement_not_the_controllers_flags() {
    // The same measurement, announced by a lockstep plant and by a real-time plant that holds
    // 20 periods: the lockstep answer is the simulation's (κ₀ = 0.5), the real-time one
    // limits the joints (κ = 1/22).
    let s = scenario();
    let plant = crate::run::sim::build_plant(&s).unwrap();
    let first = |lockstep: bool| {
        let (clock, mut link) = fake(PeerState::Alive(1));
        let m = stamp(&s, lockstep).message(0, flags::END_OF_RUN, 0, 0.0, &plant.measure());
        link.inbox.push_back((0, m));
        run(&mut link, clock.as_ref(), &s, &options()).0.unwrap();
        link.sent[0].command::<3>()
    };
    let mut sim = crate::run::sim::InProcess::new(&s).unwrap();
    let expected = sim.controller.step(&plant.measure(), s.dt, 0.0).command;
    assert_eq!(first(true), expected);
    let rt = first(false);
    assert!(rt.joints.amax() < expected.joints.amax(), "{rt:?} vs {expected:?}");
}

#[test]
fn the_announced_delay_is_predicted_over_clamped_to_what_the_law_admits() {
    let s = scenario();
    let plant = crate::run::sim::build_plant(&s).unwrap();
    let answer = |delay: f64, compensate: bool| {
        let (clock, mut link) = fake(PeerState::Alive(1));
        let m = stamp(&s, true).message(0, flags::END_OF_RUN, 0, delay, &plant.measure());
        link.inbox.push_back((0, m));
        let opt = ServeOptions { delay_compensation: compensate, ..options() };
        let (end, st) = run(&mut link, clock.as_ref(), &s, &opt);
        end.unwrap();
        (link.sent[0], st)
    };
    let reference = |delay: f64| {
        let mut c = crate::run::sim::InProcess::new(&s).unwrap().controller;
        c.step(&plant.measure(), s.dt, delay).command
    };
    let (c, st) = answer(2.5e-4, true);
    assert_eq!((c.delay, c.command::<3>(), st.delay_clamped), (2.5e-4, reference(2.5e-4), 0));
    assert_ne!(reference(2.5e-4), reference(0.0));
    // Beyond HISTORY periods (8 ms at 1 ms): clamped, counted, still a command.
    let (c, st) = answer(1.0, true);
    assert_eq!((c.delay, c.status, st.delay_clamped), (8e-3, 0, 1));
    let (c, _) = answer(-1.0, true);
    assert_eq!(c.delay, 0.0);
    // Not finite: the law's business (the safe command, status 0x700).
    let (c, _) = answer(f64::NAN, true);
    assert_eq!((c.status, c.command::<3>()), (0x700, companion_core::Command::zero()));
    // Without compensation the law is told 0.
    let (c, _) = answer(2.5e-4, false);
    assert_eq!((c.delay, c.command::<3>()), (0.0, reference(0.0)));
}

#[test]
fn a_stop_reported_by_the_plant_is_counted_and_fails_the_run() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Alive(1));
    for (i, fl) in
        [0, 0, flags::STOPPED, flags::STOPPED, 0, flags::STOPPED | flags::END_OF_RUN].iter().enumerate()
    {
        let i = i as u64;
        link.inbox.push_back((i * 1_000_000, meas_msg(&s, i, *fl)));
    }
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!((st.stop_events, st.first_stop_seq), (2, Some(2)));
    let f = st.failure().unwrap();
    assert!(f.contains("stopped the robot 2 time(s), first at cycle 2"), "{f}");
    assert_eq!(ControlStats::default().failure(), None);
}

#[test]
fn event_waiting_falls_back_to_polling_when_the_plant_does_not_notify() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    link.inbox.push_back((1_000_000, meas_msg(&s, 1, flags::END_OF_RUN)));
    let opt = ServeOptions { wait: WaitMode::Event, ..options() };
    let (end, st) = run(&mut link, clock.as_ref(), &s, &opt);
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert!(st.event_fallback);
    // A notifying plant keeps the event.
    let (clock, mut link) = fake(PeerState::Alive(1));
    let mut n = stamp(&s, false);
    n.flags |= flags::NOTIFIES;
    let plant = crate::run::sim::build_plant(&s).unwrap();
    link.inbox.push_back((0, n.message(0, flags::END_OF_RUN, 0, 0.0, &plant.measure())));
    let (_, st) = run(&mut link, clock.as_ref(), &s, &opt);
    assert!(!st.event_fallback);
}

#[test]
fn measurements_whose_announcement_changes_are_dropped() {
    let s = scenario();
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    let mut changed = meas_msg(&s, 1, 0);
    changed.hold_periods = 5;
    link.inbox.push_back((1_000_000, changed));
    link.inbox.push_back((2_000_000, meas_msg(&s, 2, flags::END_OF_RUN)));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!((st.answered, st.invalid), (2, 1));
}

/// The wake log names what the controller was doing when a measurement it took late had
/// arrived, and counts the periods the plant misses through it.
#[test]
fn the_wake_log_says_why_a_measurement_was_taken_late() {
    use crate::run::hil::wakes::WakeCount;
    let s = scenario();
    let plant = crate::run::sim::build_plant(&s).unwrap();
    let notifying = |seq: u64, fl: u32| {
        let mut st = stamp(&s, false);
        st.flags |= flags::NOTIFIES;
        st.message(seq, fl, seq * 1_000_000, 0.0, &plant.measure())
    };
    // Spinning, preempted for 1.5 ms in a receive at 1.9 ms: measurements 2 and 3 wait, 3 is
    // answered at 3.4 ms (in time for its deadline at 3.5 ms), 2 is missed.
    let (clock, mut link) = fake(PeerState::Alive(1));
    for seq in 0..4 {
        link.inbox.push_back((seq * 1_000_000, notifying(seq, if seq == 3 { flags::END_OF_RUN } else { 0 })));
    }
    link.stall = Some((1_900_000, 1_500_000));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    let late = st.wakes.late;
    assert_eq!(late.preempted, WakeCount { wakes: 1, missed: 1 });
    assert_eq!((late.wakes(), late.missed()), (1, 1));
    assert_eq!(st.wakes.wake.count(), 2, "measurements 1 and 2-3; the handshake is not timed");
    // The same, but the transport's queue kept only the newest (4): 2 and 3 were overwritten.
    // The wake is dated from 2's publication (4's less two periods), and both are missed.
    let (clock, mut link) = fake(PeerState::Alive(1));
    for seq in [0, 1, 4] {
        link.inbox.push_back((seq * 1_000_000, notifying(seq, if seq == 4 { flags::END_OF_RUN } else { 0 })));
    }
    link.stall = Some((1_900_000, 2_200_000));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(st.wakes.late.preempted, WakeCount { wakes: 1, missed: 2 });
    assert!(st.wakes.wake.quantile(1.0) >= 2_090_000, "{}", st.wakes.wake.quantile(1.0));
    // Waiting on the event, which (on this fake link) returns only after 10 ms: measurement 1
    // is taken 9 ms late, asleep on the event, and missed.
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, notifying(0, 0)));
    link.inbox.push_back((1_000_000, notifying(1, flags::END_OF_RUN)));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &ServeOptions { wait: WaitMode::Event, ..options() });
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(st.wakes.late.asleep_on_event, WakeCount { wakes: 1, missed: 1 });
    assert_eq!(st.wakes.late.wakes(), 1);
    // Spinning all along, but measurement 1, stamped at 1 ms, is there only at 1.4 ms: the
    // plant sent it late (in time for the deadline at 1.5 ms).
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, notifying(0, 0)));
    link.inbox.push_back((1_400_000, notifying(1, flags::END_OF_RUN)));
    let (end, st) = run(&mut link, clock.as_ref(), &s, &options());
    assert_eq!(end.unwrap(), ControlEnd::EndOfRun);
    assert_eq!(st.wakes.late.published_late, WakeCount { wakes: 1, missed: 0 });
    assert_eq!(st.wakes.late.wakes(), 1);
    // Lockstep has no deadline: nothing is judged.
    let (clock, mut link) = fake(PeerState::Alive(1));
    link.inbox.push_back((0, meas_msg(&s, 0, 0)));
    link.inbox.push_back((9_000_000, meas_msg(&s, 1, flags::END_OF_RUN)));
    let (_, st) = run(&mut link, clock.as_ref(), &s, &ServeOptions { deadline_ns: 0, ..options() });
    assert_eq!((st.wakes.wake.count(), st.wakes.late.wakes()), (0, 0));
}
