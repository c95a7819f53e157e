//! The controller's loop: answer each measurement with one command until the end of the run
//! or until the plant is lost.

use anyhow::{bail, Result};

use super::config::WaitMode;
use super::end::ControlEnd;
use super::messages::answer;
use super::stats::ControlStats;
use super::wait::Idler;
use super::watch::{PeerLoss, PeerWatch};
use crate::clock::Clock;
use crate::controller::{AnyController, JOINTS};
use crate::link::{ControlLink, PeerState};
use crate::signals::termination_requested;
use crate::wire::{check_measurement, flags, MeasurementMsg, WireError};

/// Options of [`serve`].
#[derive(Clone, Copy, Debug)]
pub struct ServeOptions {
    /// Waiting.
    pub wait: WaitMode,
    /// Hybrid spin margin (ns).
    pub spin_margin_ns: u64,
    /// Silence before a liveness check (ns).
    pub silence_ns: u64,
    /// Alive-but-silent limit (ns).
    pub peer_timeout_ns: u64,
    /// Alive-but-silent limit before the first measurement (ns).
    pub startup_timeout_ns: u64,
    /// The scenario hash (0: not checked).
    pub scenario_hash: u64,
    /// On SIGINT/SIGTERM, hand the interruption on to the plant process (`SIGTERM` to the
    /// peer's pid), so that it ends the run and writes its files.
    pub forward_interrupt: bool,
}

/// How long the controller waits for the plant's end of run after SIGINT/SIGTERM (ns).
const INTERRUPT_GRACE_NS: u64 = 1_000_000_000;

/// Answers measurements until the end of the run or until the plant is lost.
///
/// On SIGINT/SIGTERM it goes on answering while the plant ends the run (with
/// `forward_interrupt`, it sends the plant `SIGTERM` first: a supervisor may have signalled
/// this process alone), and reports [`ControlEnd::Interrupted`] at the end of the run, or
/// after a second without one.
///
/// # Errors
/// A transport failure, or a plant running another scenario.
pub fn serve<C: Clock, L: ControlLink>(
    clock: &C,
    link: &mut L,
    ctrl: &mut AnyController,
    opt: &ServeOptions,
    stats: &mut ControlStats,
) -> Result<ControlEnd> {
    let mut idler = Idler::new(opt.wait, opt.spin_margin_ns);
    let mut session = None;
    let mut last_seq: Option<u64> = None;
    let mut watch = PeerWatch::new(opt.silence_ns, clock.now_ns());
    let mut expected = None;
    let mut skipped_since = 0u32;
    let mut interrupted_at = None;
    let end_of_run =
        |interrupted: bool| if interrupted { ControlEnd::Interrupted } else { ControlEnd::EndOfRun };
    loop {
        let mut newest: Option<MeasurementMsg> = None;
        while let Some(m) = link.try_receive()? {
            match check_measurement::<JOINTS>(&m, session, last_seq, opt.scenario_hash) {
                Ok(()) => match newest {
                    Some(old) if m.seq <= old.seq => stats.invalid += 1,
                    Some(_) => {
                        skipped_since += 1;
                        newest = Some(m);
                    }
                    None => newest = Some(m),
                },
                Err(WireError::Scenario) => bail!(
                    "the plant runs another scenario (its controller parameters differ from this one's); \
                     give both roles the same scenario flags"
                ),
                Err(_) => stats.invalid += 1,
            }
        }
        if let Some(m) = newest {
            let t_rx = clock.now_ns();
            session.get_or_insert(m.session);
            idler.reset();
            watch.heard(t_rx);
            let Some(meas) = m.measurement::<JOINTS>() else {
                stats.invalid += 1;
                continue;
            };
            // The command is held for one period. (Delay compensation: the HIL passes 0 for
            // now; see the wire's delay field.)
            let report = ctrl.step(&meas, m.dt, 0.0);
            if let Some(e) = report.error {
                stats.rejected += 1;
                stats.rejections.count(e);
            }
            let mut cmd = answer(&m, &report, t_rx, skipped_since);
            cmd.compute_ns = clock.now_ns() - t_rx;
            link.publish(&cmd)?;
            stats.compute.record(cmd.compute_ns);
            stats.answered += 1;
            stats.skipped += u64::from(skipped_since);
            skipped_since = 0;
            last_seq = Some(m.seq);
            expected = (m.period_ns > 0).then(|| m.plant_time_ns + m.period_ns);
            if m.has(flags::END_OF_RUN) {
                stats.wait = idler.counts();
                return Ok(end_of_run(interrupted_at.is_some()));
            }
            continue;
        }
        let now = clock.now_ns();
        let limit = if last_seq.is_some() { opt.peer_timeout_ns } else { opt.startup_timeout_ns };
        match watch.check(now, limit, link)? {
            Some(PeerLoss::Died { pid, silent_ns }) => {
                return Ok(ControlEnd::PlantDied { pid, last_seq, silent_ns })
            }
            Some(PeerLoss::Gone) => return Ok(ControlEnd::PlantGone { last_seq }),
            Some(PeerLoss::Hung { silent_ns }) => return Ok(ControlEnd::PlantHung { silent_ns }),
            None => {}
        }
        if termination_requested() {
            // The plant ends the run at its next period (it got the signal too, from the same
            // terminal, or from here); give it a second, then leave.
            let t = *interrupted_at.get_or_insert_with(|| {
                if opt.forward_interrupt {
                    if let Ok(PeerState::Alive(pid)) = link.peer_state() {
                        let _ = crate::process::send_signal(pid, crate::process::Signal::Terminate);
                    }
                }
                now
            });
            if now - t > INTERRUPT_GRACE_NS {
                stats.wait = idler.counts();
                return Ok(ControlEnd::Interrupted);
            }
        }
        idler.idle(clock, expected, u64::MAX, |d| link.wait_event(d))?;
    }
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;
    use std::rc::Rc;
    use std::time::Duration;

    use anyhow::Result;
    use companion_core::{PaperRun, PlatformKind};
    use companion_plant::PaperTrajectory;

    use super::*;
    use crate::clock::FakeClock;
    use crate::hil::fault::{Corruption, Injecting};
    use crate::hil::messages::{scenario_hash, Stamp};
    use crate::link::Link;
    use crate::scenario::Scenario;
    use crate::wire::CommandMsg;

    /// A plant whose measurements arrive at given times on a fake clock.
    struct Fake {
        inbox: VecDeque<(u64, MeasurementMsg)>,
        sent: Vec<CommandMsg>,
        clock: Rc<FakeClock>,
        peer: PeerState,
        checks: u32,
    }

    impl Link for Fake {
        type Tx = CommandMsg;
        type Rx = MeasurementMsg;
        fn publish(&mut self, c: &CommandMsg) -> Result<()> {
            self.sent.push(*c);
            Ok(())
        }
        fn try_receive(&mut self) -> Result<Option<MeasurementMsg>> {
            match self.inbox.front() {
                Some((at, _)) if *at <= self.clock.now_ns() => Ok(self.inbox.pop_front().map(|x| x.1)),
                _ => Ok(None),
            }
        }
        fn wait_event(&mut self, d: Duration) -> Result<()> {
            self.clock.advance(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
            Ok(())
        }
        fn peer_state(&mut self) -> Result<PeerState> {
            self.checks += 1;
            Ok(self.peer)
        }
    }

    fn setup() -> (Scenario, AnyController, ServeOptions) {
        let s = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle)
            .duration(30.0)
            .build()
            .unwrap();
        let ctrl = AnyController::new(&s.controller).unwrap();
        let opt = ServeOptions {
            wait: WaitMode::Spin,
            spin_margin_ns: 100_000,
            silence_ns: 20_000_000,
            peer_timeout_ns: 2_000_000_000,
            startup_timeout_ns: 20_000_000_000,
            scenario_hash: scenario_hash(&s),
            forward_interrupt: false,
        };
        (s, ctrl, opt)
    }

    fn fake(peer: PeerState) -> (Rc<FakeClock>, Fake) {
        let clock = Rc::new(FakeClock::new(0, 1_000));
        let link = Fake { inbox: VecDeque::new(), sent: Vec::new(), clock: clock.clone(), peer, checks: 0 };
        (clock, link)
    }

    fn meas_msg(s: &Scenario, seq: u64, fl: u32) -> MeasurementMsg {
        let plant = crate::sim::build_plant(s).unwrap();
        let stamp = Stamp { session: 77, scenario_hash: scenario_hash(s), period_ns: 1_000_000, dt: s.dt };
        stamp.message(seq, fl, seq * 1_000_000, &plant.measure())
    }

    #[test]
    fn answers_the_newest_measurement_and_echoes_its_ids() {
        let (s, mut ctrl, opt) = setup();
        let (clock, mut link) = fake(PeerState::Alive(1));
        link.inbox.push_back((0, meas_msg(&s, 0, 0)));
        // Two measurements waiting at once: only the newer one is answered.
        link.inbox.push_back((5_000_000, meas_msg(&s, 1, 0)));
        link.inbox.push_back((5_000_000, meas_msg(&s, 2, flags::END_OF_RUN)));
        let mut st = ControlStats::default();
        let end = serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &mut st).unwrap();
        assert_eq!(end, ControlEnd::EndOfRun);
        assert_eq!(link.sent.len(), 2);
        assert_eq!((link.sent[0].seq, link.sent[1].seq), (0, 2));
        assert_eq!(link.sent[1].skipped, 1);
        assert_eq!(link.sent[1].session, 77);
        assert_eq!(link.sent[1].plant_time_ns, 2_000_000);
        assert_eq!((st.answered, st.skipped), (2, 1));
    }

    #[test]
    fn an_injection_at_a_skipped_measurement_goes_out_with_the_next_answer() {
        let (s, mut ctrl, opt) = setup();
        let (clock, mut link) = fake(PeerState::Alive(1));
        link.inbox.push_back((0, meas_msg(&s, 0, 0)));
        link.inbox.push_back((5_000_000, meas_msg(&s, 1, 0)));
        link.inbox.push_back((5_000_000, meas_msg(&s, 2, 0)));
        link.inbox.push_back((6_000_000, meas_msg(&s, 3, flags::END_OF_RUN)));
        let mut link = Injecting::new(link, vec![(1, Corruption::Session), (0, Corruption::Nan)]);
        let mut st = ControlStats::default();
        serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &mut st).unwrap();
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
        let (s, mut ctrl, opt) = setup();
        let (clock, mut link) = fake(PeerState::Dead(4242));
        link.inbox.push_back((0, meas_msg(&s, 0, 0)));
        let mut st = ControlStats::default();
        let end = serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &mut st).unwrap();
        match end {
            ControlEnd::PlantDied { pid, last_seq, silent_ns } => {
                assert_eq!((pid, last_seq), (4242, Some(0)));
                assert!(silent_ns >= opt.silence_ns && silent_ns < opt.silence_ns + 1_000_000, "{silent_ns}");
            }
            e => panic!("{e:?}"),
        }
        assert_eq!(link.checks, 1);
    }

    #[test]
    fn a_plant_with_another_scenario_is_refused() {
        let (s, mut ctrl, opt) = setup();
        let (clock, mut link) = fake(PeerState::Alive(1));
        let mut m = meas_msg(&s, 0, 0);
        m.scenario_hash ^= 1;
        link.inbox.push_back((0, m));
        let e = serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &mut ControlStats::default()).unwrap_err();
        assert!(e.to_string().contains("another scenario"), "{e}");
    }
}
