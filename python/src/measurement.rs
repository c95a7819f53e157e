//! `companion.Measurement`: what the law reads at one step, held as the flat row
//! [`crate::law`] documents.

use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// One measurement: the time, the platform's pose and steering, the joints, the target's pose
/// and body velocity.
#[pyclass(module = "companion", frozen)]
#[derive(Clone, Debug)]
pub struct Measurement {
    pub(crate) values: Vec<f64>,
    pub(crate) joints: usize,
    pub(crate) spatial: bool,
}

fn numbers(v: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<Vec<f64>> {
    let x: Vec<f64> =
        v.extract().map_err(|_| PyValueError::new_err(format!("{what} must be {n} numbers")))?;
    if x.len() != n {
        return Err(PyValueError::new_err(format!("{what} must be {n} numbers, got {}", x.len())));
    }
    Ok(x)
}

#[pymethods]
impl Measurement {
    /// `t`: time (s); `base`: the platform's pose (x, y, θ) (m, m, rad); `joints`: q (rad or m,
    /// 3 for the planar RPR arm, 6–8 for a spatial arm); `target`: the target's pose, planar
    /// (x, y, θ) (m, m, rad) or spatial as a 4×4 homogeneous transform (rotation, translation
    /// in m; z up, the platform's plane at z = 0); `target_velocity`: the target's body velocity,
    /// planar (v_x, v_y, ω) (m/s, m/s, rad/s) or spatial (v, ω) (6: m/s then rad/s);
    /// `steering`: the car's ξ = tan φ / ℓ (1/m), ignored by the other platforms.
    #[new]
    #[pyo3(signature = (t, base, joints, target, target_velocity, steering=0.0))]
    fn new(
        t: f64,
        base: &Bound<'_, PyAny>,
        joints: &Bound<'_, PyAny>,
        target: &Bound<'_, PyAny>,
        target_velocity: &Bound<'_, PyAny>,
        steering: f64,
    ) -> PyResult<Self> {
        let base = numbers(base, "base", 3)?;
        let q: Vec<f64> = joints.extract().map_err(|_| PyValueError::new_err("joints must be numbers"))?;
        let mut values = vec![t, base[0], base[1], base[2], steering];
        values.extend_from_slice(&q);
        let planar_target: Result<Vec<f64>, _> = target.extract();
        let spatial = match planar_target {
            Ok(p) if p.len() == 3 => {
                values.extend_from_slice(&p);
                values.extend(numbers(target_velocity, "target_velocity (planar)", 3)?);
                false
            }
            _ => {
                let m: Vec<Vec<f64>> = target.extract().map_err(|_| {
                    PyValueError::new_err("target must be (x, y, θ) or a 4×4 homogeneous transform")
                })?;
                if m.len() != 4 || m.iter().any(|r| r.len() != 4) {
                    return Err(PyValueError::new_err(
                        "a spatial target must be a 4×4 homogeneous transform",
                    ));
                }
                for r in &m[..3] {
                    values.extend_from_slice(&r[..3]);
                }
                values.extend([m[0][3], m[1][3], m[2][3]]);
                values.extend(numbers(target_velocity, "target_velocity (spatial: v, ω)", 6)?);
                true
            }
        };
        if !spatial && q.len() != 3 {
            return Err(PyValueError::new_err(format!("a planar measurement has 3 joints, got {}", q.len())));
        }
        if spatial && !(6..=8).contains(&q.len()) {
            return Err(PyValueError::new_err(format!(
                "a spatial measurement has 6 to 8 joints, got {}",
                q.len()
            )));
        }
        Ok(Self { values, joints: q.len(), spatial })
    }

    /// The flat row a `Law` steps on (see `Law.measurement_width`).
    #[getter]
    fn row<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.values)
    }

    /// Time (s).
    #[getter]
    fn t(&self) -> f64 {
        self.values[0]
    }

    /// The joint count.
    #[getter]
    fn joints(&self) -> usize {
        self.joints
    }

    /// Whether the target is spatial.
    #[getter]
    fn spatial(&self) -> bool {
        self.spatial
    }

    fn __repr__(&self) -> String {
        format!("Measurement({:?})", self.values)
    }
}
