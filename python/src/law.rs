//! `companion.Law`: one controller (the planar RPR arm or a spatial arm on any platform, f64
//! or f32), built from the CLI's presets and `--config` TOML, stepped from Python.
//!
//! A measurement is a flat row of numbers (the same layout as a row of the batch call's
//! array, so one law and many share one code path):
//!
//! - planar (the RPR arm): `t, x_b, y_b, θ_b, ξ, q₁, q₂, q₃, x_d, y_d, θ_d, u_d1, u_d2, u_d3`
//!   (14 numbers);
//! - spatial (`N` joints): `t, x_b, y_b, θ_b, ξ, q₁…q_N, R_d (9, row-major), p_d (3), v_d (3),
//!   ω_d (3)` (23 + N numbers).
//!
//! A command is `v, v_lat, ω, v_ξ, u_q1…u_qN` (4 + N); the diagnostics are `‖e_p‖, h_s, Ψ,
//! saturation, α̇₁, α̇₂, joint_scale` (7).

use std::path::PathBuf;
use std::sync::Mutex;

use companion_core::nalgebra::{Matrix3, SVector, Vector3};
use companion_core::{Manipulator, Measurement, PaperRun, PlatformKind, Pose, Pose3, Spatial, SpatialArm};
use companion_plant::PaperTrajectory;
use companion_runtime::domain::arm::SpatialArmSpec;
use companion_runtime::domain::controller::{
    boxed_spatial_controller, AnyController, DiscretisationConfig, Scalar, SpatialStep, StepReport, JOINTS,
};
use companion_runtime::domain::scenario::{ConfigFile, LimitsChoice, Options, Target};
use companion_runtime::run::spatial::{SpatialScenario, SpatialTargetChoice};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::arm::ArmArg;
use crate::errors::{runtime_error, step_error};

/// Numbers of a planar measurement row.
pub const PLANAR_WIDTH: usize = 5 + JOINTS + 6;
/// Diagnostics per step.
pub const DIAGNOSTICS: usize = 7;

/// Numbers of a measurement row for an arm of `joints` joints (3: planar).
pub fn measurement_width(spatial: bool, joints: usize) -> usize {
    if spatial {
        5 + joints + 18
    } else {
        PLANAR_WIDTH
    }
}

/// A spatial controller held for `&mut` access: the `Mutex` only makes the box `Sync` (as a
/// Python class must be); stepping takes `&mut self` and so never locks.
fn lock<T: ?Sized>(m: &mut Mutex<Box<T>>) -> &mut T {
    match m.get_mut() {
        Ok(b) => b.as_mut(),
        // A panic while stepping cannot have happened (the law does not panic), but the
        // controller would still be usable: take it.
        Err(poisoned) => poisoned.into_inner().as_mut(),
    }
}

/// One controller of any arm.
pub enum Inner {
    /// The planar RPR arm on any platform.
    Planar(AnyController),
    /// A spatial arm of 6 joints.
    S6(Mutex<Box<dyn SpatialStep<6> + Send>>),
    /// … of 7.
    S7(Mutex<Box<dyn SpatialStep<7> + Send>>),
    /// … of 8.
    S8(Mutex<Box<dyn SpatialStep<8> + Send>>),
}

/// What one step gives back, as plain numbers (the command then the diagnostics).
#[derive(Clone, Copy, Debug)]
pub struct Flat {
    /// `v, v_lat, ω, v_ξ, u_q…` (joints beyond the arm's are 0).
    pub command: [f64; 12],
    /// The arm's joint count.
    pub joints: usize,
    /// `‖e_p‖, h_s, Ψ, saturation, α̇₁, α̇₂, joint_scale`.
    pub diagnostics: [f64; DIAGNOSTICS],
    /// Why the step was rejected.
    pub error: Option<companion_core::StepError>,
}

fn flat<const N: usize>(r: &StepReport<N>) -> Flat {
    let p = &r.command.platform;
    let mut command = [0.0; 12];
    command[..4].copy_from_slice(&[p.v, p.v_lat, p.omega, p.v_xi]);
    for i in 0..N {
        command[4 + i] = r.command.joints[i];
    }
    Flat {
        command,
        joints: N,
        diagnostics: [r.ep_norm, r.h_s, r.psi, r.saturation, r.alpha_rate[0], r.alpha_rate[1], r.joint_scale],
        error: r.error,
    }
}

fn spatial_meas<const N: usize>(row: &[f64]) -> Measurement<f64, N, Spatial> {
    let q = &row[5..5 + N];
    let r = &row[5 + N..];
    Measurement {
        t: row[0],
        base: Pose::new(row[1], row[2], row[3]),
        steering: row[4],
        joints: SVector::<f64, N>::from_fn(|i, _| q[i]),
        target: Pose3::new(Matrix3::from_row_slice(&r[..9]), Vector3::new(r[9], r[10], r[11])),
        target_velocity: SVector::<f64, 6>::from_fn(|i, _| r[12 + i]),
    }
}

impl std::fmt::Debug for Inner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Planar(c) => f.debug_tuple("Planar").field(c).finish(),
            _ => write!(f, "Spatial({} joints)", self.joints()),
        }
    }
}

impl Inner {
    /// The arm's joint count.
    pub fn joints(&self) -> usize {
        match self {
            Self::Planar(_) => JOINTS,
            Self::S6(_) => 6,
            Self::S7(_) => 7,
            Self::S8(_) => 8,
        }
    }

    /// Whether the arm is spatial.
    pub fn spatial(&self) -> bool {
        !matches!(self, Self::Planar(_))
    }

    /// One step on a measurement row (of [`measurement_width`] numbers, checked by the caller).
    #[inline]
    pub fn step(&mut self, row: &[f64], period: f64, delay: f64) -> Flat {
        match self {
            Self::Planar(c) => {
                let m = Measurement::<f64, JOINTS> {
                    t: row[0],
                    base: Pose::new(row[1], row[2], row[3]),
                    steering: row[4],
                    joints: SVector::<f64, JOINTS>::new(row[5], row[6], row[7]),
                    target: Pose::new(row[8], row[9], row[10]),
                    target_velocity: Vector3::new(row[11], row[12], row[13]),
                };
                flat(&c.step(&m, period, delay))
            }
            Self::S6(c) => flat(&lock(c).step(&spatial_meas::<6>(row), period, delay)),
            Self::S7(c) => flat(&lock(c).step(&spatial_meas::<7>(row), period, delay)),
            Self::S8(c) => flat(&lock(c).step(&spatial_meas::<8>(row), period, delay)),
        }
    }
}

/// What builds a law: the `companion sim` flags that set the controller.
#[derive(Clone, Debug)]
pub struct LawSpec {
    /// `unicycle`, `car`, `omni`.
    pub platform: String,
    /// `a`–`d`.
    pub choice: String,
    /// `rpr`, `ur5`, `panda`, an arm file, or an `Arm`.
    pub arm: ArmArg,
    /// `f64` or `f32`.
    pub scalar: String,
    /// `--config`.
    pub config: Option<PathBuf>,
    /// `--discretisation`.
    pub discretisation: Option<String>,
    /// `--psi-rate-in-drift`.
    pub psi_rate_in_drift: bool,
    /// `--explicit-rest-filter`.
    pub explicit_rest_filter: bool,
    /// `--limits`.
    pub limits: Option<String>,
}

/// `unicycle`, `car`, `omni`.
pub fn parse_platform(s: &str) -> PyResult<PlatformKind> {
    match s {
        "unicycle" => Ok(PlatformKind::Unicycle),
        "car" => Ok(PlatformKind::Car),
        "omni" => Ok(PlatformKind::Omni),
        _ => Err(PyValueError::new_err(format!("platform must be 'unicycle', 'car' or 'omni', got {s:?}"))),
    }
}

/// `a`–`d`.
pub fn parse_choice(s: &str) -> PyResult<PaperRun> {
    match s {
        "a" => Ok(PaperRun::A),
        "b" => Ok(PaperRun::B),
        "c" => Ok(PaperRun::C),
        "d" => Ok(PaperRun::D),
        _ => Err(PyValueError::new_err(format!("choice must be 'a', 'b', 'c' or 'd', got {s:?}"))),
    }
}

/// `f64`, `f32`.
pub fn parse_scalar(s: &str) -> PyResult<Scalar> {
    match s {
        "f64" => Ok(Scalar::F64),
        "f32" => Ok(Scalar::F32),
        _ => Err(PyValueError::new_err(format!("scalar must be 'f64' or 'f32', got {s:?}"))),
    }
}

/// `midpoint`, `sampled`.
pub fn parse_discretisation(s: Option<&str>) -> PyResult<Option<DiscretisationConfig>> {
    match s {
        None => Ok(None),
        Some("midpoint") => Ok(Some(DiscretisationConfig::Midpoint)),
        Some("sampled") => Ok(Some(DiscretisationConfig::Sampled)),
        Some(o) => {
            Err(PyValueError::new_err(format!("discretisation must be 'midpoint' or 'sampled', got {o:?}")))
        }
    }
}

/// `none`, `realistic`.
pub fn parse_limits(s: Option<&str>) -> PyResult<Option<LimitsChoice>> {
    match s {
        None => Ok(None),
        Some("none") => Ok(Some(LimitsChoice::Unlimited)),
        Some("realistic") => Ok(Some(LimitsChoice::Realistic)),
        Some(o) => Err(PyValueError::new_err(format!("limits must be 'none' or 'realistic', got {o:?}"))),
    }
}

/// The config file (empty without one).
pub fn config_file(py: Python<'_>, path: Option<&PathBuf>) -> PyResult<ConfigFile> {
    match path {
        None => Ok(ConfigFile::default()),
        Some(p) => ConfigFile::load(p).map_err(|e| runtime_error(py, &anyhow::Error::new(e))),
    }
}

fn spatial_inner<const N: usize>(
    spec: &companion_runtime::domain::controller::ControllerSpec,
    arm: &SpatialArmSpec,
) -> anyhow::Result<Box<dyn SpatialStep<N> + Send>>
where
    SpatialArm<f64, N>: Manipulator<f64, N, Space = Spatial>,
    SpatialArm<f32, N>: Manipulator<f32, N, Space = Spatial>,
{
    Ok(boxed_spatial_controller::<N>(spec, arm)?)
}

impl LawSpec {
    /// Builds the controller as `companion sim` would for these flags (the scenario built
    /// and validated by the runtime; the target is not used).
    pub fn build(&self, py: Python<'_>) -> PyResult<Inner> {
        let opts = Options {
            scalar: parse_scalar(&self.scalar)?,
            psi_rate_in_drift: self.psi_rate_in_drift,
            explicit_rest_filter: self.explicit_rest_filter,
            discretisation: parse_discretisation(self.discretisation.as_deref())?,
            limits: parse_limits(self.limits.as_deref())?,
            ..Options::default()
        };
        let err = |e: anyhow::Error| runtime_error(py, &e);
        let arm = self.arm.spec(py)?;
        let mut file = config_file(py, self.config.as_ref())?;
        if let Some(a) = &arm {
            // As `companion sim --arm`: the arm's platform settings where the file has none.
            file = file.with_arm_settings(a.platform_defaults());
        }
        let (platform, choice) = (parse_platform(&self.platform)?, parse_choice(&self.choice)?);
        let b = opts.builder(file, Target::Paper(PaperTrajectory::One), choice, platform, 1.0);
        let s = b.build().map_err(|e| err(e.into()))?;
        let Some(arm) = arm else {
            return AnyController::new(&s.controller)
                .map(Inner::Planar)
                .map_err(|e| crate::errors::param_error(py, e));
        };
        let s = SpatialScenario::new(s, arm, SpatialTargetChoice::Lifted(PaperTrajectory::One))
            .map_err(|e| err(e.into()))?;
        let (spec, arm) = (&s.base.controller, &s.arm);
        Ok(match arm.joints() {
            6 => Inner::S6(Mutex::new(spatial_inner::<6>(spec, arm).map_err(err)?)),
            7 => Inner::S7(Mutex::new(spatial_inner::<7>(spec, arm).map_err(err)?)),
            8 => Inner::S8(Mutex::new(spatial_inner::<8>(spec, arm).map_err(err)?)),
            n => return Err(crate::errors::ScenarioError::new_err(format!("an arm of {n} joints"))),
        })
    }
}

/// The result of one step: the command to hold over the period and the diagnostics the CLI
/// logs.
#[pyclass(module = "companion", frozen)]
#[derive(Clone, Debug)]
pub struct Output {
    pub(crate) flat: Flat,
}

#[pymethods]
impl Output {
    /// Forward speed v (m/s).
    #[getter]
    fn v(&self) -> f64 {
        self.flat.command[0]
    }
    /// Lateral speed v_lat (m/s; omnidirectional platform, else 0).
    #[getter]
    fn v_lat(&self) -> f64 {
        self.flat.command[1]
    }
    /// Turn rate ω (rad/s).
    #[getter]
    fn omega(&self) -> f64 {
        self.flat.command[2]
    }
    /// Steering rate v_ξ (1/(m·s); car-like platform, else 0).
    #[getter]
    fn v_xi(&self) -> f64 {
        self.flat.command[3]
    }
    /// Joint velocities u_q (rad/s or m/s), one per joint.
    #[getter]
    fn joint_rates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.flat.command[4..4 + self.flat.joints])
    }
    /// The whole command `[v, v_lat, ω, v_ξ, u_q1, …]` (SI units, as above).
    #[getter]
    fn command<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.flat.command[..4 + self.flat.joints])
    }
    /// ‖e_p‖ as the law estimates it at the evaluation point (m and rad mixed; NaN when rejected).
    #[getter]
    fn ep_norm(&self) -> f64 {
        self.flat.diagnostics[0]
    }
    /// The secondary task function h_s (NaN when rejected).
    #[getter]
    fn h_s(&self) -> f64 {
        self.flat.diagnostics[1]
    }
    /// The weight Ψ of eqs. (52)–(53) (NaN when rejected).
    #[getter]
    fn psi(&self) -> f64 {
        self.flat.diagnostics[2]
    }
    /// The common saturation factor (≥ 1; NaN when rejected).
    #[getter]
    fn saturation(&self) -> f64 {
        self.flat.diagnostics[3]
    }
    /// α̇ (rad/s), two numbers (NaN when rejected).
    #[getter]
    fn alpha_rate(&self) -> (f64, f64) {
        (self.flat.diagnostics[4], self.flat.diagnostics[5])
    }
    /// The joint guard's factor (≥ 1; NaN when rejected).
    #[getter]
    fn joint_scale(&self) -> f64 {
        self.flat.diagnostics[6]
    }
    /// The diagnostics `[‖e_p‖, h_s, Ψ, saturation, α̇₁, α̇₂, joint_scale]`.
    #[getter]
    fn diagnostics<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.flat.diagnostics)
    }
    /// The `StepError` variant's name if the law rejected the step (then the command is zero).
    #[getter]
    fn error(&self) -> Option<&'static str> {
        self.flat.error.map(crate::errors::step_error_name)
    }
    fn __repr__(&self) -> String {
        format!(
            "Output(command={:?}, ep_norm={:e}, error={:?})",
            &self.flat.command[..4 + self.flat.joints],
            self.flat.diagnostics[0],
            self.error()
        )
    }
}

/// A measurement row from a Python value: a `Measurement`, or a 1-D array (or sequence) of the
/// row layout.
pub fn row_of(m: &Bound<'_, PyAny>, width: usize, buf: &mut Vec<f64>) -> PyResult<()> {
    buf.clear();
    if let Ok(m) = m.cast::<crate::measurement::Measurement>() {
        buf.extend_from_slice(&m.get().values);
    } else if let Ok(a) = m.extract::<PyReadonlyArray1<'_, f64>>() {
        buf.extend(a.as_array().iter().copied());
    } else if let Ok(v) = m.extract::<Vec<f64>>() {
        buf.extend(v);
    } else {
        return Err(PyTypeError::new_err(
            "a measurement must be a companion.Measurement, a 1-D float64 array or a sequence of numbers",
        ));
    }
    if buf.len() != width {
        return Err(PyValueError::new_err(format!(
            "a measurement for this law has {width} numbers, got {} (see Law.measurement_width)",
            buf.len()
        )));
    }
    Ok(())
}

/// One controller of the companion law (the planar RPR arm, or a spatial arm `ur5`, `panda` or
/// an arm file) on a unicycle, car-like or omnidirectional platform, in f64 or f32, built from
/// the same presets and `--config` TOML as `companion sim`.
#[pyclass(module = "companion")]
#[derive(Debug)]
pub struct Law {
    pub(crate) inner: Inner,
    buf: Vec<f64>,
    platform: String,
    arm: String,
    scalar: String,
}

#[pymethods]
impl Law {
    /// Builds the law. `platform`: 'unicycle' | 'car' | 'omni'; `choice`: the paper's variant
    /// 'a'–'d'; `arm`: 'rpr' | 'ur5' | 'panda' | a TOML arm file | a `companion.Arm`; `scalar`: 'f64' | 'f32';
    /// `config`: a `--config` TOML file; the rest as the flags of the same name.
    ///
    /// Raises a `ParamError` subclass for an invalid parameter, `ConfigError` for a bad file,
    /// `ScenarioError` otherwise.
    #[new]
    #[pyo3(signature = (platform="unicycle", choice="a", arm=None, scalar="f64", *, config=None,
        discretisation=None, psi_rate_in_drift=false, explicit_rest_filter=false, limits=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        platform: &str,
        choice: &str,
        arm: Option<&Bound<'_, PyAny>>,
        scalar: &str,
        config: Option<PathBuf>,
        discretisation: Option<String>,
        psi_rate_in_drift: bool,
        explicit_rest_filter: bool,
        limits: Option<String>,
    ) -> PyResult<Self> {
        let spec = LawSpec {
            platform: platform.into(),
            choice: choice.into(),
            arm: ArmArg::extract_or_rpr(arm)?,
            scalar: scalar.into(),
            config,
            discretisation,
            psi_rate_in_drift,
            explicit_rest_filter,
            limits,
        };
        let inner = spec.build(py)?;
        Ok(Self {
            inner,
            buf: Vec::with_capacity(32),
            platform: spec.platform,
            arm: spec.arm.label(),
            scalar: spec.scalar,
        })
    }

    /// The arm's joint count (3 for the planar RPR arm).
    #[getter]
    fn joints(&self) -> usize {
        self.inner.joints()
    }

    /// Whether the arm is spatial (§5) rather than the planar RPR arm (§4).
    #[getter]
    fn spatial(&self) -> bool {
        self.inner.spatial()
    }

    /// How many numbers a measurement row has (14 planar; 23 + joints spatial).
    #[getter]
    fn measurement_width(&self) -> usize {
        measurement_width(self.inner.spatial(), self.inner.joints())
    }

    /// One step: the command to hold for `period` seconds, taking effect `delay` seconds after
    /// the measurement was taken (0: at once), and the diagnostics.
    ///
    /// `measurement`: a `companion.Measurement`, or its row (`Measurement.row`) as a 1-D float64
    /// array or a sequence of numbers.
    /// Raises the `StepError` subclass named after the law's rejection (its `.command` is the
    /// safe zero command, `.output` the whole result); the law's state is then unchanged.
    #[pyo3(signature = (measurement, period, delay=0.0))]
    fn step(
        &mut self,
        py: Python<'_>,
        measurement: &Bound<'_, PyAny>,
        period: f64,
        delay: f64,
    ) -> PyResult<Output> {
        let width = measurement_width(self.inner.spatial(), self.inner.joints());
        row_of(measurement, width, &mut self.buf)?;
        let flat = self.inner.step(&self.buf, period, delay);
        match flat.error {
            None => Ok(Output { flat }),
            Some(e) => {
                let command = PyArray1::from_slice(py, &flat.command[..4 + flat.joints]).into_any().unbind();
                let out = Py::new(py, Output { flat })?.into_any();
                Err(step_error(py, e, out, command))
            }
        }
    }

    /// Times the Rust step alone, for the benchmark: steps this law through the rows of
    /// `measurements` (shape (n, measurement_width)) and returns each step's time in
    /// nanoseconds (no Python in between). The law's state advances as by `step`.
    #[pyo3(signature = (measurements, period, delay=0.0))]
    fn time_rust_steps<'py>(
        &mut self,
        py: Python<'py>,
        measurements: numpy::PyReadonlyArray2<'py, f64>,
        period: f64,
        delay: f64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let a = measurements.as_array();
        let width = measurement_width(self.inner.spatial(), self.inner.joints());
        if a.ncols() != width {
            return Err(PyValueError::new_err(format!(
                "measurements must have {width} columns, got {}",
                a.ncols()
            )));
        }
        let mut times = Vec::with_capacity(a.nrows());
        let mut row = vec![0.0; width];
        let mut sink = 0.0;
        for r in a.rows() {
            for (d, s) in row.iter_mut().zip(r.iter()) {
                *d = *s;
            }
            let t0 = std::time::Instant::now();
            let f = self.inner.step(std::hint::black_box(&row), period, delay);
            times.push(t0.elapsed().as_nanos() as f64);
            sink += f.command[0];
        }
        std::hint::black_box(sink);
        Ok(PyArray1::from_vec(py, times))
    }

    fn __repr__(&self) -> String {
        format!("Law(platform={:?}, arm={:?}, scalar={:?})", self.platform, self.arm, self.scalar)
    }
}
