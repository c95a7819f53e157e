//! The start of a session: what the plant announces in every measurement
//! ([`Announcement`]), what the controller is ([`ControllerIdentity`]) and why it refuses a
//! plant ([`Refusal`], sent as a command's `status`).

use super::canonical;
use super::layout::{flags, platform, CommandMsg, MeasurementMsg, PROTOCOL_VERSION};
use super::target;

/// What the plant announces in every measurement of a session: everything besides the
/// measured values that the commands depend on or that must match (constant within a
/// session).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Announcement {
    /// [`flags::ANNOUNCED`] bits: lockstep, notifies.
    pub flags: u32,
    /// [`platform`] code.
    pub platform: u32,
    /// Joints used.
    pub joint_count: u32,
    /// The target's [`target::space`] code.
    pub space: u32,
    /// Hold limit (periods).
    pub hold_periods: u32,
    /// How long each command is held (s).
    pub dt: f64,
    /// Publication period (ns); 0 in lockstep.
    pub period_ns: u64,
    /// Scenario hash; 0 = not checked.
    pub scenario_hash: u64,
    /// Arm hash; 0 = not checked.
    pub arm_hash: u64,
}

impl Announcement {
    /// The announcement a measurement carries.
    pub fn of(m: &MeasurementMsg) -> Self {
        Self {
            flags: m.flags & flags::ANNOUNCED,
            platform: m.platform,
            joint_count: m.joint_count,
            space: m.space,
            hold_periods: m.hold_periods,
            dt: m.dt,
            period_ns: m.period_ns,
            scenario_hash: m.scenario_hash,
            arm_hash: m.arm_hash,
        }
    }

    /// Lockstep: the plant waits for every command.
    pub fn lockstep(&self) -> bool {
        self.flags & flags::LOCKSTEP != 0
    }

    /// The plant notifies `measurement-ready` after each measurement.
    pub fn notifies(&self) -> bool {
        self.flags & flags::NOTIFIES != 0
    }

    /// Equal, with `dt` compared bit for bit.
    pub(super) fn same_as(&self, o: &Self) -> bool {
        Self { dt: 0.0, ..*self } == Self { dt: 0.0, ..*o } && self.dt.to_bits() == o.dt.to_bits()
    }
}

/// Why the controller refuses to serve a plant (sent as the `status` of a command, then the
/// controller exits). Each names the plant's and the controller's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refusal {
    /// The measurement's `version` is not [`PROTOCOL_VERSION`].
    Version {
        /// The plant's version.
        plant: u32,
    },
    /// Another joint count.
    JointCount {
        /// The plant's.
        plant: u32,
        /// The controller's.
        controller: u32,
    },
    /// Another platform.
    Platform {
        /// The plant's code.
        plant: u32,
        /// The controller's code.
        controller: u32,
    },
    /// Another scenario (both hashes non-zero and different).
    Scenario {
        /// The plant's hash.
        plant: u64,
        /// The controller's hash.
        controller: u64,
    },
    /// A `dt` the law does not admit (not finite, `≤ 0`, or above its `max_time_step`).
    Period {
        /// The plant's `dt` (s).
        dt: f64,
    },
    /// Another target space (a planar plant and a spatial controller, or the reverse).
    Space {
        /// The plant's [`target::space`] code.
        plant: u32,
        /// The controller's.
        controller: u32,
    },
    /// Another arm (both hashes non-zero and different).
    Arm {
        /// The plant's arm hash.
        plant: u64,
        /// The controller's.
        controller: u64,
    },
}

/// The refusal codes (`status` of a refusal command).
pub mod refusal {
    /// Another protocol version.
    pub const VERSION: u32 = 0x8001;
    /// Another joint count.
    pub const JOINT_COUNT: u32 = 0x8002;
    /// Another platform.
    pub const PLATFORM: u32 = 0x8003;
    /// Another scenario.
    pub const SCENARIO: u32 = 0x8004;
    /// A `dt` the law does not admit.
    pub const PERIOD: u32 = 0x8005;
    /// Another target space.
    pub const SPACE: u32 = 0x8006;
    /// Another arm.
    pub const ARM: u32 = 0x8007;

    /// Whether a `status` is a refusal.
    pub fn is_refusal(status: u32) -> bool {
        status & 0xff00 == 0x8000
    }
}

impl Refusal {
    /// The `status` code.
    pub fn code(&self) -> u32 {
        match self {
            Self::Version { .. } => refusal::VERSION,
            Self::JointCount { .. } => refusal::JOINT_COUNT,
            Self::Platform { .. } => refusal::PLATFORM,
            Self::Scenario { .. } => refusal::SCENARIO,
            Self::Period { .. } => refusal::PERIOD,
            Self::Space { .. } => refusal::SPACE,
            Self::Arm { .. } => refusal::ARM,
        }
    }

    /// What a plant learns from a refusal command `c` answering its measurement `m`.
    pub fn from_command(c: &CommandMsg, m: &MeasurementMsg) -> Option<Self> {
        Some(match c.status {
            refusal::VERSION => Self::Version { plant: m.version },
            refusal::JOINT_COUNT => Self::JointCount { plant: m.joint_count, controller: c.joint_count },
            refusal::PLATFORM => Self::Platform { plant: m.platform, controller: c.platform },
            refusal::SCENARIO => Self::Scenario { plant: m.scenario_hash, controller: c.scenario_hash },
            refusal::PERIOD => Self::Period { dt: m.dt },
            refusal::SPACE => Self::Space { plant: m.space, controller: c.space },
            refusal::ARM => Self::Arm { plant: m.arm_hash, controller: c.arm_hash },
            _ => return None,
        })
    }
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Version { plant } => write!(
                f,
                "protocol version mismatch: the plant speaks version {plant}, the controller version \
                 {PROTOCOL_VERSION}"
            ),
            Self::JointCount { plant, controller } => write!(
                f,
                "joint count mismatch: the plant has {plant} joints, the controller is built for {controller}"
            ),
            Self::Platform { plant, controller } => write!(
                f,
                "platform mismatch: the plant is {}, the controller is built for {}",
                platform::describe(*plant),
                platform::describe(*controller)
            ),
            Self::Scenario { plant, controller } => write!(
                f,
                "scenario mismatch: the plant's scenario hash is {plant:#018x}, the controller's {controller:#018x} \
                 (give both roles the same scenario flags, or send 0 to skip the check)"
            ),
            Self::Period { dt } => write!(
                f,
                "the controller does not admit the plant's dt = {dt} s (it must be positive, finite and at most \
                 the law's max_time_step)"
            ),
            Self::Space { plant, controller } => write!(
                f,
                "target space mismatch: the plant's target is {}, the controller's arm tracks a {} one",
                target::space::describe(*plant),
                target::space::describe(*controller)
            ),
            Self::Arm { plant, controller } => write!(
                f,
                "arm mismatch: the plant's arm is {}, the controller is built for {} (arm hashes differ; \
                 send 0 to skip the check)",
                canonical::describe_arm(*plant),
                canonical::describe_arm(*controller)
            ),
        }
    }
}

impl core::error::Error for Refusal {}

/// What the controller is and checks a plant against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerIdentity {
    /// Its [`platform`] code.
    pub platform: u32,
    /// Its joint count.
    pub joint_count: u32,
    /// Its target's [`target::space`] code.
    pub space: u32,
    /// Its arm's hash (0 = do not check).
    pub arm_hash: u64,
    /// Its scenario hash (0 = do not check).
    pub scenario_hash: u64,
    /// The largest `dt` its law admits (s).
    pub max_dt: f64,
}

impl ControllerIdentity {
    /// Checks the first measurement of a session: the plant's version and announcement.
    ///
    /// # Errors
    /// The first mismatch, as a [`Refusal`].
    pub fn admit(&self, m: &MeasurementMsg) -> Result<Announcement, Refusal> {
        if m.version != PROTOCOL_VERSION {
            return Err(Refusal::Version { plant: m.version });
        }
        if m.joint_count != self.joint_count {
            return Err(Refusal::JointCount { plant: m.joint_count, controller: self.joint_count });
        }
        if m.space != self.space {
            return Err(Refusal::Space { plant: m.space, controller: self.space });
        }
        if self.arm_hash != 0 && m.arm_hash != 0 && m.arm_hash != self.arm_hash {
            return Err(Refusal::Arm { plant: m.arm_hash, controller: self.arm_hash });
        }
        if m.platform != self.platform {
            return Err(Refusal::Platform { plant: m.platform, controller: self.platform });
        }
        if self.scenario_hash != 0 && m.scenario_hash != 0 && m.scenario_hash != self.scenario_hash {
            return Err(Refusal::Scenario { plant: m.scenario_hash, controller: self.scenario_hash });
        }
        if !(m.dt.is_finite() && m.dt > 0.0 && m.dt <= self.max_dt) {
            return Err(Refusal::Period { dt: m.dt });
        }
        Ok(Announcement::of(m))
    }
}
