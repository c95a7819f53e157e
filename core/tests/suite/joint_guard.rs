//! The joint guard: within one step no joint covers more than `κ` of its distance to the
//! limit it moves towards, no joint exceeds its velocity limit, and the joint velocities of
//! the arm law (30) are divided by one common factor (direction kept) when needed.

use crate::common::*;
use companion_core::nalgebra::SVector;
use companion_core::{PaperRun, Params};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn joints_never_cover_more_than_kappa_of_their_room(
        pt in point(0.002),
        kappa in 0.01..1.0f64,
        vmax in 0.5..50.0f64,
        dt in 1e-4..0.01f64,
    ) {
        let mut guarded = paper(PaperRun::A);
        guarded.joint_step_fraction = kappa;
        guarded.joint_velocity_limits = SVector::repeat(vmax);
        let mut free = paper(PaperRun::A);
        free.joint_step_fraction = 1.0;
        let (mut sa, mut sb) = (pt.state, pt.state);
        let a = unicycle_law(guarded).step(&mut sa, &pt.meas, dt);
        let b = unicycle_law(free).step(&mut sb, &pt.meas, dt);
        let (Ok(a), Ok(b)) = (a, b) else { return Err(TestCaseError::reject("rejected point")) };
        let lim = Params::<f64, 3>::paper_limits();
        let q = pt.meas.joints;
        for i in 0..3 {
            let u = a.command.joints[i];
            let room = if u > 0.0 { lim.upper[i] - q[i] } else { q[i] - lim.lower[i] };
            prop_assert!((u * dt).abs() <= kappa * room * (1.0 + 1e-12), "joint {i}: moves {} of room {room}", u * dt);
            prop_assert!(u.abs() <= vmax * (1.0 + 1e-12));
        }
        // One common factor: both laws divide the same (30) velocities.
        let ua = a.command.joints * a.diagnostics.joint_scale;
        let ub = b.command.joints * b.diagnostics.joint_scale;
        check_close("u_q · joint_scale", &ua, &ub, 1e-12, 1e-12)?;
        prop_assert!(a.diagnostics.joint_scale >= 1.0);
        // The platform command is not touched by the joint guard.
        prop_assert_eq!(a.command.platform, b.command.platform);
    }
}
