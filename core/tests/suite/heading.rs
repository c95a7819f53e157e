//! The heading filter (beyond the paper, `companion_core::HeadingFilter`): the platform's law
//! sees the target with its heading lagging by `δ`, `θ̂̇_d = σ δ/(ξ + |δ|)`.
//!
//! Checked here: the filtered target moves as its body velocity says (by differences of
//! poses, not by the core's Lie formulas); it changes nothing, bit for bit, while the target
//! does not turn (the paper's trajectory 1); the lag follows the filter's equation to second
//! order in the period; and a target turning in place no longer drags the platform around it
//! while the arm keeps the tool on it.

use std::f64::consts::PI;

use crate::common::*;
use companion_core::secondary::{heading_filtered, heading_rates};
use companion_core::{ControlLaw, HeadingFilter, PaperRun, Params, Platform, PoseSc, Rpr, State};
use proptest::prelude::*;

const FILTER: HeadingFilter<f64> = HeadingFilter { rate: 0.1, xi: 0.2 };

fn with_filter(run: PaperRun, f: Option<HeadingFilter<f64>>) -> Params<f64, 3> {
    let mut p = Params::paper(run);
    p.secondary.heading_filter = f;
    p
}

proptest! {
    /// `r̂_bd(t) = r_bd(t) Rot(−δ(t))` with the target moving at `u_d` and the lag at `δ̇`:
    /// its body velocity by central differences of the poses is `heading_filtered`'s `û_d`.
    #[test]
    fn the_filtered_target_moves_as_its_body_velocity_says(
        r in pose_in(3.0, PI),
        u in vec3(-1.0, 1.0),
        lag in -3.0f64..3.0,
        lag_rate in -1.0f64..1.0,
    ) {
        let at = |t: f64| -> V3 {
            let r_d = flow(&r, &u, t);
            mul(&r_d, &V3::new(0.0, 0.0, -(lag + lag_rate * t)))
        };
        let h = 1e-6;
        let rate = (at(h) - at(-h)) / (2.0 * h);
        let numeric = body(&at(0.0), &rate);
        let turn = u[2] - lag_rate;
        let (pose_hat, u_hat) = heading_filtered(&PoseSc::new(pose(&r)), &u, lag, turn);
        let exact = at(0.0);
        prop_assert!((v3(&pose_hat.pose) - exact).map(|x| x.abs()).max() < 1e-12);
        let (s, c) = pose_hat.sc;
        prop_assert!((s - exact[2].sin()).abs() < 1e-12 && (c - exact[2].cos()).abs() < 1e-12);
        prop_assert!((u_hat - numeric).norm() < 1e-6, "{u_hat} against {numeric}");
    }
}

#[test]
fn the_rates_are_the_bounded_filter() {
    // θ̂̇ = σ δ/(ξ + |δ|): linear near 0 with gain σ/ξ, σ at most, odd; δ̇ = ω_d − θ̂̇.
    let f = FILTER;
    let (turn, lag_rate) = heading_rates(1e-6, 0.3, &f);
    assert!((turn / (1e-6 * 0.1 / 0.2) - 1.0).abs() < 1e-5);
    assert_eq!(lag_rate, 0.3 - turn);
    let (big, _) = heading_rates(1e3, 0.0, &f);
    assert!(big < 0.1 && big > 0.0999);
    assert_eq!(heading_rates(-0.7, 0.0, &f).0, -heading_rates(0.7, 0.0, &f).0);
}

/// Every command of `law` on the paper's start, target moving at `u_d`, `steps` of `h`.
fn commands<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    u_d: &dyn Fn(f64) -> V3,
    h: f64,
    steps: usize,
) -> (Vec<companion_core::Command<f64, 3>>, f64, Vec<f64>) {
    let mut plant = Plant::paper_start(V3::new(2.6, 1.0, 0.0), Q::new(0.0, 0.35, 0.0), 0.0);
    let mut state = State::new();
    let mut out = Vec::with_capacity(steps);
    let mut lags = Vec::with_capacity(steps);
    let mut e_p = f64::NAN;
    for _ in 0..steps {
        let meas = plant.measurement(u_d);
        let o = law
            .step(&mut state, &meas, h)
            .unwrap_or_else(|r| panic!("rejected at {}: {:?}", plant.t, r.error));
        out.push(o.command);
        lags.push(state.heading_lag);
        e_p = o.diagnostics.e_p.norm();
        plant.advance(P::KIND, &o.command, u_d, h, 1);
    }
    (out, e_p, lags)
}

#[test]
fn a_target_that_does_not_turn_sees_no_filter() {
    // Trajectory 1 keeps the target's heading: δ stays 0 and every command is the paper's,
    // bit for bit, in every run.
    for run in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
        let paper = unicycle_law(with_filter(run, None));
        let filtered = unicycle_law(with_filter(run, Some(FILTER)));
        let (a, _, _) = commands(&paper, &trajectory_1, 1e-3, 10_000);
        let (b, _, lags) = commands(&filtered, &trajectory_1, 1e-3, 10_000);
        assert!(lags.iter().all(|l| *l == 0.0), "{run:?}: the lag moved");
        assert!(a == b, "{run:?}: a command differs");
    }
}

/// A target turning in place, trajectory 2's rotations: `ω_d = (π²/20) cos(π t/2)`.
fn turning(t: f64) -> V3 {
    V3::new(0.0, 0.0, PI * PI / 20.0 * (PI * t / 2.0).cos())
}

/// The filter's lag by RK4 at a fine step, for the target `turning`.
fn lag_reference(f: &HeadingFilter<f64>, t_end: f64) -> f64 {
    let field = |t: f64, d: f64| heading_rates(d, turning(t)[2], f).1;
    let (mut t, mut d, h) = (0.0, 0.0, 1e-5);
    while t < t_end - 1e-12 {
        let k1 = field(t, d);
        let k2 = field(t + h / 2.0, d + h / 2.0 * k1);
        let k3 = field(t + h / 2.0, d + h / 2.0 * k2);
        let k4 = field(t + h, d + h * k3);
        d += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        t += h;
    }
    d
}

#[test]
fn the_lag_follows_its_equation_to_second_order() {
    // The law advances δ by the midpoint rule with the target's extrapolated yaw rate; its
    // error after 3 s halves twice per halving of the period.
    let f = HeadingFilter { rate: 0.3, xi: 0.05 };
    let law = omni_law(with_filter(PaperRun::A, Some(f)));
    let reference = lag_reference(&f, 3.0);
    let errors: Vec<f64> = [4e-3_f64, 2e-3, 1e-3]
        .iter()
        .map(|&h| {
            let steps = (3.0 / h).round() as usize;
            let (_, _, lags) = commands(&law, &turning, h, steps);
            (lags[steps - 1] - reference).abs()
        })
        .collect();
    assert!(reference.abs() > 0.05, "the lag is {reference}: the test would show nothing");
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!((3.3..4.8).contains(&ratio), "errors {errors:?}: ratio {ratio}");
    }
    assert!(errors[2] < 1e-6, "errors {errors:?}");
}

#[test]
fn a_target_turning_in_place_no_longer_drags_the_platform() {
    // The target turns ±18° about its own vertical every 4 s. The paper's law swings the
    // companion frame |r_*| (1.5 m) around it; with the filter the platform barely moves and
    // the arm holds the tool on the target all the same.
    let path = |f: Option<HeadingFilter<f64>>| {
        let law = unicycle_law(with_filter(PaperRun::A, f));
        let (cmds, e_p, _) = commands(&law, &turning, 1e-3, 30_000);
        (cmds[20_000..].iter().map(|c| c.platform.v.abs() * 1e-3).sum::<f64>(), e_p)
    };
    let (paper, _) = path(None);
    // Gain σ/ξ = 0.1/s: the filter passes 6 % of the 18° swings at π/2 rad/s.
    let (filtered, e_p) = path(Some(HeadingFilter { rate: 0.05, xi: 0.5 }));
    assert!(paper > 10.0, "the paper's platform drove {paper} m in the last 10 s");
    assert!(filtered < 0.1 * paper, "filtered {filtered} m against the paper's {paper} m");
    assert!(e_p < 1e-4, "e_p {e_p} at 30 s");
}
