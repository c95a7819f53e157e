//! Saturation (end of §3.4.2, SPEC §3): with velocity limits the platform inputs and `α̇`
//! are all divided by one common factor `s ≥ 1` — the command keeps the direction of the
//! unsaturated one — `s` is `diagnostics.saturation`, it is the smallest such factor (one
//! component sits on its limit), every limit is met, and the state is driven by the
//! saturated velocities (`α`, and `r̃_b` through the applied `ū_b`, eq. 28).
//!
//! Each case runs the same step on a law without limits and on one with random limits
//! (some infinite) and compares. Scaling by `1/s` is one multiplication per component, so
//! the comparisons hold to a few ulps: 1e−12 relative.

use crate::common::*;
use companion_core::nalgebra::{Matrix3, Vector2};
use companion_core::{Command, ControlLaw, PaperRun, Params, Platform, PlatformKind, Rpr, VelocityLimits};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

const DT: f64 = 1e-3;
const REL: f64 = 1e-12;

fn limit() -> impl Strategy<Value = f64> {
    prop_oneof![1 => Just(f64::INFINITY), 3 => 0.01..2.0f64]
}

fn limits() -> impl Strategy<Value = VelocityLimits<f64>> {
    (limit(), limit(), limit(), limit(), limit()).prop_map(
        |(forward, lateral, angular, alpha_rate, steering_rate)| VelocityLimits {
            forward,
            lateral,
            angular,
            alpha_rate,
            steering_rate,
        },
    )
}

/// The limited quantities of each platform with their limits: `(value, limit)` pairs.
fn limited(
    kind: PlatformKind,
    c: &Command<f64, 3>,
    alpha_rate: &Vector2<f64>,
    l: &VelocityLimits<f64>,
) -> Vec<(f64, f64)> {
    let p = &c.platform;
    match kind {
        PlatformKind::Unicycle => vec![(p.v, l.forward), (p.omega, l.angular), (alpha_rate[0], l.alpha_rate)],
        PlatformKind::Car => vec![
            (p.v, l.forward),
            (alpha_rate[0], l.alpha_rate),
            (alpha_rate[1], l.alpha_rate),
            (p.v_xi, l.steering_rate),
        ],
        PlatformKind::Omni => vec![(p.v, l.forward), (p.v_lat, l.lateral), (p.omega, l.angular)],
    }
}

fn check<P: Platform<f64>>(
    free: &ControlLaw<f64, P, Rpr<f64>, 3>,
    limited_law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
) -> Result<(), TestCaseError> {
    let lim = limited_law.params().velocity_limits;
    let (u, u_next) = step_point(free, pt, DT)?;
    let (s, s_next) = step_point(limited_law, pt, DT)?;
    let factor = s.diagnostics.saturation;
    // Where the unlimited law meets the turn-per-step bound (rare: α̇ above π/dt) it is not
    // the unsaturated reference; that bound has its own test.
    prop_assume!(u.diagnostics.saturation == 1.0);

    // The factor is the largest ratio |component| / limit of the unsaturated command (≥ 1),
    // except the car's steering rate: only its feed-forward ξ̇_f = ∂ξ_f/∂α α̇ scales with the
    // platform, its feedback −k (ξ − ξ_f) does not; the factor puts |fb + ff/s| on the
    // limit, and where the feedback alone exceeds it (same sign) the platform waits.
    let mut ratio = limited(P::KIND, &u.command, &u.diagnostics.alpha_rate, &lim)
        .iter()
        .filter(|(x, l)| {
            !(P::KIND == PlatformKind::Car && *l == lim.steering_rate && *x == u.command.platform.v_xi)
        })
        .fold(0.0f64, |m, (x, l)| m.max(x.abs() / l));
    let (fb, ff) = if P::KIND == PlatformKind::Car {
        let alpha = pt.state.alpha;
        let fb = -crate::common::car().k * (pt.meas.steering - xi_f_reference(&alpha));
        (fb, u.command.platform.v_xi - fb)
    } else {
        (0.0, 0.0)
    };
    let l_xi = lim.steering_rate;
    let mut stopped = false;
    if P::KIND == PlatformKind::Car && (fb + ff).abs() > l_xi {
        if fb * ff >= 0.0 && fb.abs() >= l_xi {
            stopped = true;
        } else {
            let room = if fb * ff >= 0.0 { l_xi - fb.abs() } else { l_xi + fb.abs() };
            ratio = ratio.max(ff.abs() / room);
        }
    }
    if stopped {
        prop_assert_eq!(factor, 3.0e38);
        let c = &s.command.platform;
        prop_assert!(c.v == 0.0 && s.diagnostics.alpha_rate == Vector2::zeros());
        check_close_scalar("v_ξ at its limit", c.v_xi.abs(), l_xi, REL, 0.0)?;
        return Ok(());
    }
    check_close_scalar("saturation factor", factor, ratio.max(1.0), 1e-11, 0.0)?;

    // Every component divided by the same factor: the direction is kept.
    let (a, b) = (&u.command.platform, &s.command.platform);
    for (name, x, y) in [("v", a.v, b.v), ("v_lat", a.v_lat, b.v_lat), ("ω", a.omega, b.omega)] {
        check_close_scalar(name, y, x / factor, REL, 1e-300)?;
    }
    // (Against the feedback, a factor set by another limit can leave |fb + ff/s| above the
    // steering's limit when |fb| alone exceeds it: then v_ξ is held at the limit.)
    check_close_scalar("v_ξ", b.v_xi, (fb + ff / factor).clamp(-l_xi, l_xi), 1e-11, 1e-300)?;
    check_close("α̇", &s.diagnostics.alpha_rate, &(u.diagnostics.alpha_rate / factor), REL, 1e-300)?;
    check_close("ū_b", &s.diagnostics.u_bar, &(u.diagnostics.u_bar / factor), 1e-11, 1e-300)?;

    // Every limit met; when saturated, one of them exactly.
    let after = limited(P::KIND, &s.command, &s.diagnostics.alpha_rate, &lim);
    let worst = after.iter().fold(0.0f64, |m, (x, l)| m.max(x.abs() / l));
    prop_assert!(worst <= 1.0 + 1e-11, "a limit is exceeded: {after:?}");
    if factor > 1.0 {
        prop_assert!((worst - 1.0).abs() < 1e-11, "saturated by {factor} but no component on its limit");
    }

    // The state integrates the saturated velocities: α with α̇, r̃_b with the applied ū_b.
    let a0 = pt.state.alpha;
    let da = s.diagnostics.alpha_rate * DT;
    check_close("α", &s_next.alpha, &Vector2::new(wrap(a0[0] + da[0]), wrap(a0[1] + da[1])), 1e-12, 1.0)?;
    if limited_law.params().secondary.weight != companion_core::Weight::Constant(1.0) {
        let r = v3(&pt.state.r_tilde);
        let q_mat = Matrix3::new(1.0, 0.0, -r[1], 0.0, 1.0, r[0], 0.0, 0.0, 1.0);
        let mut d_applied = s.diagnostics.u_bar - u.diagnostics.u_bar;
        if P::KIND == PlatformKind::Car {
            // The car's companion frame also moves with v (ξ − ξ_f) (57), v saturated too.
            let pf = f_reference(PlatformKind::Car, &pt.state.alpha);
            let z = (s.command.platform.v - u.command.platform.v)
                * (pt.meas.steering - xi_f_reference(&pt.state.alpha));
            d_applied += V3::new(pf[1] * z, -pf[0] * z, z);
        }
        let want = v3(&u_next.r_tilde) - q_mat * d_applied * DT;
        check_close("r̃_b", &v3(&s_next.r_tilde), &V3::new(want[0], want[1], wrap(want[2])), 1e-12, 1.0)?;
    }
    Ok(())
}

fn with_limits(run: PaperRun, l: Option<VelocityLimits<f64>>) -> Params<f64, 3> {
    let mut p = paper(run);
    if let Some(l) = l {
        p.velocity_limits = l;
    }
    p
}

fn run(k: usize) -> PaperRun {
    [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D][k]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn unicycle(pt in point(0.01), l in limits(), k in 0usize..4) {
        check(&unicycle_law(with_limits(run(k), None)), &unicycle_law(with_limits(run(k), Some(l))), &pt)?;
    }

    #[test]
    fn car(pt in point(0.01), l in limits(), k in 0usize..4) {
        check(&car_law(with_limits(run(k), None)), &car_law(with_limits(run(k), Some(l))), &pt)?;
    }

    #[test]
    fn omnidirectional(pt in point(0.01), l in limits(), k in 0usize..4) {
        check(&omni_law(with_limits(run(k), None)), &omni_law(with_limits(run(k), Some(l))), &pt)?;
    }
}

/// Unlimited limits never saturate; the paper preset has none.
#[test]
fn no_limits_means_no_saturation() {
    let p = Params::<f64, 3>::paper(PaperRun::A);
    assert_eq!(p.velocity_limits, VelocityLimits::unlimited());
    let l = VelocityLimits::<f64>::unlimited();
    assert!([l.forward, l.lateral, l.angular, l.alpha_rate, l.steering_rate]
        .iter()
        .all(|x| *x == f64::INFINITY));
}
