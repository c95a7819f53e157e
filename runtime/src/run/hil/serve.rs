//! The controller's loop: admit the plant (the session's first measurement), then answer each
//! measurement with one command until the end of the run or until the plant is lost.
//!
//! The law is built when the plant has announced itself ([`super::handshake::for_plant`]): the
//! commands depend on the specification, the announcement and the measurements, nothing else.
//! Each step predicts over the delay the plant announces (clamped to what the law admits,
//! `[0, min(max_delay, HISTORY · dt)]`; a non-finite delay is left to the law, which answers
//! it with the safe command and status `0x700`).

use companion_core::{Manipulator, Spatial, SpatialArm};

use super::config::HilScenario;
use super::config::WaitMode;
use super::end::ControlEnd;
use super::law::{Law as _, LawError, PlanarLaw, Served, SpatialLaw};
use super::messages::answer;
use super::stats::ControlStats;
use super::wait::Idler;
use super::wakes::Took;
use super::watch::{PeerLoss, PeerWatch};
use crate::domain::arm::ArmError;
use crate::domain::controller::ControllerSpec;
use crate::domain::observe::Observer;
use crate::run::spatial::SpatialScenario;
use crate::sys::clock::Clock;
use crate::sys::signals::termination_requested;
use crate::transport::link::{ControlLink, LinkError, PeerState};
use crate::transport::wire::canonical;
use crate::transport::wire::{
    check_measurement, flags, Announcement, CommandHeader, CommandMsg, ControllerIdentity, MeasurementMsg,
    Refusal,
};

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
    /// On SIGINT/SIGTERM, hand the interruption on to the plant process (`SIGTERM` to the
    /// peer's pid), so that it ends the run and writes its files.
    pub forward_interrupt: bool,
    /// Pass the plant's announced delay to the law (else 0).
    pub delay_compensation: bool,
    /// Each answer's deadline after its period's release (ns; 0: none, lockstep): what the
    /// [wake log](super::wakes) judges wakes against.
    pub deadline_ns: u64,
}

/// The controller refused the plant (it sent the refusal and ends the run).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("refused the plant: {0}")]
pub struct Refused(pub Refusal);

/// Why the controller's loop failed (its ends, a lost plant among them, are
/// [`ControlEnd`]s).
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The transport failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The controller refused the plant.
    #[error(transparent)]
    Refused(#[from] Refused),
    /// The law for the plant cannot be built.
    #[error(transparent)]
    Law(#[from] LawError),
    /// The scenario's arm cannot be built.
    #[error(transparent)]
    Arm(#[from] ArmError),
}

/// How long the controller waits for the plant's end of run after SIGINT/SIGTERM (ns).
const INTERRUPT_GRACE_NS: u64 = 1_000_000_000;

/// The session being served.
struct Session<L> {
    session: u64,
    announced: Announcement,
    ctrl: L,
    /// The largest delay the law admits (s).
    max_delay: f64,
    /// The plant's STOPPED flag in its last measurement.
    stopped: bool,
}

impl<L> Session<L> {
    /// The delay to predict over for `m`.
    #[inline]
    fn delay(&self, m: &MeasurementMsg, compensate: bool, stats: &mut ControlStats) -> f64 {
        if !compensate {
            return 0.0;
        }
        let d = m.delay;
        if d.is_finite() && !(0.0..=self.max_delay).contains(&d) {
            stats.delay_clamped += 1;
            return d.clamp(0.0, self.max_delay);
        }
        d
    }
}

/// Answers measurements until the end of the run or until the plant is lost. The first
/// measurement of a session is the handshake: the plant's version and announcement are
/// checked against `spec` (a mismatch is refused, see [`Refused`]), and the law is built for
/// the plant. `observer` hears about a fallback from event waiting.
///
/// On SIGINT/SIGTERM it goes on answering while the plant ends the run (with
/// `forward_interrupt`, it sends the plant `SIGTERM` first: a supervisor may have signalled
/// this process alone), and reports [`ControlEnd::Interrupted`] at the end of the run, or
/// after a second without one.
///
/// # Errors
/// A transport failure, an invalid specification, or [`Refused`].
pub fn serve<C: Clock, L: ControlLink>(
    clock: &C,
    link: &mut L,
    spec: &ControllerSpec,
    opt: &ServeOptions,
    stats: &mut ControlStats,
    observer: &dyn Observer,
) -> Result<ControlEnd, ServeError> {
    serve_law(clock, link, &PlanarLaw(spec), opt, stats, observer)
}

/// [`serve`] for the scenario's arm: the paper's, or a spatial one of 6 to 8 joints.
///
/// # Errors
/// As [`serve`], and an arm that cannot be built.
pub fn serve_scenario<C: Clock, L: ControlLink>(
    clock: &C,
    link: &mut L,
    s: &HilScenario,
    opt: &ServeOptions,
    stats: &mut ControlStats,
    observer: &dyn Observer,
) -> Result<ControlEnd, ServeError> {
    fn spatial<C: Clock, L: ControlLink, const N: usize>(
        clock: &C,
        link: &mut L,
        ss: &SpatialScenario,
        opt: &ServeOptions,
        stats: &mut ControlStats,
        observer: &dyn Observer,
    ) -> Result<ControlEnd, ServeError>
    where
        SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
        SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
    {
        let arm_hash = canonical::arm_hash(&ss.arm.chain::<f64, N>()?);
        let law = SpatialLaw { spec: &ss.base.controller, arm: &ss.arm, arm_hash };
        serve_law::<C, L, N, _>(clock, link, &law, opt, stats, observer)
    }
    match s {
        HilScenario::Planar(p) => serve(clock, link, &p.controller, opt, stats, observer),
        HilScenario::Spatial(ss) => match ss.arm.joints() {
            6 => spatial::<C, L, 6>(clock, link, ss, opt, stats, observer),
            7 => spatial::<C, L, 7>(clock, link, ss, opt, stats, observer),
            8 => spatial::<C, L, 8>(clock, link, ss, opt, stats, observer),
            n => Err(ArmError::JointCount { found: n }.into()),
        },
    }
}

/// [`serve`] for any law: the paper's planar one ([`PlanarLaw`]) or a spatial arm's
/// ([`super::law::SpatialLaw`]).
///
/// # Errors
/// As [`serve`].
pub fn serve_law<C: Clock, L: ControlLink, const N: usize, F: Served<N>>(
    clock: &C,
    link: &mut L,
    law: &F,
    opt: &ServeOptions,
    stats: &mut ControlStats,
    observer: &dyn Observer,
) -> Result<ControlEnd, ServeError> {
    let identity = law.identity();
    let notify = if link.notifies() { flags::NOTIFIES } else { 0 };
    let mut idler = Idler::new(opt.wait, opt.spin_margin_ns);
    let mut served: Option<Session<F::Law>> = None;
    let mut last_seq: Option<u64> = None;
    let mut watch = PeerWatch::new(opt.silence_ns, clock.now_ns());
    let mut expected = None;
    let mut skipped_since = 0u32;
    let mut interrupted_at = None;
    let end_of_run =
        |interrupted: bool| if interrupted { ControlEnd::Interrupted } else { ControlEnd::EndOfRun };
    stats.wakes.judge_against(opt.deadline_ns);
    loop {
        // Each look is stamped for the wake log: what happened since the last one that found
        // nothing says why a measurement was taken late.
        let look = clock.now_ns();
        let mut newest: Option<MeasurementMsg> = None;
        // The oldest new measurement's publication, and how many came in this drain.
        let (mut first_pub, mut fresh) = (None, 0u64);
        while let Some(m) = link.try_receive()? {
            let Some(s) = &served else {
                let s = admit::<L, N, F>(link, law, &identity, &m, notify, clock.now_ns())?;
                if opt.wait.uses_events() && !s.announced.notifies() {
                    idler = Idler::new(WaitMode::Hybrid, opt.spin_margin_ns);
                    stats.event_fallback = true;
                    observer.warn(
                        "the plant does not notify measurement-ready (flag NOTIFIES clear): waiting by polling \
                         (hybrid) instead of on the event",
                    );
                }
                served = Some(s);
                newest = Some(m);
                continue;
            };
            match check_measurement(&m, s.session, &s.announced, last_seq) {
                Ok(()) => match newest {
                    Some(old) if m.seq <= old.seq => stats.invalid += 1,
                    Some(_) => {
                        skipped_since += 1;
                        fresh += 1;
                        newest = Some(m);
                    }
                    None => {
                        first_pub.get_or_insert(m.plant_time_ns);
                        fresh += 1;
                        newest = Some(m);
                    }
                },
                Err(_) => stats.invalid += 1,
            }
        }
        if let (Some(m), Some(s)) = (newest, &mut served) {
            let t_rx = clock.now_ns();
            idler.reset(t_rx);
            watch.heard(t_rx);
            let Ok(meas) = m.read::<N, F::Space>() else {
                stats.invalid += 1;
                continue;
            };
            let stopped = m.has(flags::STOPPED);
            if stopped && !s.stopped && stats.answered > 0 {
                stats.stop_events += 1;
                stats.first_stop_seq.get_or_insert(m.seq);
            }
            s.stopped = stopped;
            let delay = s.delay(&m, opt.delay_compensation, stats);
            let report = s.ctrl.step(&meas, m.dt, delay);
            if let Some(e) = report.error {
                stats.rejected += 1;
                stats.rejections.count(e);
            }
            let header =
                CommandHeader { identity, flags: notify, received_ns: t_rx, skipped: skipped_since, delay };
            let mut cmd = answer(&m, &header, &report);
            cmd.compute_ns = clock.now_ns() - t_rx;
            link.publish(&cmd)?;
            stats.compute.record(cmd.compute_ns);
            // The periods since the last answer, this one's included, and when the oldest was
            // published: its stamp, or, if the transport's queue overwrote it, the newest's less
            // the periods between.
            let (count, first_pub) = match last_seq {
                Some(l) if m.seq > l => {
                    let est = m.plant_time_ns.saturating_sub((m.seq - l - 1).saturating_mul(m.period_ns));
                    (m.seq - l, first_pub.map_or(est, |f: u64| f.min(est)))
                }
                _ => (fresh.max(1), first_pub.unwrap_or(m.plant_time_ns)),
            };
            let took = Took {
                first_pub,
                last_pub: m.plant_time_ns,
                count,
                look,
                received: t_rx,
                compute: cmd.compute_ns,
            };
            stats.wakes.took(&took, last_seq.is_some() && m.period_ns > 0);
            stats.delay.record(if delay.is_finite() { (delay * 1e9) as u64 } else { 0 });
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
            Some(PeerLoss::Died { pid, silent_ns, expired }) => {
                return Ok(ControlEnd::PlantDied { pid, last_seq, silent_ns, expired })
            }
            Some(PeerLoss::Gone) => return Ok(ControlEnd::PlantGone { last_seq }),
            Some(PeerLoss::Hung { silent_ns, pid }) => return Ok(ControlEnd::PlantHung { silent_ns, pid }),
            None => {}
        }
        if termination_requested() {
            // The plant ends the run at its next period (it got the signal too, from the same
            // terminal, or from here); give it a second, then leave.
            let t = *interrupted_at.get_or_insert_with(|| {
                if opt.forward_interrupt {
                    if let Ok(PeerState::Alive(pid)) = link.peer_state() {
                        let _ = crate::sys::process::send_signal(pid, crate::sys::process::Signal::Terminate);
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
        stats.wakes.idled(look, idler.last_step());
    }
}

/// The handshake: checks the session's first measurement `m` and builds the law for the plant
/// it announces, or refuses the plant (the refusal is sent, answering `m`).
#[cold]
fn admit<L: ControlLink, const N: usize, F: Served<N>>(
    link: &mut L,
    law: &F,
    identity: &ControllerIdentity,
    m: &MeasurementMsg,
    notify: u32,
    now: u64,
) -> Result<Session<F::Law>, ServeError> {
    let announced = match identity.admit(m) {
        Ok(a) => a,
        Err(why) => {
            let header = CommandHeader {
                identity: *identity,
                flags: notify,
                received_ns: now,
                skipped: 0,
                delay: 0.0,
            };
            link.publish(&CommandMsg::refusal::<N>(m, &header, &why))?;
            return Err(Refused(why).into());
        }
    };
    let (ctrl, max_delay) = law.build(&announced)?;
    Ok(Session { session: m.session, announced, ctrl, max_delay, stopped: false })
}

#[cfg(test)]
mod tests;
