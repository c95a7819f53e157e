//! `companion.Plant`: the simulator's planar plant (companion-plant, built as `companion sim`
//! builds it), so that a law can be stepped in a loop written in Python.

use std::path::PathBuf;

use companion_core::nalgebra::SVector;
use companion_core::{Command, PlatformCommand, Pose, Rpr};
use companion_plant::{PaperTrajectory, Plant as CorePlant, Simulated};
use companion_runtime::domain::controller::JOINTS;
use companion_runtime::domain::scenario::{Options, Target};
use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::runtime_error;
use crate::law::{config_file, parse_choice, parse_platform};
use crate::measurement::Measurement;

/// The planar plant of `companion sim` (the RPR arm on a platform, the target on its
/// trajectory, RK4 at a fixed step), with the same options and `--config` `[plant]` table.
#[pyclass(module = "companion")]
#[derive(Debug)]
pub struct Plant {
    plant: CorePlant<Rpr<f64>, JOINTS>,
    star: Pose<f64>,
}

#[pymethods]
impl Plant {
    /// The plant `companion sim --trajectory T --choice C --platform P` would build (the
    /// choice and platform set the start and the platform's kinematics; `target_file`
    /// replaces the trajectory; the rest as the flags of the same name).
    #[new]
    #[pyo3(signature = (trajectory=1, choice="a", platform="unicycle", *, config=None, target_file=None,
        actuator_lag=None, noise=false, wheel_scale_error=None, seed=1))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        trajectory: u8,
        choice: &str,
        platform: &str,
        config: Option<PathBuf>,
        target_file: Option<PathBuf>,
        actuator_lag: Option<f64>,
        noise: bool,
        wheel_scale_error: Option<f64>,
        seed: u64,
    ) -> PyResult<Self> {
        let target = match (target_file, trajectory) {
            (Some(p), _) => Target::File(p),
            (None, 1) => Target::Paper(PaperTrajectory::One),
            (None, 2) => Target::Paper(PaperTrajectory::Two),
            _ => return Err(PyValueError::new_err(format!("trajectory must be 1 or 2, got {trajectory}"))),
        };
        let opts = Options { actuator_lag, noise, wheel_scale_error, seed, ..Options::default() };
        let file = config_file(py, config.as_ref())?;
        let b = opts.builder(file, target, parse_choice(choice)?, parse_platform(platform)?, 120.0);
        let err = |e: anyhow::Error| runtime_error(py, &e);
        let s = b.build().map_err(|e| err(e.into()))?;
        let plant = companion_runtime::run::sim::build_plant(&s).map_err(|e| err(e.into()))?;
        let star = s.controller.params::<f64>().primary.target_in_effector;
        Ok(Self { plant, star })
    }

    /// What the controller measures now (with the plant's noise, if any).
    fn measure(&self) -> Measurement {
        row(&self.plant.measure())
    }

    /// The true state (no noise), as a measurement.
    fn truth(&self) -> Measurement {
        let x = self.plant.truth();
        row(&companion_core::Measurement {
            t: x.t,
            base: x.base,
            steering: x.steering,
            joints: x.joints,
            target: x.target,
            target_velocity: x.target_velocity,
        })
    }

    /// One RK4 step of `dt` seconds with `command` held: `[v, v_lat, ω, v_ξ, u_q1, u_q2, u_q3]`
    /// (m/s, m/s, rad/s, 1/(m·s), rad/s, m/s, rad/s), e.g. `Output.command`.
    ///
    /// Raises `ValueError` for a non-finite command or a `dt` other than the first step's.
    fn advance(&mut self, command: PyReadonlyArray1<'_, f64>, dt: f64) -> PyResult<()> {
        let c = command.as_slice()?;
        if c.len() != 4 + JOINTS {
            return Err(PyValueError::new_err(format!(
                "a command has {} numbers, got {}",
                4 + JOINTS,
                c.len()
            )));
        }
        let command = Command {
            platform: PlatformCommand { v: c[0], v_lat: c[1], omega: c[2], v_xi: c[3] },
            joints: SVector::<f64, JOINTS>::new(c[4], c[5], c[6]),
        };
        self.plant.try_advance(&command, dt).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The plant's time (s).
    #[getter]
    fn t(&self) -> f64 {
        self.plant.time()
    }

    /// The true tracking error ‖e_p‖ of eq. (42) from the exact state (m and rad mixed).
    #[getter]
    fn ep_norm(&self) -> f64 {
        self.plant.tracking_error(&self.star).norm()
    }
}

fn row(m: &companion_core::Measurement<f64, JOINTS>) -> Measurement {
    let mut values = vec![m.t, m.base.x, m.base.y, m.base.theta, m.steering];
    values.extend(m.joints.iter());
    values.extend([m.target.x, m.target.y, m.target.theta]);
    values.extend(m.target_velocity.iter());
    Measurement { values, joints: JOINTS, spatial: false }
}
