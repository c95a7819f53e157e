//! The messages built from and read into the core's types: a measurement from a
//! [`Measurement`] and its header, a command from the law's [`Command`] and diagnostics.

use companion_core::nalgebra::SVector;
use companion_core::{Command, Measurement, Planar, PlatformCommand, Pose, StepError};

use super::handshake::{ControllerIdentity, Refusal};
use super::layout::{
    count_u32, CommandMsg, MeasurementMsg, COMMAND_SIZE, MAX_JOINTS, MEASUREMENT_SIZE, PROTOCOL_VERSION,
};
use super::status::{encode_status, WireError};
use super::target::{WireSpace, WireTarget};

impl MeasurementMsg {
    /// A measurement of `N` joints and a planar or spatial target with the given header
    /// fields (the target converted by [`WireSpace::to_wire`]).
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn new<const N: usize, S: WireSpace>(header: MeasurementHeader, m: &Measurement<f64, N, S>) -> Self {
        const { assert!(N <= MAX_JOINTS) };
        let mut joints = [0.0; MAX_JOINTS];
        for (j, q) in joints.iter_mut().zip(m.joints.iter()) {
            *j = *q;
        }
        let t = S::to_wire(&m.target, &m.target_velocity);
        Self {
            version: PROTOCOL_VERSION,
            flags: header.flags,
            seq: header.seq,
            session: header.session,
            scenario_hash: header.scenario_hash,
            arm_hash: header.arm_hash,
            plant_time_ns: header.plant_time_ns,
            period_ns: header.period_ns,
            sim_time: m.t,
            dt: header.dt,
            delay: header.delay,
            platform: header.platform,
            hold_periods: header.hold_periods,
            joint_count: count_u32(N),
            space: S::CODE,
            base: [m.base.x, m.base.y, m.base.theta],
            steering: m.steering,
            target_position: t.position,
            target_rotation: t.rotation,
            target_yaw: t.yaw,
            target_twist: t.twist,
            joints,
        }
    }

    /// The target's fields.
    pub fn target(&self) -> WireTarget {
        WireTarget {
            position: self.target_position,
            rotation: self.target_rotation,
            yaw: self.target_yaw,
            twist: self.target_twist,
        }
    }

    /// The measurement for a controller of `N` joints tracking a target in `S`.
    ///
    /// # Errors
    /// [`WireError::JointCount`] if `joint_count` is not `N`, [`WireError::Changed`] if
    /// `space` is not `S`'s, or the target's [`WireSpace::from_wire`] error.
    pub fn read<const N: usize, S: WireSpace>(&self) -> Result<Measurement<f64, N, S>, WireError> {
        if self.joint_count != count_u32(N) {
            return Err(WireError::JointCount(self.joint_count));
        }
        if self.space != S::CODE {
            return Err(WireError::Changed);
        }
        let (target, target_velocity) = S::from_wire(&self.target())?;
        Ok(Measurement {
            t: self.sim_time,
            base: Pose::new(self.base[0], self.base[1], self.base[2]),
            steering: self.steering,
            joints: SVector::<f64, N>::from_fn(|i, _| self.joints[i]),
            target,
            target_velocity,
        })
    }

    /// The measurement for a controller of `N` joints and a planar target (`None` if the
    /// message does not give one: [`read`](Self::read)).
    pub fn measurement<const N: usize>(&self) -> Option<Measurement<f64, N>> {
        self.read::<N, Planar>().ok()
    }

    /// Whether a flag bit is set.
    pub fn has(&self, flag: u32) -> bool {
        self.flags & flag != 0
    }

    /// The message as bytes, little-endian, in the documented layout (the in-memory
    /// layout: no padding, checked by `zerocopy` at compile time).
    pub fn to_bytes(&self) -> [u8; MEASUREMENT_SIZE] {
        zerocopy::transmute!(*self)
    }

    /// The inverse of [`MeasurementMsg::to_bytes`].
    pub fn from_bytes(b: &[u8; MEASUREMENT_SIZE]) -> Self {
        zerocopy::transmute!(*b)
    }
}

/// The header fields of a measurement besides the measured values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeasurementHeader {
    /// Period number.
    pub seq: u64,
    /// [`flags`](super::flags) bits.
    pub flags: u32,
    /// Session id.
    pub session: u64,
    /// Scenario hash.
    pub scenario_hash: u64,
    /// Arm hash.
    pub arm_hash: u64,
    /// Measurement time (ns).
    pub plant_time_ns: u64,
    /// Period (ns), 0 in lockstep.
    pub period_ns: u64,
    /// Hold (s).
    pub dt: f64,
    /// Expected delay of the answer (s).
    pub delay: f64,
    /// [`platform`](super::platform) code.
    pub platform: u32,
    /// Hold limit (periods).
    pub hold_periods: u32,
}

/// What the law logged for one step (carried back for the plant's `timeseries.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoggedDiagnostics {
    /// `‖e_p‖`.
    pub ep_norm: f64,
    /// `h_s`.
    pub h_s: f64,
    /// `Ψ`.
    pub psi: f64,
    /// Saturation factor.
    pub saturation: f64,
    /// `α̇`.
    pub alpha_rate: [f64; 2],
    /// The joint guard's factor.
    pub joint_scale: f64,
    /// Which acceleration limits acted ([`limits`](super::limits) bits).
    pub limits: u32,
}

impl LoggedDiagnostics {
    /// No diagnostics (a refusal).
    pub const NONE: Self = Self {
        ep_norm: f64::NAN,
        h_s: f64::NAN,
        psi: f64::NAN,
        saturation: f64::NAN,
        alpha_rate: [f64::NAN; 2],
        joint_scale: f64::NAN,
        limits: 0,
    };

    /// The diagnostics of a step that found nothing to do (benchmarks and tests of the
    /// transport): no error, no saturation, the joint guard idle.
    pub const IDLE: Self = Self {
        ep_norm: 0.0,
        h_s: 0.0,
        psi: 1.0,
        saturation: 1.0,
        alpha_rate: [0.0; 2],
        joint_scale: 1.0,
        limits: 0,
    };
}

/// The header fields of a command besides the ids copied from the measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandHeader {
    /// The controller's identity.
    pub identity: ControllerIdentity,
    /// [`flags::NOTIFIES`](super::flags::NOTIFIES) or 0.
    pub flags: u32,
    /// Receipt of the measurement (ns, controller's clock).
    pub received_ns: u64,
    /// Skipped measurements since the previous answer.
    pub skipped: u32,
    /// The delay the law predicted over (s).
    pub delay: f64,
}

impl CommandMsg {
    /// The answer to `meas`: a command of `N` joints, its status and diagnostics, and timing.
    ///
    /// # Panics
    /// At compile time if `N > MAX_JOINTS`.
    pub fn answer<const N: usize>(
        meas: &MeasurementMsg,
        header: &CommandHeader,
        command: &Command<f64, N>,
        error: Option<StepError>,
        diag: &LoggedDiagnostics,
    ) -> Self {
        const { assert!(N <= MAX_JOINTS) };
        let mut joints = [0.0; MAX_JOINTS];
        for (j, u) in joints.iter_mut().zip(command.joints.iter()) {
            *j = *u;
        }
        let p = &command.platform;
        Self {
            version: PROTOCOL_VERSION,
            status: encode_status(error),
            seq: meas.seq,
            session: meas.session,
            plant_time_ns: meas.plant_time_ns,
            compute_ns: 0,
            received_ns: header.received_ns,
            skipped: header.skipped,
            joint_count: count_u32(N),
            flags: header.flags,
            platform: header.identity.platform,
            scenario_hash: header.identity.scenario_hash,
            arm_hash: header.identity.arm_hash,
            space: header.identity.space,
            limits: diag.limits,
            delay: header.delay,
            v: p.v,
            v_lat: p.v_lat,
            omega: p.omega,
            v_xi: p.v_xi,
            joints,
            ep_norm: diag.ep_norm,
            h_s: diag.h_s,
            psi: diag.psi,
            saturation: diag.saturation,
            alpha_rate: diag.alpha_rate,
            joint_scale: diag.joint_scale,
        }
    }

    /// The refusal of `meas`: every velocity zero, `status` the refusal's code.
    pub fn refusal<const N: usize>(meas: &MeasurementMsg, header: &CommandHeader, why: &Refusal) -> Self {
        let zero = Command::<f64, N>::zero();
        Self { status: why.code(), ..Self::answer(meas, header, &zero, None, &LoggedDiagnostics::NONE) }
    }

    /// The command for `N` joints (call after [`check_command`](super::check_command)).
    pub fn command<const N: usize>(&self) -> Command<f64, N> {
        Command {
            platform: PlatformCommand { v: self.v, v_lat: self.v_lat, omega: self.omega, v_xi: self.v_xi },
            joints: SVector::<f64, N>::from_fn(|i, _| if i < MAX_JOINTS { self.joints[i] } else { 0.0 }),
        }
    }

    /// The logged diagnostics.
    pub fn diagnostics(&self) -> LoggedDiagnostics {
        LoggedDiagnostics {
            ep_norm: self.ep_norm,
            h_s: self.h_s,
            psi: self.psi,
            saturation: self.saturation,
            alpha_rate: self.alpha_rate,
            joint_scale: self.joint_scale,
            limits: self.limits,
        }
    }

    /// Whether a flag bit is set.
    pub fn has(&self, flag: u32) -> bool {
        self.flags & flag != 0
    }

    /// The message as bytes, little-endian, in the documented layout.
    pub fn to_bytes(&self) -> [u8; COMMAND_SIZE] {
        zerocopy::transmute!(*self)
    }

    /// The inverse of [`CommandMsg::to_bytes`].
    pub fn from_bytes(b: &[u8; COMMAND_SIZE]) -> Self {
        zerocopy::transmute!(*b)
    }
}
