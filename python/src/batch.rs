//! `companion.LawBatch`: many independent laws stepped in one call (Monte Carlo from Python),
//! one row of a numpy array per law, the loop in Rust with the GIL released.

use std::path::PathBuf;

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::step_error_code;
use crate::law::{measurement_width, Inner, LawSpec, DIAGNOSTICS};

/// `n` independent laws of one configuration (the arguments of `Law`), each with its own
/// state.
#[pyclass(module = "companion")]
#[derive(Debug)]
pub struct LawBatch {
    laws: Vec<Inner>,
    width: usize,
    joints: usize,
}

/// The three arrays one batch step returns.
type StepArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<u8>>);

#[pymethods]
impl LawBatch {
    /// `n` laws, each built as `Law(platform, choice, arm, scalar, config=…, …)` would be.
    #[new]
    #[pyo3(signature = (n, platform="unicycle", choice="a", arm=None, scalar="f64", *, config=None,
        discretisation=None, psi_rate_in_drift=false, explicit_rest_filter=false, limits=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        n: usize,
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
            arm: crate::arm::ArmArg::extract_or_rpr(arm)?,
            scalar: scalar.into(),
            config,
            discretisation,
            psi_rate_in_drift,
            explicit_rest_filter,
            limits,
        };
        let first = spec.build(py)?;
        let (spatial, joints) = (first.spatial(), first.joints());
        let mut laws = Vec::with_capacity(n);
        if n > 0 {
            laws.push(first);
        }
        while laws.len() < n {
            laws.push(spec.build(py)?);
        }
        Ok(Self { laws, width: measurement_width(spatial, joints), joints })
    }

    fn __len__(&self) -> usize {
        self.laws.len()
    }

    /// The arm's joint count.
    #[getter]
    fn joints(&self) -> usize {
        self.joints
    }

    /// The columns of the measurement array (as `Law.measurement_width`).
    #[getter]
    fn measurement_width(&self) -> usize {
        self.width
    }

    /// Steps law `i` on row `i` of `measurements` (shape (n, measurement_width), float64) with
    /// the same `period` and `delay` (s). Returns `(commands, diagnostics, errors)`: commands
    /// (n, 4 + joints) `[v, v_lat, ω, v_ξ, u_q…]`, diagnostics (n, 7) `[‖e_p‖, h_s, Ψ,
    /// saturation, α̇₁, α̇₂, joint_scale]`, errors (n,) uint8: 0 for an accepted step, else
    /// 1 + the index of the `StepError` variant in `companion.STEP_ERRORS` (that law's command
    /// is then zero and its state unchanged). Nothing is raised for a rejected step.
    #[pyo3(signature = (measurements, period, delay=0.0))]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        measurements: PyReadonlyArray2<'py, f64>,
        period: f64,
        delay: f64,
    ) -> PyResult<StepArrays<'py>> {
        let a = measurements.as_array();
        if a.nrows() != self.laws.len() || a.ncols() != self.width {
            return Err(PyValueError::new_err(format!(
                "measurements must have shape ({}, {}), got ({}, {})",
                self.laws.len(),
                self.width,
                a.nrows(),
                a.ncols()
            )));
        }
        let (n, width, cw) = (self.laws.len(), self.width, 4 + self.joints);
        let mut commands = Array2::<f64>::zeros((n, cw));
        let mut diagnostics = Array2::<f64>::zeros((n, DIAGNOSTICS));
        let mut errors = Array1::<u8>::zeros(n);
        let laws = &mut self.laws;
        // A contiguous array is read in place; another layout is copied row by row.
        let contiguous = a.as_slice();
        py.detach(|| {
            let mut row = vec![0.0; width];
            for (i, law) in laws.iter_mut().enumerate() {
                let r: &[f64] = match contiguous {
                    Some(s) => &s[i * width..(i + 1) * width],
                    None => {
                        for (d, s) in row.iter_mut().zip(a.row(i).iter()) {
                            *d = *s;
                        }
                        &row
                    }
                };
                let f = law.step(r, period, delay);
                for (d, s) in commands.row_mut(i).iter_mut().zip(&f.command[..cw]) {
                    *d = *s;
                }
                for (d, s) in diagnostics.row_mut(i).iter_mut().zip(&f.diagnostics) {
                    *d = *s;
                }
                errors[i] = step_error_code(f.error);
            }
        });
        Ok((commands.into_pyarray(py), diagnostics.into_pyarray(py), errors.into_pyarray(py)))
    }
}
