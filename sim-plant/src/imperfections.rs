//! An imperfect plant, on request: actuator lag, measurement noise, a wheel-speed scale
//! error. Off by default ([`Imperfections::default`] is the perfect plant of the paper).

use crate::error::{PlantError, Rule};

/// Gaussian measurement noise: one standard deviation per kind of quantity. Applied by
/// [`Plant::measure`](crate::Plant::measure) to what the controller sees, never to the
/// true state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Noise {
    /// σ of the platform's and the target's `x`, `y` (m).
    pub position: f64,
    /// σ of the platform's and the target's heading `θ` (rad).
    pub angle: f64,
    /// σ of each joint position (rad for revolute joints, m for prismatic ones).
    pub joints: f64,
    /// σ of the car's steering state `ξ = tan φ / ℓ` (1/m) (other platforms' controllers
    /// ignore `ξ`).
    pub steering: f64,
}

impl Noise {
    /// A noise level typical of a wheeled robot localised by a motion-capture system or a
    /// good lidar map, with joint encoders: 2 mm, 0.005 rad (0.3°), 0.001 rad or m on the
    /// joints, 0.005 1/m on the steering state.
    pub fn typical() -> Self {
        Self { position: 0.002, angle: 0.005, joints: 0.001, steering: 0.005 }
    }

    fn validate(&self) -> Result<(), PlantError> {
        for (param, value) in [
            ("noise.position", self.position),
            ("noise.angle", self.angle),
            ("noise.joints", self.joints),
            ("noise.steering", self.steering),
        ] {
            PlantError::check_finite(param, value)?;
            if value < 0.0 {
                return Err(PlantError::Invalid { param, rule: Rule::Negative, value });
            }
        }
        Ok(())
    }
}

/// The ways the simulated robot differs from the model the controller assumes. The
/// default is the perfect plant: no lag, no noise, no scale error.
///
/// # Random numbers
///
/// The noise comes from [`rand::rngs::ChaCha12Rng`] (from the `chacha20` crate), seeded by
/// [`Imperfections::seed`] through `SeedableRng::seed_from_u64`. Not `StdRng`: rand
/// documents `StdRng` as *non-portable* (its algorithm may change in any release), whereas
/// the ChaCha stream is fixed by its specification, so a seed gives the same numbers on
/// every machine and every version. The noise of step `n` is drawn from ChaCha stream
/// number `n` (`set_stream(n)`, position 0), so it depends only on the seed and the step:
/// calling [`Plant::measure`](crate::Plant::measure) twice in a step gives the same
/// measurement, and a replay that skips measurements still gets the same noise later.
///
/// Gaussian samples are made here by the Box–Muller transform from the generator's
/// uniform numbers, with `ln`, `sqrt`, `sin`, `cos` from the pinned `libm`. Not
/// `rand_distr::StandardNormal`: its ziggurat calls `exp`/`ln` through `num-traits`, which
/// switches to the platform's math library whenever any crate in the build enables
/// `num-traits/std` (proptest does, in test builds), so a test binary and the runtime's
/// plant process could disagree in the last bit of rare samples. Here they cannot.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Imperfections {
    /// First-order lag of every actuator, time constant `τ > 0` (s): each applied velocity
    /// `a` follows its command `c` by `ȧ = (c − a)/τ`, starting from rest; integrated
    /// inside RK4 as extra states. `None`: the command is applied at once.
    pub actuator_lag: Option<f64>,
    /// Measurement noise; `None`: the controller measures the true state exactly.
    pub noise: Option<Noise>,
    /// Wheel-speed scale error `e > −1` (dimensionless): the platform's actual forward and
    /// lateral speeds are `(1 + e)` times the (lagged) commanded ones (as from a wrong
    /// wheel radius in the odometry). Angular speeds `ω` and `v_ξ` are not scaled; the car's
    /// yaw rate `v ξ` is, through `v`.
    pub wheel_scale_error: f64,
    /// Seed of the noise generator (see [Random numbers](Self#random-numbers)).
    pub seed: u64,
}

impl Imperfections {
    /// The perfect plant (the paper's).
    pub fn perfect() -> Self {
        Self::default()
    }

    /// A plausible real robot: 50 ms actuator lag, [`Noise::typical`], wheels 2 % faster
    /// than the controller believes, noise seeded by `seed`.
    pub fn typical(seed: u64) -> Self {
        Self { actuator_lag: Some(0.05), noise: Some(Noise::typical()), wheel_scale_error: 0.02, seed }
    }

    /// Whether this is the perfect plant.
    pub fn is_perfect(&self) -> bool {
        self.actuator_lag.is_none() && self.noise.is_none() && self.wheel_scale_error == 0.0
    }

    pub(crate) fn validate(&self) -> Result<(), PlantError> {
        if let Some(tau) = self.actuator_lag {
            PlantError::check_finite("actuator_lag", tau)?;
            if tau <= 0.0 {
                return Err(PlantError::Invalid {
                    param: "actuator_lag",
                    rule: Rule::NotPositive,
                    value: tau,
                });
            }
        }
        if let Some(noise) = &self.noise {
            noise.validate()?;
        }
        let e = self.wheel_scale_error;
        PlantError::check_finite("wheel_scale_error", e)?;
        if e <= -1.0 {
            return Err(PlantError::Invalid {
                param: "wheel_scale_error",
                rule: Rule::NotAboveMinusOne,
                value: e,
            });
        }
        Ok(())
    }
}
