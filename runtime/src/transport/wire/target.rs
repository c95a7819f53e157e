//! The target on the wire: the one place where a planar or a spatial target becomes the
//! six-degree-of-freedom fields of [`MeasurementMsg`](super::MeasurementMsg), and back.
//!
//! The wire always carries the target in SE(3) — position `p = (x, y, z)`, rotation matrix
//! `R` (row by row), body twist `(v, ω)` with `ṗ = R v`, `Ṙ = R [ω]×` — plus its yaw `ψ`
//! and the announced [`space`] it lives in:
//!
//! ```text
//! planar target (x, y, θ), u_d = (v₁, v₂, ω)  →  p = (x, y, 0),  R = R_z(θ),  ψ = θ,
//!                                                twist = (v₁, v₂, 0, 0, 0, ω),  space = 1
//! wire, space = 1                              →  (p_x, p_y, ψ),  u_d = (v_x, v_y, ω_z)
//! spatial target (R, p), (v, ω)                →  p, R, ψ = atan2(R₂₁, R₁₁),  (v, ω),  space = 2
//! wire, space = 2                              →  (R, p), (v, ω)  (ψ is not read)
//! ```
//!
//! **Why the yaw travels besides `R`.** A planar controller needs `θ` itself, bit for bit
//! (lockstep HIL must equal `companion sim`), and `θ` cannot be recovered exactly from a
//! rotation: `atan2(sin θ, cos θ)` differs from `θ` in the last bit for about 4 % of the
//! angles in `(−π, π]` (and for every angle outside it: a target that turns keeps an
//! unwrapped `θ`), `2 atan2(q_z, q_w)` of the rotation's quaternion for about 27 %
//! (`rotation_cannot_carry_the_yaw_exactly` measures both). So `ψ` carries the planar angle
//! exactly, and the planar reading takes nothing from `R`.
//!
//! **Why a rotation matrix and not a quaternion.** The core computes with matrices
//! ([`companion_core::so3`] says why), and a spatial lockstep run must equal the in-process
//! simulation bit for bit: matrix → quaternion → matrix is not exact (a bridge that holds a
//! quaternion converts it once, with the formula in `docs/book/src/bridge.md`).
//!
//! A spatial reading checks that `R` is a rotation (`max |RᵀR − I| ≤ 10⁻⁶`, `det R > 0`:
//! [`ROTATION_TOLERANCE`]); a planar reading checks that the target is planar (`z`, `v_z`,
//! `ω_x`, `ω_y` exactly 0; `R` is not read). A message that fails is malformed
//! ([`TargetError`], which the wire reports as
//! [`WireError::NotARotation`](super::WireError::NotARotation) or
//! [`WireError::NotPlanar`](super::WireError::NotPlanar)): dropped and counted like any
//! malformed measurement.

use companion_core::nalgebra::{Matrix3, Vector3, Vector6};
use companion_core::{so3, Planar, Pose, Pose3, Space, Spatial};

/// The `space` codes of both messages: where the target lives.
pub mod space {
    /// The plane, SE(2): the paper's §4 (the `rpr` arm).
    pub const PLANAR: u32 = 1;
    /// Space, SE(3): §5 (six- and seven-joint arms).
    pub const SPATIAL: u32 = 2;

    /// A code in words.
    pub fn describe(code: u32) -> String {
        match code {
            PLANAR => "planar (SE(2))".into(),
            SPATIAL => "spatial (SE(3))".into(),
            n => format!("unknown ({n})"),
        }
    }
}

/// How far from orthonormal a measured rotation may be: `max |RᵀR − I| ≤ 10⁻⁶` (a matrix
/// computed in `f64` from a normalised quaternion is within `10⁻¹⁵`; one from a `f32`
/// quaternion within `10⁻⁶`).
pub const ROTATION_TOLERANCE: f64 = 1e-6;

/// The target's fields of a measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WireTarget {
    /// `p = (x, y, z)` (m), fixed frame.
    pub position: [f64; 3],
    /// `R`, row by row.
    pub rotation: [f64; 9],
    /// `ψ` (rad): exact `θ` for a planar target; `atan2(R₂₁, R₁₁)` for a spatial one.
    pub yaw: f64,
    /// Body twist `(v_x, v_y, v_z, ω_x, ω_y, ω_z)` (m/s, rad/s).
    pub twist: [f64; 6],
}

/// A target space as it goes on the wire (implemented for [`Planar`] and [`Spatial`]).
/// Why a target on the wire is malformed (the wire counts it as a malformed measurement).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetError {
    /// A planar target off the plane (`z`, `v_z`, `ω_x` or `ω_y` not 0).
    NotPlanar,
    /// A spatial target whose finite rotation is not orthonormal ([`ROTATION_TOLERANCE`]).
    NotARotation,
}

pub trait WireSpace: Space<f64> {
    /// Its [`space`] code.
    const CODE: u32;

    /// The wire's fields of a target pose and body velocity.
    fn to_wire(pose: &Self::Pose, velocity: &Self::Vector) -> WireTarget;

    /// The target pose and body velocity of the wire's fields.
    ///
    /// # Errors
    /// [`TargetError`] (see the module docs).
    fn from_wire(t: &WireTarget) -> Result<(Self::Pose, Self::Vector), TargetError>;
}

fn rows(r: &Matrix3<f64>) -> [f64; 9] {
    [r[(0, 0)], r[(0, 1)], r[(0, 2)], r[(1, 0)], r[(1, 1)], r[(1, 2)], r[(2, 0)], r[(2, 1)], r[(2, 2)]]
}

impl WireSpace for Planar {
    const CODE: u32 = space::PLANAR;

    #[inline]
    fn to_wire(pose: &Pose<f64>, u: &Vector3<f64>) -> WireTarget {
        WireTarget {
            position: [pose.x, pose.y, 0.0],
            rotation: rows(&Pose3::from_planar(pose).rotation),
            yaw: pose.theta,
            twist: [u[0], u[1], 0.0, 0.0, 0.0, u[2]],
        }
    }

    #[inline]
    fn from_wire(t: &WireTarget) -> Result<(Pose<f64>, Vector3<f64>), TargetError> {
        // Exactly zero, as a planar plant writes them.
        let off_plane = [t.position[2], t.twist[2], t.twist[3], t.twist[4]];
        if off_plane.iter().any(|x| *x != 0.0) {
            return Err(TargetError::NotPlanar);
        }
        Ok((Pose::new(t.position[0], t.position[1], t.yaw), Vector3::new(t.twist[0], t.twist[1], t.twist[5])))
    }
}

impl WireSpace for Spatial {
    const CODE: u32 = space::SPATIAL;

    #[inline]
    fn to_wire(pose: &Pose3<f64>, xi: &Vector6<f64>) -> WireTarget {
        let r = &pose.rotation;
        WireTarget {
            position: [pose.translation[0], pose.translation[1], pose.translation[2]],
            rotation: rows(r),
            yaw: r[(1, 0)].atan2(r[(0, 0)]),
            twist: [xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]],
        }
    }

    #[inline]
    fn from_wire(t: &WireTarget) -> Result<(Pose3<f64>, Vector6<f64>), TargetError> {
        let r = Matrix3::from_row_slice(&t.rotation);
        // Non-finite entries are the law's business (a non-finite target); a finite matrix
        // must be a rotation.
        if r.iter().all(|x| x.is_finite()) && so3::orthonormality(&r) > ROTATION_TOLERANCE {
            return Err(TargetError::NotARotation);
        }
        let p = Vector3::new(t.position[0], t.position[1], t.position[2]);
        Ok((Pose3::new(r, p), Vector6::from_row_slice(&t.twist)))
    }
}

#[cfg(test)]
mod tests {
    use companion_core::nalgebra::Vector6;
    use companion_core::{Pose, Pose3};

    use super::*;

    /// A few thousand angles in and beyond (−π, π], and the special ones.
    fn angles() -> Vec<f64> {
        let mut a: Vec<f64> =
            (0..20_000).map(|i| -12.0 + f64::from(i) * 1.2e-3 + 1e-7 * f64::from(i % 7)).collect();
        a.extend([0.0, -0.0, core::f64::consts::PI, -core::f64::consts::PI, 1e-300, 7.0e8]);
        a
    }

    #[test]
    fn a_planar_target_round_trips_bit_for_bit() {
        for (k, th) in angles().into_iter().enumerate() {
            let x = k as f64 * 1e-3 - 3.7;
            let pose = Pose::new(x, 0.1 - x / 3.0, th);
            let u = Vector3::new(-th / 20.0, x, th.sin());
            let w = Planar::to_wire(&pose, &u);
            assert_eq!(w.position[2].to_bits(), 0);
            assert_eq!(w.twist[2..5], [0.0; 3]);
            let (p, v) = Planar::from_wire(&w).unwrap();
            let bits = |a: [f64; 3]| a.map(f64::to_bits);
            assert_eq!(bits([p.x, p.y, p.theta]), bits([pose.x, pose.y, pose.theta]), "θ = {th}");
            assert_eq!(bits([v[0], v[1], v[2]]), bits([u[0], u[1], u[2]]));
            // The rotation on the wire is the lifted pose's, R_z(θ).
            assert_eq!(Matrix3::from_row_slice(&w.rotation), Pose3::from_planar(&pose).rotation);
        }
    }

    #[test]
    fn rotation_cannot_carry_the_yaw_exactly() {
        // Why ψ travels: what fraction of the angles in (−π, π] a rotation matrix (atan2 of
        // its first column) or a unit quaternion (2 atan2(q_z, q_w)) gives back exactly.
        let inside: Vec<f64> = angles()
            .into_iter()
            .filter(|t| *t > -core::f64::consts::PI && *t <= core::f64::consts::PI)
            .collect();
        let (mut by_matrix, mut by_quaternion) = (0, 0);
        for &th in &inside {
            let r = Pose3::from_planar(&Pose::new(0.0, 0.0, th)).rotation;
            by_matrix += usize::from(r[(1, 0)].atan2(r[(0, 0)]).to_bits() != th.to_bits());
            let q = so3::to_quaternion(&r);
            by_quaternion += usize::from((2.0 * q[2].atan2(q[3])).to_bits() != th.to_bits());
        }
        let frac = |n: usize| n as f64 / inside.len() as f64;
        println!(
            "of {} angles in (−π, π]: {:.1} % not recovered from R, {:.1} % not from the quaternion",
            inside.len(),
            100.0 * frac(by_matrix),
            100.0 * frac(by_quaternion)
        );
        assert!(frac(by_matrix) > 0.01 && frac(by_quaternion) > 0.01);
    }

    #[test]
    fn a_spatial_target_round_trips_bit_for_bit() {
        let pose = Pose3::exp(&Vector6::new(0.3, -1.2, 0.45, 0.7, -0.2, 2.9));
        let xi = Vector6::new(0.1, 0.2, -0.3, 0.01, -0.02, 0.5);
        let w = Spatial::to_wire(&pose, &xi);
        assert_eq!(Spatial::from_wire(&w), Ok((pose, xi)));
        assert_eq!(w.yaw, pose.rotation[(1, 0)].atan2(pose.rotation[(0, 0)]));
        // Row by row: R₁₂ is the second number.
        assert_eq!(w.rotation[1], pose.rotation[(0, 1)]);
    }

    #[test]
    fn a_planar_target_lifted_is_the_same_spatial_target() {
        // The wire is one: a planar plant's message read by a spatial controller gives the
        // planar target lifted (z = 0, a rotation about z, twist (v₁, v₂, 0, 0, 0, ω)).
        let pose = Pose::new(2.6, 1.0, 0.4);
        let u = Vector3::new(0.0, -0.157, 0.02);
        let (p3, xi) = Spatial::from_wire(&Planar::to_wire(&pose, &u)).unwrap();
        assert_eq!(p3, Pose3::from_planar(&pose));
        assert_eq!(xi, Vector6::new(0.0, -0.157, 0.0, 0.0, 0.0, 0.02));
    }

    #[test]
    fn off_plane_targets_and_non_rotations_are_malformed() {
        let w = Planar::to_wire(&Pose::new(1.0, 2.0, 0.3), &Vector3::new(0.1, 0.0, 0.2));
        for i in [2usize, 3, 4] {
            let mut bad = w;
            bad.twist[i] = 1e-12;
            assert_eq!(Planar::from_wire(&bad), Err(TargetError::NotPlanar), "twist {i}");
        }
        assert_eq!(
            Planar::from_wire(&WireTarget { position: [1.0, 2.0, 0.5], ..w }),
            Err(TargetError::NotPlanar)
        );
        // The planar reading takes nothing from R.
        assert!(Planar::from_wire(&WireTarget { rotation: [0.0; 9], ..w }).is_ok());
        // A reflection, a scaled rotation, zeros: not rotations.
        let mut reflection = w;
        reflection.rotation[8] = -1.0;
        let mut scaled = w;
        scaled.rotation.iter_mut().for_each(|x| *x *= 1.001);
        for bad in [reflection, scaled, WireTarget { rotation: [0.0; 9], ..w }] {
            assert_eq!(Spatial::from_wire(&bad), Err(TargetError::NotARotation), "{bad:?}");
        }
        // Within the tolerance: accepted (a rotation from a f32 quaternion).
        let mut close = w;
        close.rotation[0] *= 1.0 + 4e-7;
        assert!(Spatial::from_wire(&close).is_ok());
        // Non-finite values pass through, for the law to report.
        let mut nan = w;
        nan.rotation[4] = f64::NAN;
        nan.position[2] = f64::NAN;
        assert!(Spatial::from_wire(&nan).is_ok_and(|(p, _)| !p.is_finite()));
        // ... but a planar target's z is exactly 0.
        assert_eq!(Planar::from_wire(&nan), Err(TargetError::NotPlanar));
    }
}
