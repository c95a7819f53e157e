//! Builds the plant of a scenario.

use anyhow::{Context, Result};
use companion_core::Rpr;
use companion_plant::{Imperfections, Noise, Plant, PlantConfig, Trajectory};

use crate::controller::JOINTS;
use crate::scenario::{Scenario, Target};

/// The plant of `s`: platform, imperfections, target and initial conditions.
///
/// # Errors
/// A bad target file or plant parameter, with the reason.
pub fn build(s: &Scenario) -> Result<Plant<Rpr<f64>, JOINTS>> {
    let trajectory = match &s.target {
        Target::Paper(t) => Trajectory::from(*t),
        Target::File(path) => {
            Trajectory::load(path).with_context(|| format!("target file {}", path.display()))?
        }
    };
    let initial = trajectory.initial_conditions().context("target file")?;
    let p = &s.plant;
    let imperfections = Imperfections {
        actuator_lag: p.actuator_lag,
        noise: p.noise.map(|n| Noise {
            position: n.position,
            angle: n.angle,
            joints: n.joints,
            steering: n.steering,
        }),
        wheel_scale_error: p.wheel_scale_error.unwrap_or(0.0),
        seed: p.seed.unwrap_or(1),
    };
    let config = PlantConfig::new(s.controller.platform).with_imperfections(imperfections);
    Plant::new(config, Rpr::paper(), initial, trajectory).context("plant parameters")
}
