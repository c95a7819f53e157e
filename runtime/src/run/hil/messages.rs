//! The loops' ends of the wire: the one builder of measurement headers (the plant stamps
//! every measurement with its ids and its announcement), the report a received command
//! carries, and the controller's answer to a measurement.

use companion_core::{Command, Measurement};

use crate::domain::controller::StepReport;
#[cfg(test)]
use crate::domain::controller::JOINTS;
use crate::transport::wire::target::WireSpace;
use crate::transport::wire::{
    decode_status, limits, CommandHeader, CommandMsg, LoggedDiagnostics, MeasurementHeader, MeasurementMsg,
};

/// What the plant stamps on every measurement of a run: its session and its announcement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stamp {
    /// Session id (random per plant run).
    pub session: u64,
    /// Scenario hash (0: not checked).
    pub scenario_hash: u64,
    /// Arm hash (0: not checked).
    pub arm_hash: u64,
    /// The period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// How long each command is held (s).
    pub dt: f64,
    /// The announced flags (`LOCKSTEP`, `NOTIFIES`).
    pub flags: u32,
    /// The platform code.
    pub platform: u32,
    /// Hold limit (periods).
    pub hold_periods: u32,
}

impl Stamp {
    /// Measurement `seq` with the announced flags and `flags`, measured at `plant_time_ns`,
    /// its answer expected to take effect `delay` seconds later.
    #[inline]
    pub fn message<const N: usize, S: WireSpace>(
        &self,
        seq: u64,
        flags: u32,
        plant_time_ns: u64,
        delay: f64,
        meas: &Measurement<f64, N, S>,
    ) -> MeasurementMsg {
        let header = MeasurementHeader {
            seq,
            flags: self.flags | flags,
            session: self.session,
            scenario_hash: self.scenario_hash,
            arm_hash: self.arm_hash,
            plant_time_ns,
            period_ns: self.period_ns,
            dt: self.dt,
            delay,
            platform: self.platform,
            hold_periods: self.hold_periods,
        };
        MeasurementMsg::new(header, meas)
    }
}

/// The report a validated command carries (the zero command when the law rejected the step,
/// whatever the message's velocities).
pub fn report_of<const N: usize>(c: &CommandMsg) -> StepReport<N> {
    let error = decode_status(c.status).ok().flatten();
    let command = if error.is_some() { Command::zero() } else { c.command::<N>() };
    StepReport {
        command,
        ep_norm: c.ep_norm,
        h_s: c.h_s,
        psi: c.psi,
        saturation: c.saturation,
        alpha_rate: c.alpha_rate,
        joint_scale: c.joint_scale,
        platform_acceleration: error.is_none() && c.limits & limits::PLATFORM_ACCELERATION != 0,
        joint_acceleration: error.is_none() && c.limits & limits::JOINT_ACCELERATION != 0,
        error,
    }
}

/// The controller's answer to `m`: the step's command, status and logged diagnostics.
pub fn answer<const N: usize>(
    m: &MeasurementMsg,
    header: &CommandHeader,
    report: &StepReport<N>,
) -> CommandMsg {
    let diag = LoggedDiagnostics {
        ep_norm: report.ep_norm,
        h_s: report.h_s,
        psi: report.psi,
        saturation: report.saturation,
        alpha_rate: report.alpha_rate,
        joint_scale: report.joint_scale,
        limits: if report.platform_acceleration { limits::PLATFORM_ACCELERATION } else { 0 }
            | if report.joint_acceleration { limits::JOINT_ACCELERATION } else { 0 },
    };
    CommandMsg::answer(m, header, &report.command, report.error, &diag)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rejected_step_is_applied_as_the_zero_command() {
        let stamp = Stamp {
            session: 5,
            scenario_hash: 0,
            arm_hash: 0,
            period_ns: 0,
            dt: 1e-3,
            flags: crate::transport::wire::flags::LOCKSTEP,
            platform: crate::transport::wire::platform::UNICYCLE,
            hold_periods: 0,
        };
        let m = stamp.message(
            3,
            0,
            0,
            0.0,
            &Measurement::<f64, JOINTS> {
                t: 0.0,
                base: companion_core::Pose::new(0.0, 0.0, 0.0),
                steering: 0.0,
                joints: companion_core::nalgebra::SVector::<f64, JOINTS>::new(0.0, 0.35, 0.0),
                target: companion_core::Pose::new(1.0, 0.0, 0.0),
                target_velocity: companion_core::nalgebra::Vector3::zeros(),
            },
        );
        let mut r = StepReport::<JOINTS>::rejected(companion_core::StepError::SingularArm);
        r.command.platform.v = 3.0;
        let id = crate::transport::wire::ControllerIdentity {
            platform: 1,
            joint_count: 3,
            space: crate::transport::wire::target::space::PLANAR,
            arm_hash: 0,
            scenario_hash: 0,
            max_dt: 0.1,
        };
        let header = CommandHeader { identity: id, flags: 0, received_ns: 0, skipped: 0, delay: 0.0 };
        let c = answer(&m, &header, &r);
        assert_eq!((c.seq, c.session), (3, 5));
        let back = report_of::<JOINTS>(&c);
        assert_eq!(back.command, Command::zero());
        assert_eq!(back.error, Some(companion_core::StepError::SingularArm));
    }
}
