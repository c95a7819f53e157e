//! The one place where this example meets hardware: the [`Robot`] trait. Put your drivers
//! behind it (encoders/odometry and joint sensors in [`Robot::measure`], motor drivers in
//! [`Robot::apply`]); the control task calls nothing else. [`StubRobot`] is the stand-in
//! that closes the loop on a simulated plant (see [`crate::plant`]).

use companion_core::nalgebra::SVector;
use companion_core::{Command, Measurement, Pose};
use rtic_sync::channel::{Receiver, Sender};

use crate::plant::{trajectory_1, PlantState};

/// Joints of the paper's arm (RPR).
pub const JOINTS: usize = 3;

/// The command the controller sends each period (`f32`, three joints).
pub type Cmd = Command<f32, JOINTS>;

/// What the controller reads each period.
pub type Meas = Measurement<f32, JOINTS>;

/// Capacity of the stub's channels (one message per period in each direction; one spare).
pub const DEPTH: usize = 2;

/// Sensors in, actuators out, called from the 1 kHz control interrupt (TIM2, the highest
/// priority): keep both short and non-blocking. A real implementation reads the latest
/// values its drivers hold (DMA buffers, encoder counters, the last camera fix of the
/// target) and writes set-points to the motor drivers; slow I/O belongs in lower-priority
/// tasks that refresh those values.
pub trait Robot {
    /// The measurement at time `t` (s since the first period): platform pose `(x, y, θ)`,
    /// steering (car-like platforms only), joint positions, the target's pose and body
    /// velocity.
    fn measure(&mut self, t: f32) -> Meas;

    /// Sends the command for the coming period: platform velocities `(v, v_lat, ω, v_ξ)`
    /// and joint velocities, to be held until the next call.
    fn apply(&mut self, cmd: &Cmd);
}

/// The stand-in robot: commands go to the stub plant task through one channel, the plant's
/// state comes back through another, the target follows the paper's trajectory 1 in
/// closed form.
#[derive(Debug)]
pub struct StubRobot {
    commands: Sender<'static, Cmd, DEPTH>,
    states: Receiver<'static, PlantState, DEPTH>,
    last: PlantState,
    /// Periods in which the plant had not delivered a new state (the previous one was used).
    pub stale: u32,
    /// Commands the plant task could not take (its queue was full).
    pub dropped: u32,
}

impl StubRobot {
    /// A stub robot talking to the plant task through these channel ends, starting from `initial`.
    pub fn new(
        commands: Sender<'static, Cmd, DEPTH>,
        states: Receiver<'static, PlantState, DEPTH>,
        initial: PlantState,
    ) -> Self {
        Self { commands, states, last: initial, stale: 0, dropped: 0 }
    }
}

impl Robot for StubRobot {
    fn measure(&mut self, t: f32) -> Meas {
        let mut fresh = false;
        while let Ok(s) = self.states.try_recv() {
            self.last = s;
            fresh = true;
        }
        if !fresh {
            self.stale += 1;
        }
        let (target, target_velocity) = trajectory_1(t);
        Measurement {
            t,
            base: Pose::new(self.last.x, self.last.y, self.last.theta),
            steering: 0.0,
            joints: SVector::<f32, JOINTS>::from(self.last.q),
            target,
            target_velocity,
        }
    }

    fn apply(&mut self, cmd: &Cmd) {
        if self.commands.try_send(*cmd).is_err() {
            self.dropped += 1;
        }
    }
}
