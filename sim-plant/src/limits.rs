//! Physical limits of a realistic robot, for runs that are not the paper's.
//!
//! The paper's simulations use no velocity limits
//! ([`VelocityLimits::unlimited`]); a real base cannot do 66 rad/s. The numbers below
//! describe a mid-size indoor mobile manipulator (a platform of about 0.6 m, a 0.5 m
//! wheelbase for the car-like version). They are a preset, not a claim about a particular
//! product: pass your robot's datasheet values instead when you have them.

use companion_core::VelocityLimits;

/// Wheelbase `ℓ` of the realistic car-like platform (m): the distance between its axles.
pub const REALISTIC_WHEELBASE: f64 = 0.5;

/// Largest steering angle `φ` of the realistic car-like platform: 35° (rad).
pub const REALISTIC_MAX_STEERING_ANGLE: f64 = 35.0 * core::f64::consts::PI / 180.0;

/// Velocity limits of a realistic robot, to be met by the controller's common saturation
/// factor (end of §3.4.2 of the paper):
///
/// | velocity | limit | why |
/// |---|---|---|
/// | forward `v₁` | 1.0 m/s | brisk walking pace, safe indoors near people |
/// | lateral `v₂` (omnidirectional) | 0.8 m/s | mecanum wheels are slower sideways |
/// | angular `ω` | 2.0 rad/s | about 115°/s, a typical differential-drive base |
/// | transverse-function `α̇ᵢ` | 10 rad/s | the companion frame's oscillation: 1.6 Hz |
/// | steering `v_ξ` (car-like) | 2.0 1/(m·s) | with `ℓ = 0.5 m`: `φ̇ = ℓ ξ̇ cos²φ ≤ 1 rad/s`, a steering servo's speed |
///
/// Not used in the paper's runs (they are unsaturated).
pub fn realistic_limits() -> VelocityLimits<f64> {
    VelocityLimits { forward: 1.0, lateral: 0.8, angular: 2.0, alpha_rate: 10.0, steering_rate: 2.0 }
}

/// The largest steering state `ξ = tan φ / ℓ` (1/m) of a car with largest steering angle
/// `max_angle` (rad, in `(0, π/2)`) and wheelbase `wheelbase` (m): the inverse of its
/// smallest turning radius.
pub fn steering_limit(max_angle: f64, wheelbase: f64) -> f64 {
    libm::tan(max_angle) / wheelbase
}

/// The realistic car's largest `|ξ|`: `tan 35° / 0.5 m ≈ 1.40 1/m` (a turning radius of
/// 0.71 m). Pass it as [`PlantConfig::steering_limit`](crate::PlantConfig::steering_limit)
/// to make the simulated wheels stop at their end stops.
pub fn realistic_steering_limit() -> f64 {
    steering_limit(REALISTIC_MAX_STEERING_ANGLE, REALISTIC_WHEELBASE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realistic_values_are_finite_positive_and_as_documented() {
        let l = realistic_limits();
        for v in [l.forward, l.lateral, l.angular, l.alpha_rate, l.steering_rate] {
            assert!(v.is_finite() && v > 0.0);
        }
        assert_eq!((l.forward, l.lateral, l.angular), (1.0, 0.8, 2.0));
        let xi = realistic_steering_limit();
        assert!((xi - 1.4004150).abs() < 1e-6, "{xi}");
        // φ̇ at straight wheels for the steering-rate limit is 1 rad/s.
        assert!((REALISTIC_WHEELBASE * l.steering_rate - 1.0).abs() < 1e-15);
    }
}
