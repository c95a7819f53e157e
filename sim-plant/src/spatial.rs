//! The plant of a spatial run (§5): a wheeled platform carrying an arm described as a
//! [`Chain`] (six to eight joints), and a target in SE(3).
//!
//! ```text
//! platform   as the planar plant: unicycle, car-like (55), omnidirectional (3)
//! arm        q̇ = u_q
//! target     lifted: planar motion of §4.3 (integrated) + z_d(t) in closed form
//!            file:   r_d(t) = r_d(t_k) exp((t − t_k) ξ_k), exact
//! ```
//!
//! The platform, the arm's joints and the lifted target's planar motion are integrated by
//! *the same* RK4 step under a zero-order hold as the planar plant (the crate's `dynamics`
//! module, with its actuator lag and wheel-scale error); the planar motion of a lifted
//! target is therefore bit for bit the planar plant's. What is new here is only the arm's
//! geometry (the chain's frames, for the record and the true tracking error) and the
//! target's third dimension. Measurement noise is not simulated for spatial runs (refused).

use companion_core::nalgebra::{SVector, Vector3, Vector6};
use companion_core::{so3, Chain, Command, Measurement, PlatformKind, Pose3, Spatial};

use crate::dynamics::{Continuous, Trig};
use crate::error::{AdvanceError, PlantError, Rule};
use crate::initial::InitialConditions;
use crate::plant::{PlantConfig, PlantState, Simulated};
use crate::spatial_target::SpatialTarget;
use crate::trajectory::{PiecewiseTrajectory, Trajectory};

/// The simulated spatial mobile manipulator and its target (module docs). (Beside the planar
/// [`crate::Plant`], which is generic over the paper's closed-form planar arms and integrates
/// its target with the robot; both share the state, the start, the step and the interface.)
#[derive(Clone, Debug)]
pub struct SpatialPlant<const N: usize> {
    config: PlantConfig,
    chain: Chain<f64, N>,
    target: SpatialTarget,
    /// The planar motion the shared RK4 step integrates (none for a file's target).
    planar: Trajectory,
    /// A file target's pose at the start of each segment (and the final pose).
    starts: Vec<Pose3<f64>>,
    x: Continuous<N>,
    state: PlantState<N, Spatial>,
    dt: Option<f64>,
    trig: Trig,
}

impl<const N: usize> SpatialPlant<N> {
    /// A plant at its initial conditions.
    ///
    /// # Errors
    /// A bad plant parameter (noise is refused: `noise` with [`Rule::Unsupported`]), an
    /// invalid chain, a non-finite initial value.
    pub fn new(
        config: PlantConfig,
        chain: Chain<f64, N>,
        initial: &InitialConditions<N, Spatial>,
        target: SpatialTarget,
    ) -> Result<Self, PlantError> {
        config.validate()?;
        if config.imperfections.noise.is_some() {
            return Err(PlantError::Invalid { param: "noise", rule: Rule::Unsupported, value: 1.0 });
        }
        chain.validate().map_err(PlantError::Arm)?;
        initial.validate()?;
        let r_d0 = initial.target;
        let (planar, starts) = match &target {
            SpatialTarget::Lifted(l) => (Trajectory::from(l.planar), Vec::new()),
            SpatialTarget::Piecewise(p) => {
                let none = PiecewiseTrajectory::new(Vec::new()).map_err(|_| PlantError::Invalid {
                    param: "target",
                    rule: Rule::NonFinite,
                    value: f64::NAN,
                })?;
                (Trajectory::Piecewise(none), p.segment_starts(&r_d0))
            }
        };
        // The planar target the shared step integrates: the projection of r_d(0).
        let yaw = r_d0.rotation[(1, 0)].atan2(r_d0.rotation[(0, 0)]);
        let x = Continuous {
            base: initial.base.to_vector(),
            steering: initial.steering,
            joints: initial.joints,
            target: Vector3::new(r_d0.translation[0], r_d0.translation[1], yaw),
            platform_lag: SVector::zeros(),
            joint_lag: SVector::zeros(),
        };
        let mut plant = Self {
            config,
            chain,
            target,
            planar,
            starts,
            x,
            state: PlantState {
                t: 0.0,
                step: 0,
                base: initial.base,
                steering: initial.steering,
                joints: initial.joints,
                target: r_d0,
                target_velocity: Vector6::zeros(),
                applied: Command::zero(),
                command: Command::zero(),
            },
            dt: None,
            trig: Trig::default(),
        };
        plant.state.target_velocity = plant.target_twist(0.0, 0.0);
        Ok(plant)
    }

    /// The arm.
    pub fn chain(&self) -> &Chain<f64, N> {
        &self.chain
    }

    /// The target.
    pub fn target(&self) -> &SpatialTarget {
        &self.target
    }

    /// The time (s).
    pub fn time(&self) -> f64 {
        self.state.t
    }

    /// Every joint's moving frame (after its motion `Jᵢ(qᵢ)`) and the end effector, in the
    /// world: `r_b · M · O₁ J₁(q₁) ⋯ Oᵢ Jᵢ(qᵢ)` and `… · E`.
    pub fn frames(&self) -> ([Pose3<f64>; N], Pose3<f64>) {
        let world = Pose3::from_planar(&self.state.base);
        let mut f = self.chain.mount;
        let mut links = [Pose3::identity(); N];
        for (i, j) in self.chain.joints.iter().enumerate() {
            f = f.compose(&j.origin).compose(&j.motion(self.state.joints[i]));
            links[i] = world.compose(&f);
        }
        (links, world.compose(&f.compose(&self.chain.tool)))
    }

    /// The target's pose at `t` from the integrated planar state (lifted) or in closed form.
    fn target_pose(&self, t: f64, planar: &Vector3<f64>) -> Pose3<f64> {
        match &self.target {
            SpatialTarget::Lifted(l) => {
                let (s, c) = libm::sincos(planar[2]);
                Pose3::new(so3::about_axis(2, s, c), Vector3::new(planar[0], planar[1], l.z(t)))
            }
            SpatialTarget::Piecewise(p) => p.pose(&self.starts, t),
        }
    }

    /// The body twist at `t`, the planar piece chosen at `t_piece` (a step's midpoint, as the
    /// planar plant does).
    fn target_twist(&self, t: f64, t_piece: f64) -> Vector6<f64> {
        match &self.target {
            SpatialTarget::Lifted(l) => {
                let u = self.planar.piece(t_piece).velocity(t);
                Vector6::new(u[0], u[1], l.z_rate(t), 0.0, 0.0, u[2])
            }
            SpatialTarget::Piecewise(p) => p.velocity(t_piece),
        }
    }

    /// The platform kind.
    pub fn platform(&self) -> PlatformKind {
        self.config.platform
    }
}

impl<const N: usize> Simulated<N> for SpatialPlant<N> {
    type Space = Spatial;

    /// What the controller sees: the true state (no noise in spatial runs).
    fn measure(&self) -> Measurement<f64, N, Spatial> {
        self.state.measurement()
    }

    /// The true state.
    fn truth(&self) -> &PlantState<N, Spatial> {
        &self.state
    }

    /// The end effector in the world: `r_b · r_be(q)` (the last of [`frames`](Self::frames),
    /// to the bit).
    fn end_effector(&self) -> Pose3<f64> {
        Pose3::from_planar(&self.state.base).compose(&self.chain.end_effector(&self.state.joints))
    }

    /// The true tracking error `e_p = (p̃, log R̃)` of `r̃ = (r*_ed)⁻¹ r_ed`,
    /// `r_ed = r_be(q)⁻¹ r_bd`, from the exact state (core's `spatial` module docs).
    fn tracking_error(&self, target_in_effector: &Pose3<f64>) -> Vector6<f64> {
        let world = Pose3::from_planar(&self.state.base);
        let effector = world.compose(&self.chain.end_effector(&self.state.joints));
        let r = target_in_effector.inverse().compose(&effector.inverse().compose(&self.state.target));
        let phi = so3::log(&r.rotation);
        Vector6::new(r.translation[0], r.translation[1], r.translation[2], phi[0], phi[1], phi[2])
    }

    /// One step of `dt` seconds in which `previous` acts for the first `delay` seconds and
    /// `command` for the rest (the real-time HIL plant: a command takes effect when it
    /// arrives); `delay = 0` is [`try_advance`](Self::try_advance) exactly.
    ///
    /// # Errors
    /// As [`try_advance`](Self::try_advance), and a delay that is not in `[0, dt)`; the state
    /// is left as it was.
    fn try_advance_delayed(
        &mut self,
        previous: &Command<f64, N>,
        command: &Command<f64, N>,
        delay: f64,
        dt: f64,
    ) -> Result<(), AdvanceError> {
        let model = self.config.model(&self.planar);
        let n = self.state.step;
        let (x, applied, t1) =
            model.period(&mut self.dt, (n, &self.x), (previous, command, delay), dt, &mut self.trig)?;
        let target = (self.target_pose(t1, &x.target), self.target_twist(t1, t1 + 0.5 * dt));
        self.state = PlantState::after((n, t1), &x, target, applied, command);
        self.x = x;
        Ok(())
    }
}

/// The lowest and highest point the chain's end effector can reach, with a target
/// `reach_beyond` metres beyond it (m above the ground): a necessary bound — the mount's
/// height plus or minus the sum of every link's offset, the tool's and the prismatic
/// joints' travel.
pub fn vertical_reach<const N: usize>(chain: &Chain<f64, N>, reach_beyond: f64) -> (f64, f64) {
    let mut r = chain.tool.translation.norm() + reach_beyond.abs();
    for j in &chain.joints {
        // Every offset can point anywhere once the joints before it turn.
        r += j.origin.translation.norm();
        if j.kind == companion_core::JointKind::Prismatic {
            r += j.lower.abs().max(j.upper.abs());
        }
    }
    let z = chain.mount.translation[2];
    (z - r, z + r)
}

#[cfg(test)]
mod tests {
    use companion_core::{PlatformCommand, Pose};

    use super::*;
    use crate::spatial_target::LiftedTrajectory;
    use crate::trajectory::{paper_initial, PaperTrajectory};
    use crate::Plant;

    fn ur5_plant(kind: PlatformKind, traj: PaperTrajectory) -> SpatialPlant<6> {
        let chain = Chain::<f64, 6>::ur5();
        let lifted = LiftedTrajectory::new(traj, 0.9);
        let initial =
            InitialConditions::<6, Spatial>::in_space(Pose::identity(), lifted.initial_r_bd(), chain.home());
        SpatialPlant::new(PlantConfig::new(kind), chain, &initial, SpatialTarget::Lifted(lifted)).unwrap()
    }

    /// The planar plant of the paper's arm on `traj`.
    fn paper_plant(kind: PlatformKind, traj: PaperTrajectory) -> Plant<companion_core::Rpr<f64>, 3> {
        let arm = companion_core::Rpr::paper();
        Plant::new(PlantConfig::new(kind), arm, paper_initial(traj), Trajectory::from(traj)).unwrap()
    }

    fn command(k: usize) -> (Command<f64, 3>, Command<f64, 6>) {
        let s = (k as f64 * 0.37).sin();
        let platform = PlatformCommand { v: 0.5 * s, v_lat: 0.2, omega: 0.3 - s, v_xi: 0.1 * s };
        (
            Command { platform, joints: SVector::<f64, 3>::repeat(0.1 * s) },
            Command { platform, joints: SVector::<f64, 6>::repeat(0.1 * s) },
        )
    }

    /// The platform and the lifted target's planar motion are the planar plant's, bit for
    /// bit, on every platform and both trajectories.
    #[test]
    fn the_planar_part_is_the_planar_plants_bit_for_bit() {
        for kind in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
            for traj in [PaperTrajectory::One, PaperTrajectory::Two] {
                let mut planar = paper_plant(kind, traj);
                let mut spatial = ur5_plant(kind, traj);
                for k in 0..7000 {
                    let (c3, c6) = command(k);
                    planar.advance(&c3, 1e-3);
                    spatial.try_advance(&c6, 1e-3).unwrap();
                    let (p, s) = (planar.truth(), spatial.truth());
                    assert_eq!(p.base, s.base, "{kind:?} {traj:?} step {k}");
                    assert_eq!(p.steering, s.steering);
                    assert_eq!(p.target.x, s.target.translation[0]);
                    assert_eq!(p.target.y, s.target.translation[1]);
                    assert_eq!(p.target_velocity[0], s.target_velocity[0]);
                    assert_eq!(p.target_velocity[2], s.target_velocity[5]);
                    assert_eq!(s.joints[0], p.joints[0]);
                }
            }
        }
    }

    /// A step in which the previous command acts first (the real-time HIL's delay) is the
    /// planar plant's delayed step, bit for bit; a delay outside `[0, dt)` is refused and
    /// leaves the state as it was.
    #[test]
    fn the_delayed_step_is_the_planar_plants_bit_for_bit() {
        for kind in [PlatformKind::Unicycle, PlatformKind::Car, PlatformKind::Omni] {
            let traj = PaperTrajectory::One;
            let mut planar = paper_plant(kind, traj);
            let mut spatial = ur5_plant(kind, traj);
            for k in 1..3000 {
                let ((p3, p6), (c3, c6)) = (command(k - 1), command(k));
                let delay = 1e-3 * (k % 10) as f64 / 10.0;
                planar.try_advance_delayed(&p3, &c3, delay, 1e-3).unwrap();
                spatial.try_advance_delayed(&p6, &c6, delay, 1e-3).unwrap();
                let (p, s) = (planar.truth(), spatial.truth());
                assert_eq!(p.base, s.base, "{kind:?} step {k}");
                assert_eq!(p.steering, s.steering);
                assert_eq!(s.joints[0], p.joints[0]);
            }
            let before = *spatial.truth();
            let c = command(0).1;
            assert!(spatial.try_advance_delayed(&c, &c, 1e-3, 1e-3).is_err());
            assert!(spatial.try_advance_delayed(&c, &c, -1e-9, 1e-3).is_err());
            assert_eq!(*spatial.truth(), before);
        }
    }

    /// The lifted target's height and its twist: `z_d(t)` exactly, `ż_d` in the twist, the
    /// frame level; the joints move at the command.
    #[test]
    fn the_lifted_target_rises_and_falls() {
        let mut p = ur5_plant(PlatformKind::Unicycle, PaperTrajectory::Two);
        let mut c = Command::<f64, 6>::zero();
        c.joints[2] = 0.1;
        for _ in 0..2500 {
            p.try_advance(&c, 1e-3).unwrap();
        }
        let s = p.truth();
        let t = s.t;
        assert_eq!(t, 2.5);
        let z = 0.9 + 0.05 * (2.0 * core::f64::consts::PI * t / 10.0).sin();
        assert!((s.target.translation[2] - z).abs() < 1e-15);
        assert!(
            (s.target_velocity[2]
                - 0.05 * 0.2 * core::f64::consts::PI * (0.2 * core::f64::consts::PI * t).cos())
            .abs()
                < 1e-15
        );
        assert_eq!(s.target.rotation[(2, 2)], 1.0);
        assert!((s.joints[2] - (core::f64::consts::FRAC_PI_2 + 0.25)).abs() < 1e-12);
    }

    /// The frames are the chain's: the last link composed with the tool is the end
    /// effector, and `e_p` is zero where the arm holds the target at `r*_ed`.
    #[test]
    fn frames_and_the_true_error() {
        let chain = Chain::<f64, 7>::panda();
        let q = chain.home();
        let base = Pose::new(0.3, -0.2, 0.7);
        let star = Pose3::translation(0.0, 0.0, 0.2);
        let r_bd = chain.end_effector(&q).compose(&star);
        let target =
            SpatialTarget::Piecewise(crate::PiecewiseTrajectory::<Spatial>::new(Vec::new()).unwrap());
        let initial = InitialConditions::<7, Spatial>::in_space(base, r_bd, q);
        let p = SpatialPlant::new(PlantConfig::new(PlatformKind::Omni), chain, &initial, target).unwrap();
        let (links, effector) = p.frames();
        let last = links[6].compose(&chain.tool);
        assert!((last.translation - effector.translation).norm() < 1e-15);
        assert_eq!(p.end_effector(), effector, "the same products");
        let direct = Pose3::from_planar(&base).compose(&chain.end_effector(&q));
        assert!((direct.translation - effector.translation).norm() < 1e-14);
        assert!(p.tracking_error(&star).norm() < 1e-14, "{}", p.tracking_error(&star));
        let measured = p.measure();
        assert_eq!(measured.joints, q);
        assert_eq!(measured.target_velocity, Vector6::zeros());
    }

    #[test]
    fn noise_and_bad_steps_are_refused() {
        let chain = Chain::<f64, 6>::ur5();
        let lifted = LiftedTrajectory::new(PaperTrajectory::One, 0.9);
        let initial =
            InitialConditions::<6, Spatial>::in_space(Pose::identity(), lifted.initial_r_bd(), chain.home());
        let noisy = PlantConfig::new(PlatformKind::Unicycle).with_imperfections(crate::Imperfections {
            noise: Some(crate::Noise::default()),
            ..Default::default()
        });
        let e = SpatialPlant::new(noisy, chain, &initial, SpatialTarget::Lifted(lifted)).unwrap_err();
        assert!(e.to_string().contains("`noise`"), "{e}");
        let mut p = ur5_plant(PlatformKind::Unicycle, PaperTrajectory::One);
        let mut c = Command::<f64, 6>::zero();
        c.joints[0] = f64::NAN;
        assert_eq!(p.try_advance(&c, 1e-3), Err(AdvanceError::NonFiniteCommand));
        assert_eq!(p.truth().step, 0);
    }

    #[test]
    fn the_reach_bound_contains_the_home_and_is_finite() {
        let chain = Chain::<f64, 6>::ur5();
        let (lo, hi) = vertical_reach(&chain, 0.2);
        let z = chain.end_effector(&chain.home()).translation[2];
        assert!(lo < z && z < hi, "{lo} {z} {hi}");
        // UR5: 0.5 m up, links ≈ 1.1 m, tool 0, target 0.2 m beyond.
        assert!(hi < 2.0 && lo > -1.0, "{lo} {hi}");
    }
}
