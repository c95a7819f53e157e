//! `companion.Arm`: an arm as the law sees it — a preset, a TOML arm file, or the chain
//! between two links of a URDF (`Arm.from_urdf`) — with its joints, limits, home, and its
//! forward kinematics and Jacobian for checking the description against another library.
//!
//! `Law(arm=…)` and `simulate(arm=…)` take an `Arm` wherever they take a name or a file.

use std::path::PathBuf;

use companion_core::nalgebra::{Matrix3, SVector, Vector3};
use companion_core::{Chain, Pose3};
use companion_runtime::domain::arm::{ArmChoice, HomeList, SpatialArmSpec, UrdfRequest};
use numpy::{PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::runtime_error;

/// A spatial arm (6 to 8 joints).
#[pyclass(module = "companion", frozen)]
#[derive(Clone, Debug)]
pub struct Arm {
    pub(crate) spec: SpatialArmSpec,
}

/// What `arm=` was given: a name or file (read when the law is built), or an `Arm`.
#[derive(Clone, Debug)]
pub enum ArmArg {
    /// `rpr`, `ur5`, `panda`, or a TOML arm file.
    Named(String),
    /// An `Arm` object.
    Given(Box<SpatialArmSpec>),
}

impl ArmArg {
    /// `arm=`'s value: a `str` or an `Arm`.
    pub fn extract(obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(a) = obj.cast::<Arm>() {
            return Ok(Self::Given(Box::new(a.get().spec.clone())));
        }
        if let Ok(s) = obj.extract::<String>() {
            return Ok(Self::Named(s));
        }
        Err(PyTypeError::new_err("arm must be 'rpr', 'ur5', 'panda', a TOML arm file or a companion.Arm"))
    }

    /// The spatial arm (`None` for the planar `rpr`).
    pub fn spec(&self, py: Python<'_>) -> PyResult<Option<SpatialArmSpec>> {
        match self {
            Self::Given(s) => Ok(Some((**s).clone())),
            Self::Named(name) => {
                if let ArmChoice::Urdf(r) = ArmChoice::parse(name) {
                    return Err(PyValueError::new_err(format!(
                        "{}: a URDF needs its links and home: companion.Arm.from_urdf(path, base_link, tip_link, ...)",
                        r.path.display()
                    )));
                }
                SpatialArmSpec::from_choice(&ArmChoice::parse(name)).map_err(|e| runtime_error(py, &e.into()))
            }
        }
    }

    /// `arm=`'s value, `'rpr'` if not given.
    pub fn extract_or_rpr(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        obj.map_or_else(|| Ok(Self::Named("rpr".into())), Self::extract)
    }

    /// How `repr` shows it.
    pub fn label(&self) -> String {
        match self {
            Self::Named(s) => s.clone(),
            Self::Given(s) => s.name().to_string(),
        }
    }
}

/// The chain in `f64` with its joint count as a type, for `$body`.
macro_rules! with_chain {
    ($spec:expr, $py:expr, |$c:ident| $body:expr) => {{
        let err = |e: companion_runtime::domain::arm::ArmError| runtime_error($py, &e.into());
        match $spec.joints() {
            6 => {
                let $c: Chain<f64, 6> = $spec.chain().map_err(err)?;
                $body
            }
            7 => {
                let $c: Chain<f64, 7> = $spec.chain().map_err(err)?;
                $body
            }
            _ => {
                let $c: Chain<f64, 8> = $spec.chain().map_err(err)?;
                $body
            }
        }
    }};
}

/// `q` as a vector of the chain's `N` joints.
fn joints<const N: usize>(q: &PyReadonlyArray1<'_, f64>) -> PyResult<SVector<f64, N>> {
    let q = q.as_slice()?;
    if q.len() != N {
        return Err(PyValueError::new_err(format!("q has {} values: the arm has {N} joints", q.len())));
    }
    if !q.iter().all(|x| x.is_finite()) {
        return Err(PyValueError::new_err("q must be finite"));
    }
    Ok(SVector::from_column_slice(q))
}

/// A joint's axis, a point on it, and whether it turns (else it slides).
type Axis = (Vector3<f64>, Vector3<f64>, bool);

/// The tip in the arm's base frame (the chain without its mount), and every joint's axis and
/// a point on it in that frame.
fn frames<const N: usize>(c: &Chain<f64, N>, q: &SVector<f64, N>) -> (Pose3<f64>, [Axis; N]) {
    let mut f = Pose3::<f64>::identity();
    let mut axes = [(Vector3::zeros(), Vector3::zeros(), true); N];
    for (i, j) in c.joints.iter().enumerate() {
        f = f.compose(&j.origin);
        axes[i] = (f.rotation * j.axis, f.translation, j.kind == companion_core::JointKind::Revolute);
        f = f.compose(&j.motion(q[i]));
    }
    (f.compose(&c.tool), axes)
}

#[pymethods]
impl Arm {
    /// An arm by name (`'ur5'`, `'panda'`) or from a TOML arm file.
    #[new]
    fn new(py: Python<'_>, arm: &str) -> PyResult<Self> {
        match ArmArg::Named(arm.to_string()).spec(py)? {
            Some(spec) => Ok(Self { spec }),
            None => {
                Err(PyValueError::new_err("'rpr' is the planar arm: Arm is a spatial arm (6 to 8 joints)"))
            }
        }
    }

    /// The chain from `base_link` to `tip_link` of a URDF (the root link if `base_link` is
    /// None), its home from an SRDF's `group_state` (`srdf`, `home_state`) and/or `home`: a
    /// sequence of every joint's value in the chain's order, or a dict of joints by name
    /// (over the state's). Raises `ScenarioError` naming the joint or link on a bad file.
    #[staticmethod]
    #[pyo3(signature = (path, base_link=None, tip_link=None, srdf=None, home_state=None, home=None))]
    fn from_urdf(
        py: Python<'_>,
        path: PathBuf,
        base_link: Option<String>,
        tip_link: Option<String>,
        srdf: Option<PathBuf>,
        home_state: Option<String>,
        home: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let home = match home {
            None => None,
            Some(h) => Some(if let Ok(d) = h.cast::<PyDict>() {
                HomeList::Named(
                    d.extract::<Vec<(String, f64)>>()
                        .or_else(|_| d.items().extract::<Vec<(String, f64)>>())?,
                )
            } else {
                HomeList::Values(h.extract::<Vec<f64>>()?)
            }),
        };
        let request = UrdfRequest { path, base_link, tip_link, srdf, home_state, home, mount: None };
        let spec = SpatialArmSpec::from_choice(&ArmChoice::Urdf(Box::new(request)))
            .map_err(|e| runtime_error(py, &e.into()))?
            .ok_or_else(|| PyValueError::new_err("not a spatial arm"))?;
        Ok(Self { spec })
    }

    /// The arm's name (a URDF's `<robot name>`).
    #[getter]
    fn name(&self) -> String {
        self.spec.name().to_string()
    }
    /// The number of joints.
    #[getter]
    fn joints(&self) -> usize {
        self.spec.joints()
    }
    /// The joints' names, from the base outwards.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.spec.joint_names()
    }
    /// Lower limits (rad or m; -inf for a continuous joint).
    #[getter]
    fn lower<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        with_chain!(self.spec, py, |c| Ok(PyArray1::from_slice(py, c.limits().lower.as_slice())))
    }
    /// Upper limits (rad or m; inf for a continuous joint).
    #[getter]
    fn upper<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        with_chain!(self.spec, py, |c| Ok(PyArray1::from_slice(py, c.limits().upper.as_slice())))
    }
    /// Speed limits (rad/s or m/s; inf where none).
    #[getter]
    fn max_velocity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        with_chain!(self.spec, py, |c| Ok(PyArray1::from_slice(py, c.max_velocities().as_slice())))
    }
    /// The home configuration (rad or m).
    #[getter]
    fn home<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        with_chain!(self.spec, py, |c| Ok(PyArray1::from_slice(py, c.home().as_slice())))
    }

    /// The tip's pose in the base link's frame at `q` (4×4 homogeneous matrix; m).
    fn forward<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        with_chain!(self.spec, py, |c| {
            let (tip, _) = frames(&c, &joints(&q)?);
            let r: Matrix3<f64> = tip.rotation;
            let t = tip.translation;
            let rows: Vec<Vec<f64>> = (0..4)
                .map(|i| {
                    if i < 3 {
                        vec![r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]]
                    } else {
                        vec![0.0, 0.0, 0.0, 1.0]
                    }
                })
                .collect();
            Ok(PyArray2::from_vec2(py, &rows)?)
        })
    }

    /// The geometric Jacobian at `q` (6×N): rows (v; ω) of the tip's origin in the base
    /// link's axes (Pinocchio's LOCAL_WORLD_ALIGNED with the base link as the world).
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: PyReadonlyArray1<'_, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        with_chain!(self.spec, py, |c| {
            let (tip, axes) = frames(&c, &joints(&q)?);
            let mut rows = vec![vec![0.0; axes.len()]; 6];
            for (k, (z, o, revolute)) in axes.iter().enumerate() {
                let (v, w) =
                    if *revolute { (z.cross(&(tip.translation - o)), *z) } else { (*z, Vector3::zeros()) };
                for i in 0..3 {
                    rows[i][k] = v[i];
                    rows[i + 3][k] = w[i];
                }
            }
            Ok(PyArray2::from_vec2(py, &rows)?)
        })
    }

    fn __repr__(&self) -> String {
        format!("Arm(name={:?}, joints={})", self.spec.name(), self.spec.joints())
    }
}
