//! One recorded step: a row of `timeseries.csv`, for the paper's planar arm (`Row`, the
//! default parameters: targets in the plane, three joints) or a spatial one
//! (`Row<Spatial, N>`, §5). The planar arm is the 3-joint planar case of the same type.

use companion_core::nalgebra::{SVector, Vector3, Vector6};
use companion_core::{Planar, PlatformKind, Pose, Pose3, Space, Spatial};

use crate::domain::controller::{StepReport, JOINTS};

/// What the record needs of a target's space beyond the law's [`Space`]: the pose that stands
/// for "not computed", the error's norm, and how a row is written (`timeseries.csv`'s columns,
/// the replay's error). Implemented for [`Planar`] (the paper's arm, §4) and [`Spatial`] (§5).
pub trait Task: Space<f64, Pose: Send + Sync, Vector: Send + Sync> + Send + Sync {
    /// The identity pose (a row's end effector on a step that is not logged).
    fn identity() -> Self::Pose;

    /// The pose in space (the plane's at height 0, turned about `z`).
    fn lift(p: &Self::Pose) -> Pose3<f64>;

    /// `‖v‖`, the Euclidean norm of all the components.
    fn norm(v: &Self::Vector) -> f64;

    /// The names of `e_p`'s components, as the replay writes them.
    const ERROR_NAMES: &'static [&'static str];

    /// The columns of `timeseries.csv` for a platform and `joints` joints (`status` last).
    fn columns(kind: PlatformKind, joints: usize) -> Vec<String>;

    /// A row's numbers in the order of [`columns`](Self::columns) (all but `status`).
    fn numbers<const N: usize>(row: &Row<Self, N>, kind: PlatformKind, out: &mut dyn FnMut(f64))
    where
        Self: Sized;
}

/// The plant's true state at one step, as recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantSample<S: Space<f64> = Planar, const N: usize = JOINTS> {
    /// Time (s).
    pub t: f64,
    /// Platform pose `(x, y, θ)`, `θ` never wrapped.
    pub base: Pose<f64>,
    /// Car steering `ξ` (1/m); 0 for other platforms.
    pub steering: f64,
    /// Joints.
    pub joints: SVector<f64, N>,
    /// End-effector pose (world); the identity on steps that are not logged (the summary does
    /// not read it, and its forward kinematics are the costly part of a sample).
    pub end_effector: S::Pose,
    /// Target pose (world).
    pub target: S::Pose,
    /// The target's body velocity `u_d` (m/s, rad/s).
    pub target_velocity: S::Vector,
    /// The true tracking error `e_p` (eq. (42) in the plane, `(p̃, log R̃)` in space), from the
    /// plant's exact state.
    pub e_p: S::Vector,
    /// `‖e_p‖`: what the summary and the `ep_norm` column report (the robot's error, not the
    /// law's estimate).
    pub ep_norm: f64,
}

/// How the command of a step was obtained (HIL adds hold/stop).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandSource {
    /// The controller's command for this step.
    Fresh,
    /// The previous command, held because this step's command missed its deadline.
    Held,
    /// The safe zero command: commands missed too many deadlines.
    Stopped,
}

/// One logged row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row<S: Space<f64> = Planar, const N: usize = JOINTS> {
    /// The plant's state.
    pub plant: PlantSample<S, N>,
    /// The controller's report.
    pub report: StepReport<N>,
    /// Where the command came from.
    pub source: CommandSource,
}

impl<S: Space<f64>, const N: usize> Row<S, N> {
    /// The status column: `ok`, `rejected:` and the law's reason (e.g.
    /// `rejected:JointAtLimit(1)`), `held` or `stopped`.
    pub fn status(&self) -> String {
        let mut s = String::new();
        self.write_status(&mut s);
        s
    }

    /// Appends the status column to `out`.
    pub fn write_status(&self, out: &mut String) {
        use std::fmt::Write as _;
        match (self.source, self.report.error) {
            (CommandSource::Held, _) => out.push_str("held"),
            (CommandSource::Stopped, _) => out.push_str("stopped"),
            (CommandSource::Fresh, None) => out.push_str("ok"),
            (CommandSource::Fresh, Some(e)) => {
                let _ = write!(out, "rejected:{e:?}");
            }
        }
    }
}

/// The platform's columns beyond `v` and `omega` in the planar CSV.
fn planar_extra(kind: PlatformKind) -> &'static [&'static str] {
    match kind {
        PlatformKind::Car => &["alpha_dot2", "xi", "v_xi"],
        PlatformKind::Omni => &["v_lat"],
        PlatformKind::Unicycle => &[],
    }
}

impl Task for Planar {
    fn identity() -> Pose<f64> {
        Pose::identity()
    }

    fn lift(p: &Pose<f64>) -> Pose3<f64> {
        Pose3::from_planar(p)
    }

    #[inline]
    fn norm(v: &Vector3<f64>) -> f64 {
        v.norm()
    }

    const ERROR_NAMES: &'static [&'static str] = &["x", "y", "theta"];

    /// The paper's columns (its figures and the Python package read them): the pose
    /// triples, the law's `Ψ`, `α̇` and saturation, and the platform's own velocities.
    fn columns(kind: PlatformKind, joints: usize) -> Vec<String> {
        let mut h: Vec<String> = ["t", "x_b", "y_b", "theta_b"].map(String::from).to_vec();
        h.extend((1..=joints).map(|i| format!("q{i}")));
        h.extend(
            [
                "x_e",
                "y_e",
                "theta_e",
                "x_d",
                "y_d",
                "theta_d",
                "ep_norm",
                "h_s",
                "psi",
                "v",
                "omega",
                "alpha_dot",
                "sat",
                "joint_scale",
            ]
            .map(String::from),
        );
        h.extend(planar_extra(kind).iter().map(|c| (*c).to_string()));
        h.push("status".to_string());
        h
    }

    fn numbers<const N: usize>(row: &Row<Self, N>, kind: PlatformKind, out: &mut dyn FnMut(f64)) {
        let p = &row.plant;
        let r = &row.report;
        let c = &r.command.platform;
        for x in [p.t, p.base.x, p.base.y, p.base.theta] {
            out(x);
        }
        for q in p.joints.iter() {
            out(*q);
        }
        for x in [
            p.end_effector.x,
            p.end_effector.y,
            p.end_effector.theta,
            p.target.x,
            p.target.y,
            p.target.theta,
            p.ep_norm,
            r.h_s,
            r.psi,
            c.v,
            c.omega,
            r.alpha_rate[0],
            r.saturation,
            r.joint_scale,
        ] {
            out(x);
        }
        match kind {
            PlatformKind::Car => [r.alpha_rate[1], p.steering, c.v_xi].into_iter().for_each(out),
            PlatformKind::Omni => out(c.v_lat),
            PlatformKind::Unicycle => {}
        }
    }
}

impl Task for Spatial {
    fn identity() -> Pose3<f64> {
        Pose3::identity()
    }

    fn lift(p: &Pose3<f64>) -> Pose3<f64> {
        *p
    }

    #[inline]
    fn norm(v: &Vector6<f64>) -> f64 {
        v.norm()
    }

    /// The translation (m) and the rotation vector (rad) of `(r*_ed)⁻¹ r_ed`.
    const ERROR_NAMES: &'static [&'static str] = &["x", "y", "z", "rx", "ry", "rz"];

    /// A pose as position and unit quaternion `(x, y, z, w)`, as Foxglove orders it; the six
    /// components of `e_p`; every platform velocity.
    fn columns(_kind: PlatformKind, joints: usize) -> Vec<String> {
        let mut h: Vec<String> = ["t", "x_b", "y_b", "theta_b", "xi"].map(String::from).to_vec();
        h.extend((1..=joints).map(|i| format!("q{i}")));
        for p in ["e", "d"] {
            h.extend(["x", "y", "z", "qx", "qy", "qz", "qw"].iter().map(|c| format!("{c}_{p}")));
        }
        h.extend(
            [
                "ep_x", "ep_y", "ep_z", "ep_rx", "ep_ry", "ep_rz", "ep_norm", "h_s", "psi", "v", "v_lat",
                "omega", "v_xi",
            ]
            .map(String::from),
        );
        h.extend((1..=joints).map(|i| format!("u_q{i}")));
        h.push("joint_scale".to_string());
        h.push("status".to_string());
        h
    }

    fn numbers<const N: usize>(row: &Row<Self, N>, _kind: PlatformKind, out: &mut dyn FnMut(f64)) {
        let p = &row.plant;
        let r = &row.report;
        for x in [p.t, p.base.x, p.base.y, p.base.theta, p.steering] {
            out(x);
        }
        for q in p.joints.iter() {
            out(*q);
        }
        for pose in [&p.end_effector, &p.target] {
            for x in pose.translation.iter() {
                out(*x);
            }
            for x in companion_core::so3::to_quaternion(&pose.rotation) {
                out(x);
            }
        }
        for x in p.e_p.iter() {
            out(*x);
        }
        let c = &r.command.platform;
        for x in [p.ep_norm, r.h_s, r.psi, c.v, c.v_lat, c.omega, c.v_xi] {
            out(x);
        }
        for u in r.command.joints.iter() {
            out(*u);
        }
        out(r.joint_scale);
    }
}
