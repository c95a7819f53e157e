//! The loops' ends of the wire: the one builder of measurement headers (the plant stamps
//! every measurement with its ids, period and step), the report a received command carries,
//! and the controller's answer to a measurement.

use companion_core::{Command, Measurement};

use crate::controller::{StepReport, JOINTS};
use crate::scenario::Scenario;
use crate::wire::{decode_status, fnv1a, CommandMsg, LoggedDiagnostics, MeasurementHeader, MeasurementMsg};

/// The scenario hash both roles compute: FNV-1a of the controller's specification (a
/// controller refuses a plant whose hash differs).
pub fn scenario_hash(s: &Scenario) -> u64 {
    serde_json::to_vec(&s.controller).map_or(0, |b| fnv1a(&b)).max(1)
}

/// What the plant stamps on every measurement of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamp {
    /// Session id (random per plant run).
    pub session: u64,
    /// Scenario hash.
    pub scenario_hash: u64,
    /// The period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// The step the controller integrates over (s).
    pub dt: f64,
}

impl Stamp {
    /// Measurement `seq` with `flags`, stamped with the publication time `plant_time_ns`.
    #[inline]
    pub fn message(
        &self,
        seq: u64,
        flags: u32,
        plant_time_ns: u64,
        meas: &Measurement<f64, JOINTS>,
    ) -> MeasurementMsg {
        let header = MeasurementHeader {
            seq,
            flags,
            session: self.session,
            scenario_hash: self.scenario_hash,
            plant_time_ns,
            period_ns: self.period_ns,
            dt: self.dt,
        };
        MeasurementMsg::new(header, meas)
    }
}

/// The report a validated command carries (the zero command when the law rejected the step,
/// whatever the message's velocities).
pub fn report_of(c: &CommandMsg) -> StepReport {
    let error = decode_status(c.status).ok().flatten();
    let command = if error.is_some() { Command::zero() } else { c.command::<JOINTS>() };
    StepReport {
        command,
        ep_norm: c.ep_norm,
        h_s: c.h_s,
        psi: c.psi,
        saturation: c.saturation,
        alpha_rate: c.alpha_rate,
        // Not on the wire.
        joint_scale: f64::NAN,
        error,
    }
}

/// The controller's answer to `m`: the step's command, status and logged diagnostics.
pub fn answer(m: &MeasurementMsg, report: &StepReport, received_ns: u64, skipped: u32) -> CommandMsg {
    let diag = LoggedDiagnostics {
        ep_norm: report.ep_norm,
        h_s: report.h_s,
        psi: report.psi,
        saturation: report.saturation,
        alpha_rate: report.alpha_rate,
    };
    CommandMsg::answer(m, &report.command, report.error, &diag, received_ns, skipped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rejected_step_is_applied_as_the_zero_command() {
        let stamp = Stamp { session: 5, scenario_hash: 0, period_ns: 0, dt: 1e-3 };
        let m = stamp.message(
            3,
            0,
            0,
            &Measurement::<f64, JOINTS> {
                t: 0.0,
                base: companion_core::Pose::new(0.0, 0.0, 0.0),
                steering: 0.0,
                joints: companion_core::nalgebra::SVector::<f64, JOINTS>::new(0.0, 0.35, 0.0),
                target: companion_core::Pose::new(1.0, 0.0, 0.0),
                target_velocity: companion_core::nalgebra::Vector3::zeros(),
            },
        );
        let mut r = StepReport::rejected(companion_core::StepError::SingularArm);
        r.command.platform.v = 3.0;
        let c = answer(&m, &r, 0, 0);
        assert_eq!((c.seq, c.session), (3, 5));
        let back = report_of(&c);
        assert_eq!(back.command, Command::zero());
        assert_eq!(back.error, Some(companion_core::StepError::SingularArm));
    }
}
