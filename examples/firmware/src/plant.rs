//! The stub plant: a unicycle platform carrying the RPR arm, integrated exactly over one
//! period under the held command, and the paper's trajectory 1 for the target.

use companion_core::nalgebra::Vector3;
use companion_core::{wrap_angle, Pose, Real};

use crate::robot::{Cmd, JOINTS};

/// The plant's state: platform pose and joint positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantState {
    /// Platform position (m).
    pub x: f32,
    /// Platform position (m).
    pub y: f32,
    /// Platform heading (rad).
    pub theta: f32,
    /// Joint positions (rad, m, rad).
    pub q: [f32; JOINTS],
}

impl PlantState {
    /// The paper's initial state for trajectory 1: platform at the origin, heading 0,
    /// `q(0) = (0, 0.35, 0)`.
    pub const PAPER: Self = Self { x: 0.0, y: 0.0, theta: 0.0, q: [0.0, 0.35, 0.0] };

    /// Advances by `h` seconds under `cmd` held (zero-order hold). The unicycle's arc is
    /// integrated in closed form: with `a = ωh/2`, the displacement is
    /// `v h (sin a / a) (cos(θ + a), sin(θ + a))` — exact for any `ω`, and well conditioned
    /// as `ω → 0`. The joints are integrators.
    pub fn advance(&mut self, cmd: &Cmd, h: f32) {
        let v = cmd.platform.v;
        let a = 0.5 * cmd.platform.omega * h;
        // |a| < 1e-3: the series, whose next term (a⁴/120) is below f32 resolution.
        let sinc = if a * a < 1e-6 { 1.0 - a * a / 6.0 } else { a.sincos().0 / a };
        let (s, c) = (self.theta + a).sincos();
        let d = v * h * sinc;
        self.x += d * c;
        self.y += d * s;
        self.theta = wrap_angle(self.theta + 2.0 * a);
        for (q, u) in self.q.iter_mut().zip(cmd.joints.iter()) {
            *q += u * h;
        }
    }
}

/// The target on the paper's trajectory 1 at `t` (s): a circle of radius 0.1 m, period 4 s,
/// fixed heading, from `(2.6, 1, 0)`; `u_d(t) = −(π/20)(sin(πt/2), cos(πt/2), 0)` and so
/// `r_d(t) = (2.6 + (cos(πt/2) − 1)/10, 1 − sin(πt/2)/10, 0)`.
pub fn trajectory_1(t: f32) -> (Pose<f32>, Vector3<f32>) {
    let w = 0.5 * core::f32::consts::PI;
    let (s, c) = (w * t).sincos();
    let speed = core::f32::consts::PI / 20.0;
    (Pose::new(2.6 + 0.1 * (c - 1.0), 1.0 - 0.1 * s, 0.0), Vector3::new(-speed * s, -speed * c, 0.0))
}
