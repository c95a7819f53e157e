//! The controller process: answers each measurement with one command.

use std::process::{Child, ExitCode};
use std::time::Duration;

use anyhow::{anyhow, bail, Result};
use serde::Serialize;

use super::wait::Idler;
use super::{HilArgs, WaitMode, EXIT_INTERRUPTED, EXIT_PEER_HUNG, EXIT_PEER_LOST};
use crate::clock::{Clock, MonotonicClock};
use crate::control::{AnyController, JOINTS};
use crate::ipc::{ControlEndpoint, PeerState, Role};
use crate::latency::stats::{fmt_ns, LatencyHistogram};
use crate::scenario::Scenario;
use crate::wire::{check_measurement, flags, CommandMsg, LoggedDiagnostics, MeasurementMsg, WireError};

/// The controller's side of the transport, as the loop sees it (a fake in tests).
pub trait ControlLink {
    /// Publishes a command.
    ///
    /// # Errors
    /// A transport failure.
    fn publish(&mut self, c: &CommandMsg) -> Result<()>;
    /// Takes the oldest waiting measurement.
    ///
    /// # Errors
    /// A transport failure.
    fn try_receive(&mut self) -> Result<Option<MeasurementMsg>>;
    /// Waits on the transport's event for at most `timeout` (event mode; else returns).
    ///
    /// # Errors
    /// A transport failure.
    fn wait_event(&mut self, timeout: Duration) -> Result<()>;
    /// Whether the plant is alive.
    ///
    /// # Errors
    /// The node list cannot be read.
    fn peer_state(&mut self) -> Result<PeerState>;
}

impl ControlLink for ControlEndpoint {
    #[inline]
    fn publish(&mut self, c: &CommandMsg) -> Result<()> {
        self.send(c)
    }
    #[inline]
    fn try_receive(&mut self) -> Result<Option<MeasurementMsg>> {
        ControlEndpoint::try_receive(self)
    }
    #[inline]
    fn wait_event(&mut self, timeout: Duration) -> Result<()> {
        ControlEndpoint::wait_event(self, timeout)
    }
    fn peer_state(&mut self) -> Result<PeerState> {
        ControlEndpoint::peer_state(self)
    }
}

/// A corrupted command to send (testing the plant's validation end to end).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corruption {
    /// Another protocol version.
    Version,
    /// A NaN forward speed.
    Nan,
    /// A sequence number from the future.
    Seq,
    /// Another session.
    Session,
}

/// Parses `version@100,nan@200,seq@300,session@400`, sorted by sequence number.
///
/// Each corruption goes out once, just before the answer to the first measurement whose
/// sequence number is at least the given one (in real time a measurement can be skipped as
/// superseded, so an exact match could never come).
///
/// # Errors
/// An unknown kind or a bad number.
pub fn parse_injections(s: &str) -> Result<Vec<(u64, Corruption)>> {
    s.split(',')
        .filter(|x| !x.trim().is_empty())
        .map(|item| {
            let (kind, at) =
                item.trim().split_once('@').ok_or_else(|| anyhow!("--inject item {item:?}: KIND@SEQ"))?;
            let kind = match kind {
                "version" => Corruption::Version,
                "nan" => Corruption::Nan,
                "seq" => Corruption::Seq,
                "session" => Corruption::Session,
                _ => bail!("--inject: unknown kind {kind:?} (version, nan, seq, session)"),
            };
            Ok((at.parse::<u64>().map_err(|e| anyhow!("--inject {item:?}: {e}"))?, kind))
        })
        .collect::<Result<Vec<_>>>()
        .map(|mut v| {
            v.sort_by_key(|x| x.0);
            v
        })
}

fn corrupt(c: &CommandMsg, k: Corruption) -> CommandMsg {
    match k {
        Corruption::Version => CommandMsg { version: c.version + 1, ..*c },
        Corruption::Nan => CommandMsg { v: f64::NAN, ..*c },
        Corruption::Seq => CommandMsg { seq: c.seq + 1_000_000, ..*c },
        Corruption::Session => CommandMsg { session: c.session ^ 0x5a5a, ..*c },
    }
}

/// How the controller's run ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ControlEnd {
    /// The plant sent its last measurement and got its answer.
    EndOfRun,
    /// The plant's process died.
    PlantDied {
        /// Its pid.
        pid: i32,
        /// The last measurement answered.
        last_seq: Option<u64>,
        /// Time from the last measurement to the finding (ns).
        silent_ns: u64,
    },
    /// The plant's node is gone.
    PlantGone {
        /// The last measurement answered.
        last_seq: Option<u64>,
    },
    /// The plant is alive but silent.
    PlantHung {
        /// Silence (ns).
        silent_ns: u64,
    },
    /// SIGINT/SIGTERM and no end of run within a second.
    Interrupted,
}

/// What the controller measured.
#[derive(Clone, Debug, Default)]
pub struct ControlStats {
    /// Compute time per answer (ns).
    pub compute: LatencyHistogram,
    /// Measurements answered.
    pub answered: u64,
    /// Measurements skipped as superseded by a newer one.
    pub skipped: u64,
    /// Measurements dropped as malformed or out of order.
    pub invalid: u64,
    /// Steps the law rejected (safe command sent).
    pub rejected: u64,
}

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
}

/// Answers measurements until the end of the run or until the plant is lost.
///
/// `injections` (sorted by sequence number, as [`parse_injections`] returns them) are
/// corrupted commands sent for testing.
///
/// # Errors
/// A transport failure, or a plant running another scenario.
pub fn serve<C: Clock, L: ControlLink>(
    clock: &C,
    link: &mut L,
    ctrl: &mut AnyController,
    opt: &ServeOptions,
    injections: &[(u64, Corruption)],
    stats: &mut ControlStats,
) -> Result<ControlEnd> {
    let mut idler = Idler::new(opt.wait, opt.spin_margin_ns);
    let mut session = None;
    let mut last_seq: Option<u64> = None;
    let mut last_rx = clock.now_ns();
    let mut last_check = last_rx;
    let mut expected = None;
    let mut skipped_since = 0u32;
    let mut interrupted_at = None;
    let mut next_injection = 0;
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
            last_rx = t_rx;
            let Some(meas) = m.measurement::<JOINTS>() else {
                stats.invalid += 1;
                continue;
            };
            // The controller integrates its state over the time since the previous answer.
            let k = last_seq.map_or(1, |l| m.seq - l);
            #[allow(clippy::cast_precision_loss)]
            let dt = if k == 1 { m.dt } else { m.dt * k as f64 };
            let report = ctrl.step(&meas, dt);
            if report.error.is_some() {
                stats.rejected += 1;
            }
            let diag = LoggedDiagnostics {
                ep_norm: report.ep_norm,
                h_s: report.h_s,
                psi: report.psi,
                saturation: report.saturation,
                alpha_rate: report.alpha_rate,
            };
            let mut cmd = CommandMsg::answer(&m, &report.command, report.error, &diag, t_rx, skipped_since);
            while let Some(&(at, kind)) = injections.get(next_injection) {
                if at > m.seq {
                    break;
                }
                link.publish(&corrupt(&cmd, kind))?;
                next_injection += 1;
            }
            cmd.compute_ns = clock.now_ns() - t_rx;
            link.publish(&cmd)?;
            stats.compute.record(cmd.compute_ns);
            stats.answered += 1;
            stats.skipped += u64::from(skipped_since);
            skipped_since = 0;
            last_seq = Some(m.seq);
            expected = (m.period_ns > 0).then(|| m.plant_time_ns + m.period_ns);
            if m.has(flags::END_OF_RUN) {
                return Ok(ControlEnd::EndOfRun);
            }
            continue;
        }
        let now = clock.now_ns();
        let silent = now - last_rx;
        if silent >= opt.silence_ns && now - last_check >= opt.silence_ns {
            last_check = now;
            let limit = if last_seq.is_some() { opt.peer_timeout_ns } else { opt.startup_timeout_ns };
            match link.peer_state()? {
                PeerState::Dead(pid) => {
                    return Ok(ControlEnd::PlantDied { pid, last_seq, silent_ns: silent })
                }
                PeerState::Absent => return Ok(ControlEnd::PlantGone { last_seq }),
                PeerState::Alive(_) if silent >= limit => {
                    return Ok(ControlEnd::PlantHung { silent_ns: silent })
                }
                PeerState::Alive(_) => {}
            }
        }
        if crate::rt::termination_requested() {
            // The plant (same terminal) got the signal too and ends the run at its next period;
            // give it a second, then leave.
            let t = *interrupted_at.get_or_insert(now);
            if now - t > 1_000_000_000 {
                return Ok(ControlEnd::Interrupted);
            }
        }
        idler.idle(clock, expected, u64::MAX, |d| link.wait_event(d))?;
    }
}

fn serve_options(a: &HilArgs, s: &Scenario) -> Result<ServeOptions> {
    let t = a.timing(s)?;
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let startup = (a.startup_timeout * 1e9) as u64;
    Ok(ServeOptions {
        wait: t.wait,
        spin_margin_ns: t.spin_margin_ns,
        silence_ns: t.silence_ns,
        peer_timeout_ns: t.peer_timeout_ns,
        startup_timeout_ns: startup.max(t.peer_timeout_ns),
        scenario_hash: super::plant::scenario_hash(s),
    })
}

struct Session {
    end: ControlEnd,
    stats: ControlStats,
}

fn session(a: &HilArgs, s: &Scenario, abort: impl FnMut() -> Option<String>) -> Result<Session> {
    let opt = serve_options(a, s)?;
    let injections = a.inject.as_deref().map(parse_injections).transpose()?.unwrap_or_default();
    let mut ctrl = AnyController::new(&s.controller).map_err(|e| anyhow!("invalid parameter: {e}"))?;
    let mut ep = ControlEndpoint::control(&a.name, a.wait_mode() == WaitMode::Event)?;
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let startup = Duration::from_secs_f64(a.startup_timeout);
    ep.wait_for_peer(startup, abort)?;
    let rt = a.rt_config(Role::Control).map(|cfg| crate::rt::apply(&cfg));
    if let Some(r) = &rt {
        r.warn("controller");
    }
    let mut stats = ControlStats::default();
    let r = serve(&MonotonicClock, &mut ep, &mut ctrl, &opt, &injections, &mut stats);
    if rt.is_some() {
        crate::rt::reset_thread();
    }
    let end = r?;
    if matches!(end, ControlEnd::PlantDied { .. }) {
        ep.cleanup_dead_nodes();
    }
    Ok(Session { end, stats })
}

fn print_stats(st: &ControlStats) {
    let p = st.compute.percentiles();
    eprintln!(
        "controller: answered {} measurements ({} skipped as superseded, {} dropped as malformed, {} rejected by \
         the law); compute p50 {} p99 {} max {}",
        st.answered,
        st.skipped,
        st.invalid,
        st.rejected,
        fmt_ns(p.p50),
        fmt_ns(p.p99),
        fmt_ns(p.max)
    );
}

#[allow(clippy::cast_precision_loss)]
fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}

fn describe(end: &ControlEnd) -> String {
    let seq = |s: &Option<u64>| {
        s.map_or("before the first measurement".to_string(), |s| format!("after cycle {s}"))
    };
    match end {
        ControlEnd::EndOfRun => "end of run".into(),
        ControlEnd::PlantDied { pid, last_seq, silent_ns } => format!(
            "the plant (pid {pid}) died {}; noticed {:.1} ms after its last measurement",
            seq(last_seq),
            ms(*silent_ns)
        ),
        ControlEnd::PlantGone { last_seq } => format!("the plant left {}", seq(last_seq)),
        ControlEnd::PlantHung { silent_ns } => {
            format!("the plant is alive but has sent nothing for {:.0} ms", ms(*silent_ns))
        }
        ControlEnd::Interrupted => "interrupted".into(),
    }
}

fn exit_code(end: &ControlEnd) -> u8 {
    match end {
        ControlEnd::EndOfRun => 0,
        ControlEnd::PlantDied { .. } | ControlEnd::PlantGone { .. } => EXIT_PEER_LOST,
        ControlEnd::PlantHung { .. } => EXIT_PEER_HUNG,
        ControlEnd::Interrupted => EXIT_INTERRUPTED,
    }
}

/// `companion control`: the controller role alone.
///
/// # Errors
/// A bad flag or a transport failure.
pub fn run_alone(a: &HilArgs) -> Result<ExitCode> {
    let s = a.scenario()?;
    eprintln!("controller: demo '{}' waiting for its plant (companion plant --name {})", a.name, a.name);
    let Session { end, stats } = session(a, &s, || None)?;
    print_stats(&stats);
    if end != ControlEnd::EndOfRun {
        eprintln!("controller: {}", describe(&end));
    }
    Ok(ExitCode::from(exit_code(&end)))
}

/// What the controller writes when the plant died under it.
#[derive(Debug, Serialize)]
struct Fault {
    fault: String,
    plant_pid: i32,
    plant_exit: String,
    last_cycle_answered: Option<u64>,
    noticed_after_last_measurement_ms: f64,
    rows_on_disk: Option<u64>,
    controller_answered: u64,
}

fn exit_text(st: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (st.code(), st.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(sig)) => format!("killed by signal {sig}"),
        _ => "unknown".into(),
    }
}

/// The controller side of `companion hil`, with the plant `child` it started.
///
/// # Errors
/// A transport failure.
pub fn run_as_parent(a: &HilArgs, s: &Scenario, child: Child) -> Result<ExitCode> {
    let mut child = crate::latency::pingpong::ChildGuard(Some(child));
    let pid = child.0.as_ref().map_or(0, Child::id);
    let mut exited = None;
    let abort = || -> Option<String> {
        let c = child.0.as_mut()?;
        match c.try_wait() {
            Ok(Some(st)) => {
                exited = Some(st);
                Some(format!("the plant (pid {pid}) ended before the run started ({})", exit_text(st)))
            }
            _ => None,
        }
    };
    let result = session(a, s, abort);
    if exited.is_some() {
        child.0 = None;
    }
    let Session { end, stats } = match result {
        Ok(x) => x,
        Err(e) => {
            // The plant may already have explained (e.g. a name in use); its status says more.
            if let Some(st) = exited {
                return Ok(ExitCode::from(u8::try_from(st.code().unwrap_or(2)).unwrap_or(2)));
            }
            // Leave the plant to notice the lost controller, stop the robot and write its
            // files (it does so within --silence-ms); kill it only if it does not.
            eprintln!("error: {e:#}");
            let _ = child.finish(Duration::from_secs_f64(a.peer_timeout + 5.0));
            return Ok(ExitCode::from(2));
        }
    };
    match end {
        ControlEnd::EndOfRun | ControlEnd::Interrupted => {
            // The plant writes its files and plots, then exits with the run's status.
            let st = child.finish(Duration::from_secs(600))?;
            print_stats(&stats);
            let code = st.and_then(|s| s.code()).unwrap_or(2);
            if end == ControlEnd::Interrupted && code == 0 {
                return Ok(ExitCode::from(EXIT_INTERRUPTED));
            }
            Ok(ExitCode::from(u8::try_from(code).unwrap_or(2)))
        }
        ControlEnd::PlantDied { .. } | ControlEnd::PlantGone { .. } | ControlEnd::PlantHung { .. } => {
            let status = if matches!(end, ControlEnd::PlantHung { .. }) {
                // Alive but silent: stop it (it cannot be trusted to end on its own).
                child.finish(Duration::ZERO)?
            } else {
                child.finish(Duration::from_secs(5))?
            };
            let how = status.map_or("unknown".to_string(), exit_text);
            eprintln!("controller: {} ({how})", describe(&end));
            let rows = super::trim_partial_csv(&a.out).ok();
            if let Some(r) = rows {
                eprintln!(
                    "controller: {} rows recorded up to the fault are in {}",
                    r,
                    a.out.join("timeseries.csv").display()
                );
            }
            let (last, silent) = match end {
                ControlEnd::PlantDied { last_seq, silent_ns, .. } => (last_seq, silent_ns),
                ControlEnd::PlantGone { last_seq } => (last_seq, 0),
                ControlEnd::PlantHung { silent_ns } => (None, silent_ns),
                _ => (None, 0),
            };
            let fault = Fault {
                fault: describe(&end),
                plant_pid: i32::try_from(pid).unwrap_or(0),
                plant_exit: how,
                last_cycle_answered: last.or((stats.answered > 0).then_some(stats.answered - 1)),
                noticed_after_last_measurement_ms: ms(silent),
                rows_on_disk: rows,
                controller_answered: stats.answered,
            };
            let _ = std::fs::create_dir_all(&a.out);
            let path = a.out.join("fault.json");
            if let Err(e) = std::fs::write(&path, serde_json::to_string_pretty(&fault)? + "\n") {
                eprintln!("warning: writing {}: {e}", path.display());
            }
            print_stats(&stats);
            Ok(ExitCode::from(exit_code(&end)))
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::VecDeque;

    use clap::Parser;

    use super::*;
    use crate::clock::FakeClock;
    use crate::wire::MeasurementHeader;

    #[derive(Parser, Debug)]
    struct T {
        #[command(flatten)]
        a: HilArgs,
    }

    struct Fake {
        inbox: VecDeque<(u64, MeasurementMsg)>,
        sent: Vec<CommandMsg>,
        clock: std::rc::Rc<FakeClock>,
        peer: PeerState,
        checks: u32,
    }

    impl ControlLink for Fake {
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
        let t = T::parse_from(["x"]);
        let s = t.a.scenario().unwrap();
        let ctrl = AnyController::new(&s.controller).unwrap();
        let opt = serve_options(&t.a, &s).unwrap();
        (s, ctrl, opt)
    }

    fn fake(peer: PeerState) -> (std::rc::Rc<FakeClock>, Fake) {
        let clock = std::rc::Rc::new(FakeClock::new(0, 1_000));
        let link = Fake { inbox: VecDeque::new(), sent: Vec::new(), clock: clock.clone(), peer, checks: 0 };
        (clock, link)
    }

    fn meas_msg(s: &Scenario, seq: u64, fl: u32) -> MeasurementMsg {
        let plant = crate::sim::build_plant(s).unwrap();
        MeasurementMsg::new(
            MeasurementHeader {
                seq,
                flags: fl,
                session: 77,
                scenario_hash: super::super::plant::scenario_hash(s),
                plant_time_ns: seq * 1_000_000,
                period_ns: 1_000_000,
                dt: s.dt,
            },
            &plant.measure(),
        )
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
        let end = serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &[], &mut st).unwrap();
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
        let inj = parse_injections("session@1,nan@0").unwrap();
        let mut st = ControlStats::default();
        serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &inj, &mut st).unwrap();
        // Answers 0, 2, 3; NaN before answer 0; seq 1 was skipped, so its corruption goes
        // before answer 2; each exactly once.
        let seen: Vec<_> = link.sent.iter().map(|c| (c.seq, c.session == 77, c.v.is_nan())).collect();
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
        let end = serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &[], &mut st).unwrap();
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
        let e =
            serve(clock.as_ref(), &mut link, &mut ctrl, &opt, &[], &mut ControlStats::default()).unwrap_err();
        assert!(e.to_string().contains("another scenario"), "{e}");
    }

    #[test]
    fn injections_parse() {
        assert_eq!(
            parse_injections("version@1,nan@2,seq@3,session@4").unwrap(),
            vec![
                (1, Corruption::Version),
                (2, Corruption::Nan),
                (3, Corruption::Seq),
                (4, Corruption::Session)
            ]
        );
        assert!(parse_injections("bogus@1").is_err());
        assert!(parse_injections("nan").is_err());
    }
}
