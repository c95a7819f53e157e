//! Builds the plant of a scenario.

use std::path::PathBuf;

use companion_core::nalgebra::{SVector, Vector2};
use companion_core::{Platform, PlatformKind, Pose, Rpr};
use companion_plant::{
    Imperfections, InitialConditions, Noise, Plant, PlantConfig, PlantError, Trajectory, TrajectoryError,
};

use crate::domain::controller::JOINTS;
use crate::domain::scenario::{Scenario, Target};

/// Why the plant of a scenario could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PlantSetupError {
    /// The target file cannot be read or breaks a rule.
    #[error("target file {}", path.display())]
    TargetFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: TrajectoryError,
    },
    /// The target file's start (`r_bd(0)`, `q(0)`) is not one.
    #[error("target file")]
    Start(#[source] TrajectoryError),
    /// A plant parameter breaks a rule.
    #[error("plant parameters")]
    Plant(#[source] PlantError),
}

/// The plant of `s`: platform, imperfections, target and initial conditions — the
/// scenario's own start if it has one, else the target's (`r_bd(0)`, `q(0)`).
///
/// The car's steering starts at `ξ_f(α(0))` unless the start says otherwise: §5 derives the
/// companion frame's kinematics (60) for `ξ = ξ_f(α)` ("let us therefore assume from now on
/// that ξ − ξ_f(α) is exactly equal to zero"), and the steering law (59) only keeps it there.
/// With `α(0) = 0` and straight wheels the two would differ by `ε η₁ cos³θ_f(0)` at the start.
///
/// # Errors
/// A bad target file or plant parameter, with the reason.
pub fn build(s: &Scenario) -> Result<Plant<Rpr<f64>, JOINTS>, PlantSetupError> {
    let trajectory = match &s.target {
        Target::Paper(t) => Trajectory::from(*t),
        Target::File(path) => Trajectory::load(path)
            .map_err(|source| PlantSetupError::TargetFile { path: path.clone(), source })?,
    };
    let mut initial = match &s.start {
        Some(st) => InitialConditions::with_relative_target(
            Pose::identity(),
            Pose::new(st.target[0], st.target[1], st.target[2]),
            SVector::<f64, JOINTS>::from(st.joints),
        ),
        None => trajectory.initial_conditions().map_err(PlantSetupError::Start)?,
    };
    if s.controller.platform == PlatformKind::Car {
        initial.steering = match s.start.and_then(|st| st.steering) {
            Some(xi) => xi,
            None => matched_steering(s),
        };
    }
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
    Plant::new(config, Rpr::paper(), initial, trajectory).map_err(PlantSetupError::Plant)
}

/// `ξ_f(α(0))` (1/m) of the scenario's car: the steering its transverse function prescribes
/// at the controller's initial `α`.
pub fn matched_steering(s: &Scenario) -> f64 {
    let c = &s.controller;
    let alpha = Vector2::new(c.initial_alpha[0], c.initial_alpha[1]);
    c.car::<f64>().companion(&alpha).map_or(0.0, |f| f.xi_f)
}

#[cfg(test)]
mod tests {
    use companion_core::{PaperRun, PlatformKind};
    use companion_plant::PaperTrajectory;

    use super::*;
    use crate::domain::scenario::Start;

    #[test]
    fn the_cars_steering_starts_where_its_transverse_function_says() {
        let b = || Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Car);
        let s = b().build().unwrap();
        let xi_f = s.controller.car::<f64>().companion(&Vector2::zeros()).unwrap().xi_f;
        assert!(xi_f.abs() > 0.1, "ξ_f(0) = {xi_f}: the test needs a function that steers at α = 0");
        assert_eq!(build(&s).unwrap().truth().steering, xi_f);
        // At α₁ = π/2, f̄₂ = ε η₁ cos α₁ vanishes: straight wheels.
        let s = b().initial_alpha([core::f64::consts::FRAC_PI_2, 0.3]).build().unwrap();
        assert!(build(&s).unwrap().truth().steering.abs() < 1e-12);
        // A start that gives ξ(0) has it.
        let start = Start { target: [2.0, 0.5, 0.1], joints: [0.1, 0.3, -0.1], steering: Some(0.25) };
        let s = b().start(start).build().unwrap();
        let plant = build(&s).unwrap();
        let x = plant.truth();
        assert_eq!(x.steering, 0.25);
        assert_eq!((x.target.x, x.target.y, x.target.theta), (2.0, 0.5, 0.1));
        assert_eq!(x.joints[2], -0.1);
        // Other platforms have no steering.
        let s = Scenario::builder(PaperTrajectory::One, PaperRun::A, PlatformKind::Unicycle).build().unwrap();
        assert_eq!(build(&s).unwrap().truth().steering, 0.0);
        // A start that is not finite is refused when the scenario is built.
        let bad = Start { target: [f64::NAN, 0.0, 0.0], ..start };
        assert!(b().start(bad).build().is_err());
    }
}
