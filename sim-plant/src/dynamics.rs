//! The equations of motion and one RK4 step under a zero-order-hold command.
//!
//! ```text
//! platform   ṙ_b = R̄(θ_b) u_b                                  (eq. 3)
//!            unicycle  u_b = ((1+e) v, 0, ω)
//!            car       u_b = ((1+e) v, 0, (1+e) v ξ),  ξ̇ = v_ξ     (eq. 55)
//!            omni      u_b = ((1+e) v, (1+e) v_lat, ω)
//! arm        q̇ = u_q
//! target     ṙ_d = R̄(θ_d) u_d(t)
//! lag        ȧ = (c − a)/τ   for every commanded velocity c   (only with actuator lag)
//! ```
//!
//! With lag, the platform and joint velocities used above are the lag states `a`;
//! without, the command itself. Angles are integrated as they are, never wrapped.

use companion_core::nalgebra::{SVector, Vector3, Vector4};
use companion_core::{Command, PlatformCommand, PlatformKind};

use crate::trajectory::{Piece, Trajectory};

/// The integrated state. The platform command is packed as `(v, v_lat, ω, v_ξ)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Continuous<const N: usize> {
    /// `r_b = (x, y, θ)` (m, m, rad).
    pub base: Vector3<f64>,
    /// `ξ` (1/m).
    pub steering: f64,
    /// `q`.
    pub joints: SVector<f64, N>,
    /// `r_d = (x, y, θ)` (m, m, rad).
    pub target: Vector3<f64>,
    /// Lag states of `(v, v_lat, ω, v_ξ)`.
    pub platform_lag: Vector4<f64>,
    /// Lag states of `u_q`.
    pub joint_lag: SVector<f64, N>,
}

impl<const N: usize> Continuous<N> {
    /// `self + h · d`.
    fn add_scaled(&self, h: f64, d: &Self) -> Self {
        Self {
            base: self.base + d.base * h,
            steering: self.steering + h * d.steering,
            joints: self.joints + d.joints * h,
            target: self.target + d.target * h,
            platform_lag: self.platform_lag + d.platform_lag * h,
            joint_lag: self.joint_lag + d.joint_lag * h,
        }
    }
}

/// `(v, v_lat, ω, v_ξ)` of a platform command.
pub(crate) fn pack(p: &PlatformCommand<f64>) -> Vector4<f64> {
    Vector4::new(p.v, p.v_lat, p.omega, p.v_xi)
}

/// `R̄(θ) u`, eq. (3).
fn pose_rate(theta: f64, u: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = libm::sincos(theta);
    Vector3::new(c * u[0] - s * u[1], s * u[0] + c * u[1], u[2])
}

/// The fixed parameters of the equations of motion.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Model<'a> {
    pub kind: PlatformKind,
    /// `1 + e`.
    pub wheel_scale: f64,
    /// `τ` (s).
    pub lag: Option<f64>,
    /// Largest `|ξ|` (1/m).
    pub steering_limit: Option<f64>,
    pub trajectory: &'a Trajectory,
}

impl Model<'_> {
    /// The platform's actual body velocity `u_b` and steering rate `ξ̇` for velocities
    /// `p = (v, v_lat, ω, v_ξ)` delivered by the actuators, at steering `ξ`.
    fn platform(&self, p: &Vector4<f64>, xi: f64) -> (Vector3<f64>, f64) {
        let v = self.wheel_scale * p[0];
        match self.kind {
            PlatformKind::Unicycle => (Vector3::new(v, 0.0, p[2]), 0.0),
            PlatformKind::Car => (Vector3::new(v, 0.0, v * xi), self.gated_steering_rate(p[3], xi)),
            PlatformKind::Omni => (Vector3::new(v, self.wheel_scale * p[1], p[2]), 0.0),
        }
    }

    /// `v_ξ`, or 0 when the wheels are at their end stop and `v_ξ` pushes beyond it.
    fn gated_steering_rate(&self, v_xi: f64, xi: f64) -> f64 {
        match self.steering_limit {
            Some(l) if (xi >= l && v_xi > 0.0) || (xi <= -l && v_xi < 0.0) => 0.0,
            _ => v_xi,
        }
    }

    /// The velocities actually applied, in the form of a command: the platform's actual
    /// `(v, v_lat, ω)` (for the car `ω = v ξ`, as in `PlatformCommand`), `v_ξ`, and `u_q`;
    /// fields a platform does not have are zero.
    pub fn applied<const N: usize>(&self, x: &Continuous<N>, command: &Command<f64, N>) -> Command<f64, N> {
        let (p, joints) = match self.lag {
            Some(_) => (x.platform_lag, x.joint_lag),
            None => (pack(&command.platform), command.joints),
        };
        let (u_b, xi_dot) = self.platform(&p, x.steering);
        Command {
            platform: PlatformCommand { v: u_b[0], v_lat: u_b[1], omega: u_b[2], v_xi: xi_dot },
            joints,
        }
    }

    /// `ẋ = F(t, x)` under the held command `(c, c_q)`.
    fn derivative<const N: usize>(
        &self,
        piece: &Piece,
        t: f64,
        x: &Continuous<N>,
        c: &Vector4<f64>,
        c_q: &SVector<f64, N>,
    ) -> Continuous<N> {
        let (p, p_q, lag_rate, joint_lag_rate) = match self.lag {
            Some(tau) => (x.platform_lag, x.joint_lag, (c - x.platform_lag) / tau, (c_q - x.joint_lag) / tau),
            None => (*c, *c_q, Vector4::zeros(), SVector::zeros()),
        };
        let (u_b, steering) = self.platform(&p, x.steering);
        let u_d = piece.velocity(t);
        Continuous {
            base: pose_rate(x.base[2], &u_b),
            steering,
            joints: p_q,
            target: pose_rate(x.target[2], &u_d),
            platform_lag: lag_rate,
            joint_lag: joint_lag_rate,
        }
    }

    /// One classical RK4 step from `t0` to `t1 = t0 + h` with the command held. The target
    /// velocity is evaluated at `t0`, `t0 + h/2` and `t1`, on the smooth piece of `u_d`
    /// that contains the step's midpoint (so a jump of `u_d` on a step's edge is taken
    /// exactly). A steering limit, if any, is enforced exactly at the end of the step
    /// (clamp).
    pub fn rk4<const N: usize>(
        &self,
        t0: f64,
        t1: f64,
        h: f64,
        x: &Continuous<N>,
        command: &Command<f64, N>,
    ) -> Continuous<N> {
        let c = pack(&command.platform);
        let c_q = command.joints;
        let half = 0.5 * h;
        let t_mid = t0 + half;
        let piece = self.trajectory.piece(t_mid);
        let k1 = self.derivative(&piece, t0, x, &c, &c_q);
        let k2 = self.derivative(&piece, t_mid, &x.add_scaled(half, &k1), &c, &c_q);
        let k3 = self.derivative(&piece, t_mid, &x.add_scaled(half, &k2), &c, &c_q);
        let k4 = self.derivative(&piece, t1, &x.add_scaled(h, &k3), &c, &c_q);
        let sum = k1.add_scaled(2.0, &k2).add_scaled(2.0, &k3).add_scaled(1.0, &k4);
        let mut next = x.add_scaled(h / 6.0, &sum);
        if let (PlatformKind::Car, Some(l)) = (self.kind, self.steering_limit) {
            next.steering = next.steering.clamp(-l, l);
        }
        next
    }
}
