//! `companion.simulate`: `companion sim`'s run (the runtime's own loop and files), its logged
//! rows as numpy arrays and its `summary.json` as a dict.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use companion_plant::PaperTrajectory;
use companion_runtime::domain::observe::Silent;
use companion_runtime::domain::record::verdict::DEFAULT_MAX_REJECTED;
use companion_runtime::domain::record::{Acceptance, Row};
use companion_runtime::domain::scenario::{Options, Target};
use companion_runtime::run::spatial::{SpatialRows, SpatialScenario, SpatialTargetChoice};
use numpy::ndarray::{Array1, Array2};
use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{runtime_error, sim_error, spatial_error};
use crate::law::{
    config_file, parse_choice, parse_discretisation, parse_limits, parse_platform, parse_scalar,
};

/// `sim`'s duration when none is given (s), as the CLI's.
const DEFAULT_DURATION: f64 = 120.0;

/// A folder of its own for a run whose files are not kept.
fn scratch_dir() -> PathBuf {
    static COUNT: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "companion-py-{}-{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Column `f` of every row as a numpy array.
fn column<'py, T: Copy + numpy::Element, R>(
    py: Python<'py>,
    rows: &[R],
    f: impl Fn(&R) -> T,
) -> Bound<'py, PyAny> {
    rows.iter().map(f).collect::<Array1<T>>().into_pyarray(py).into_any()
}

/// Columns `f` (`k` per row) of every row as an (n, k) array.
fn columns<'py, R>(py: Python<'py>, rows: &[R], k: usize, f: impl Fn(&R, usize) -> f64) -> Bound<'py, PyAny> {
    Array2::from_shape_fn((rows.len(), k), |(i, j)| f(&rows[i], j)).into_pyarray(py).into_any()
}

fn planar_timeseries<'py>(py: Python<'py>, rows: &[Row]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let pose = |p: &companion_core::Pose<f64>, j: usize| [p.x, p.y, p.theta][j];
    d.set_item("t", column(py, rows, |r| r.plant.t))?;
    d.set_item("base", columns(py, rows, 3, |r, j| pose(&r.plant.base, j)))?;
    d.set_item("steering", column(py, rows, |r| r.plant.steering))?;
    d.set_item("joints", columns(py, rows, 3, |r, j| r.plant.joints[j]))?;
    d.set_item("end_effector", columns(py, rows, 3, |r, j| pose(&r.plant.end_effector, j)))?;
    d.set_item("target", columns(py, rows, 3, |r, j| pose(&r.plant.target, j)))?;
    d.set_item("ep_norm", column(py, rows, |r| r.plant.ep_norm))?;
    d.set_item(
        "command",
        columns(py, rows, 7, |r, j| {
            let c = &r.report.command;
            let p = &c.platform;
            if j < 4 {
                [p.v, p.v_lat, p.omega, p.v_xi][j]
            } else {
                c.joints[j - 4]
            }
        }),
    )?;
    d.set_item("h_s", column(py, rows, |r| r.report.h_s))?;
    d.set_item("psi", column(py, rows, |r| r.report.psi))?;
    d.set_item("saturation", column(py, rows, |r| r.report.saturation))?;
    d.set_item("alpha_rate", columns(py, rows, 2, |r, j| r.report.alpha_rate[j]))?;
    d.set_item("joint_scale", column(py, rows, |r| r.report.joint_scale))?;
    d.set_item("status", rows.iter().map(Row::status).collect::<Vec<_>>())?;
    Ok(d)
}

fn spatial_timeseries<'py>(py: Python<'py>, rows: &SpatialRows) -> PyResult<Bound<'py, PyDict>> {
    match rows {
        SpatialRows::Six(r) => arm_timeseries(py, r),
        SpatialRows::Seven(r) => arm_timeseries(py, r),
        SpatialRows::Eight(r) => arm_timeseries(py, r),
    }
}

fn arm_timeseries<'py, const N: usize>(
    py: Python<'py>,
    rows: &[Row<companion_core::Spatial, N>],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let homogeneous = |p: &companion_core::Pose3<f64>, k: usize| {
        let (i, j) = (k / 4, k % 4);
        match (i, j) {
            (3, 3) => 1.0,
            (3, _) => 0.0,
            (_, 3) => p.translation[i],
            _ => p.rotation[(i, j)],
        }
    };
    type SpatialRow<const N: usize> = Row<companion_core::Spatial, N>;
    let pose4 =
        |py, f: &dyn Fn(&SpatialRow<N>) -> companion_core::Pose3<f64>| -> PyResult<Bound<'py, PyAny>> {
            let a = Array2::from_shape_fn((rows.len(), 16), |(i, k)| homogeneous(&f(&rows[i]), k));
            a.into_shape_with_order((rows.len(), 4, 4))
                .map(|a| a.into_pyarray(py).into_any())
                .map_err(|e| PyValueError::new_err(e.to_string()))
        };
    let pose = |p: &companion_core::Pose<f64>, j: usize| [p.x, p.y, p.theta][j];
    d.set_item("t", column(py, rows, |r| r.plant.t))?;
    d.set_item("base", columns(py, rows, 3, |r, j| pose(&r.plant.base, j)))?;
    d.set_item("steering", column(py, rows, |r| r.plant.steering))?;
    d.set_item("joints", columns(py, rows, N, |r, j| r.plant.joints[j]))?;
    d.set_item("end_effector", pose4(py, &|r| r.plant.end_effector)?)?;
    d.set_item("target", pose4(py, &|r| r.plant.target)?)?;
    d.set_item("target_twist", columns(py, rows, 6, |r, j| r.plant.target_velocity[j]))?;
    d.set_item("e_p", columns(py, rows, 6, |r, j| r.plant.e_p[j]))?;
    d.set_item("ep_norm", column(py, rows, |r| r.plant.ep_norm))?;
    d.set_item(
        "command",
        columns(py, rows, 4 + N, |r, j| {
            let c = &r.report.command;
            let p = &c.platform;
            if j < 4 {
                [p.v, p.v_lat, p.omega, p.v_xi][j]
            } else {
                c.joints[j - 4]
            }
        }),
    )?;
    d.set_item("h_s", column(py, rows, |r| r.report.h_s))?;
    d.set_item("saturation", column(py, rows, |r| r.report.saturation))?;
    d.set_item("joint_scale", column(py, rows, |r| r.report.joint_scale))?;
    d.set_item("status", rows.iter().map(Row::status).collect::<Vec<_>>())?;
    Ok(d)
}

fn json_dict<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// Runs `companion sim` with these options (each the flag of the same name; `arm` 'rpr' |
/// 'ur5' | 'panda' | an arm file) and returns `(timeseries, summary)`: the logged rows (every
/// `log_every` steps and the last) as a dict of numpy arrays, and `summary.json` as a dict
/// (its `trajectory_digest` is the CLI's for the same flags). The run's files
/// (`timeseries.csv`, `summary.json`, `scenario.json`) are written into `out` if given, else
/// into a temporary folder that is removed.
#[pyfunction]
#[pyo3(signature = (trajectory=1, choice="a", platform="unicycle", arm=None, *, dt=0.001, duration=None,
    scalar="f64", config=None, target_file=None, psi_rate_in_drift=false, explicit_rest_filter=false,
    discretisation=None, limits=None, actuator_lag=None, noise=false, wheel_scale_error=None, seed=1,
    log_every=10, delay=0.0, delay_compensation=true, max_rejected=DEFAULT_MAX_REJECTED, out=None))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    trajectory: u8,
    choice: &str,
    platform: &str,
    arm: Option<&Bound<'_, PyAny>>,
    dt: f64,
    duration: Option<f64>,
    scalar: &str,
    config: Option<PathBuf>,
    target_file: Option<PathBuf>,
    psi_rate_in_drift: bool,
    explicit_rest_filter: bool,
    discretisation: Option<String>,
    limits: Option<String>,
    actuator_lag: Option<f64>,
    noise: bool,
    wheel_scale_error: Option<f64>,
    seed: u64,
    log_every: u64,
    delay: f64,
    delay_compensation: bool,
    max_rejected: f64,
    out: Option<PathBuf>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let traj = match trajectory {
        1 => PaperTrajectory::One,
        2 => PaperTrajectory::Two,
        _ => return Err(PyValueError::new_err(format!("trajectory must be 1 or 2, got {trajectory}"))),
    };
    if !(0.0..=1.0).contains(&max_rejected) {
        return Err(PyValueError::new_err(format!(
            "max_rejected must be a fraction in [0, 1], got {max_rejected}"
        )));
    }
    let opts = Options {
        scalar: parse_scalar(scalar)?,
        dt,
        duration,
        log_every,
        psi_rate_in_drift,
        explicit_rest_filter,
        discretisation: parse_discretisation(discretisation.as_deref())?,
        limits: parse_limits(limits.as_deref())?,
        actuator_lag,
        noise,
        wheel_scale_error,
        seed,
        ..Options::default()
    };
    let (platform, choice) = (parse_platform(platform)?, parse_choice(choice)?);
    let err = |e: anyhow::Error| runtime_error(py, &e);
    let spatial = crate::arm::ArmArg::extract_or_rpr(arm)?.spec(py)?;
    let mut file = config_file(py, config.as_ref())?;
    if let Some(a) = &spatial {
        // As `companion sim --arm`: the arm's platform settings where the file has none.
        file = file.with_arm_settings(a.platform_defaults());
    }
    let planar_target = match (&target_file, &spatial) {
        (Some(p), None) => Target::File(p.clone()),
        _ => Target::Paper(traj),
    };
    let b = opts.builder(file, planar_target, choice, platform, DEFAULT_DURATION);
    let b = b.delay(delay).delay_compensation(delay_compensation);
    let base = b.build().map_err(|e| err(e.into()))?;
    let (dir, keep) = match out {
        Some(d) => (d, true),
        None => (scratch_dir(), false),
    };
    let result = match spatial {
        None => {
            companion_runtime::domain::plant_setup::build(&base).map_err(|e| err(e.into()))?;
            let acceptance = Acceptance { max_rejected, ..Acceptance::default() };
            let run =
                py.detach(|| companion_runtime::run::sim::run_one_with(&base, &dir, &Silent, &acceptance));
            run.map_err(|e| sim_error(py, e))
                .and_then(|o| Ok((planar_timeseries(py, &o.rows)?, json_dict(py, &o.summary)?)))
        }
        Some(arm) => {
            let target = match target_file {
                Some(p) => SpatialTargetChoice::File(p),
                None => SpatialTargetChoice::Lifted(traj),
            };
            let s = SpatialScenario::new(base, arm, target).map_err(|e| err(e.into()))?;
            companion_runtime::run::spatial::check(&s).map_err(|e| spatial_error(py, e))?;
            let run = py.detach(|| {
                companion_runtime::run::spatial::run_spatial(&s, &dir, &Silent, max_rejected, None)
            });
            run.map_err(|e| spatial_error(py, e))
                .and_then(|(o, _)| Ok((spatial_timeseries(py, &o.rows)?, json_dict(py, &o.summary)?)))
        }
    };
    if !keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    result
}
