//! Parameter validation (SPEC §6, STYLE "validate once"): every [`Rule`] is triggered by
//! a parameter that breaks it, and the error names that parameter (and joint); the paper's
//! §4.3 preset holds the SPEC §4 values, validates for runs (a)–(d) on every platform, and
//! reports — without rejecting — the one condition the paper's own values break
//! (`δ₂⁺⁺ = 0.0333 < δ₂ = 0.035`, SPEC §3).

use companion_core::{
    Bound, CarLike, ControlLaw, Omnidirectional, PaperRun, ParamError, Params, Pose, Precompensation, Rpr,
    Rule, Unicycle, VelocityLimits, Warning, Weight, WeightMargins,
};

type P = Params<f64, 3>;

const PI: f64 = core::f64::consts::PI;

fn validate(p: &P) -> Result<(), ParamError> {
    ControlLaw::new(*p, Unicycle::paper(), Rpr::paper()).map(|_| ())
}

fn scalar(param: &'static str, rule: Rule) -> ParamError {
    ParamError::new(param, rule)
}

fn joint(param: &'static str, j: usize, rule: Rule) -> ParamError {
    ParamError::joint(param, j, rule)
}

fn margins_of(p: &mut P) -> &mut WeightMargins<f64, 3> {
    match &mut p.secondary.weight {
        Weight::Filtered { margins, .. }
        | Weight::PerJoint { margins, .. }
        | Weight::FromFilteredJoints { margins } => margins,
        Weight::Constant(_) => panic!("no margins"),
    }
}

/// One case: a run to start from, a change that breaks one rule, the expected error.
type Case = (PaperRun, fn(&mut P), ParamError);

fn cases() -> Vec<Case> {
    use PaperRun::*;
    use Rule::*;
    vec![
        // Joint limits.
        (A, |p| p.joint_limits.lower[0] = f64::NAN, joint("joint_limits.lower", 0, NonFinite)),
        (A, |p| p.joint_limits.upper[2] = f64::INFINITY, joint("joint_limits.upper", 2, NonFinite)),
        (A, |p| p.joint_limits.lower[1] = 0.7, joint("joint_limits.lower", 1, EmptyInterval)),
        (A, |p| p.joint_limits.lower[2] = 2.0, joint("joint_limits.lower", 2, EmptyInterval)),
        // Primary task.
        (
            A,
            |p| p.primary.target_in_effector = Pose::new(0.5, f64::NAN, 0.0),
            scalar("target_in_effector", NonFinite),
        ),
        (A, |p| p.primary.penalty_weight[1] = 0.0, joint("penalty_weight", 1, NotPositive)),
        (A, |p| p.primary.penalty_weight[2] = f64::NAN, joint("penalty_weight", 2, NonFinite)),
        (A, |p| p.primary.penalty_margin[0] = -0.1, joint("penalty_margin", 0, NotPositive)),
        (A, |p| p.primary.penalty_margin[2] = PI / 2.0, joint("penalty_margin", 2, PenaltyMarginTooWide)),
        (A, |p| p.primary.penalty_margin[1] = 0.36, joint("penalty_margin", 1, PenaltyMarginTooWide)),
        (A, |p| p.primary.regularisation_gain = -0.2, scalar("regularisation_gain", Negative)),
        (A, |p| p.primary.regularisation_gain = f64::INFINITY, scalar("regularisation_gain", NonFinite)),
        (A, |p| p.primary.regularisation_decay = -1.0, scalar("regularisation_decay", Negative)),
        (A, |p| p.primary.filter_sigma = 0.0, scalar("filter_sigma", NotPositive)),
        (A, |p| p.primary.filter_xi = -1.0, scalar("filter_xi", NotPositive)),
        (A, |p| p.primary.gain[2] = 0.0, joint("gain", 2, NotPositive)),
        (A, |p| p.primary.gain[0] = -3.0, joint("gain", 0, NotPositive)),
        (A, |p| p.primary.null_space_gain = -1.0, scalar("null_space_gain", Negative)),
        (A, |p| p.primary.null_space_gain = f64::NAN, scalar("null_space_gain", NonFinite)),
        // Secondary task.
        (
            A,
            |p| p.secondary.preferred_pose = Pose::new(f64::INFINITY, 0.0, 0.0),
            scalar("preferred_pose", NonFinite),
        ),
        (A, |p| p.secondary.gamma_1 = 0.0, scalar("gamma_1", NotPositive)),
        (B, |p| p.secondary.gamma_2 = f64::NAN, scalar("gamma_2", NonFinite)),
        (B, |p| p.secondary.rest_sigma[1] = 0.0, joint("rest_sigma", 1, NotPositive)),
        (B, |p| p.secondary.rest_xi = 0.0, scalar("rest_xi", NotPositive)),
        (C, |p| p.secondary.weight = Weight::Constant(1.5), scalar("weight.psi", NotInUnitInterval)),
        (C, |p| p.secondary.weight = Weight::Constant(-0.1), scalar("weight.psi", NotInUnitInterval)),
        (C, |p| p.secondary.weight = Weight::Constant(f64::NAN), scalar("weight.psi", NonFinite)),
        (
            B,
            |p| {
                if let Weight::Filtered { lambda, .. } = &mut p.secondary.weight {
                    *lambda = 0.0
                }
            },
            scalar("weight.lambda", NotPositive),
        ),
        (
            B,
            |p| {
                if let Weight::Filtered { xi, .. } = &mut p.secondary.weight {
                    *xi = -1.0
                }
            },
            scalar("weight.xi", NotPositive),
        ),
        (B, |p| margins_of(p).lower[1] = 0.0, joint("weight.margins.lower", 1, NotPositive)),
        (B, |p| margins_of(p).lower_inner[0] = f64::NAN, joint("weight.margins.lower_inner", 0, NonFinite)),
        (B, |p| margins_of(p).upper[2] = -0.1, joint("weight.margins.upper", 2, NotPositive)),
        (B, |p| margins_of(p).upper_inner[1] = 0.0, joint("weight.margins.upper_inner", 1, NotPositive)),
        (
            B,
            |p| {
                let m = margins_of(p);
                m.lower_inner[0] = m.lower[0];
            },
            joint("weight.margins.lower_inner", 0, WeightMarginOrder),
        ),
        (
            C,
            |p| {
                let m = margins_of(p);
                m.upper_inner[1] = 2.0 * m.upper[1];
            },
            joint("weight.margins.upper_inner", 1, WeightMarginOrder),
        ),
        (
            D,
            |p| {
                let m = margins_of(p);
                m.lower[2] = 2.0;
                m.upper[2] = 1.2;
            },
            joint("weight.margins.lower", 2, WeightMarginOrder),
        ),
        (B, |p| p.secondary.k_bar[2] = 0.0, joint("k_bar", 2, NotPositive)),
        (B, |p| p.secondary.d[0] = -1.0, joint("d", 0, NotPositive)),
        (B, |p| p.secondary.mu = 0.0, scalar("mu", NotPositive)),
        (B, |p| p.secondary.mu = f64::INFINITY, scalar("mu", NonFinite)),
        (
            B,
            |p| p.secondary.precompensation = Precompensation::Full40 { nu: 0.0 },
            scalar("precompensation.nu", NotPositive),
        ),
        // Decomposition (51) is exact only for Ψ ≡ 1.
        (
            B,
            |p| p.secondary.precompensation = Precompensation::Full51,
            scalar("precompensation", Decomposition51NeedsPsiOne),
        ),
        (
            A,
            |p| p.secondary.weight = Weight::Constant(0.5),
            scalar("precompensation", Decomposition51NeedsPsiOne),
        ),
        // Velocity limits (+∞ means none) and the time step.
        (A, |p| p.velocity_limits.forward = f64::NAN, scalar("velocity_limits.forward", NonFinite)),
        (A, |p| p.velocity_limits.lateral = 0.0, scalar("velocity_limits.lateral", NotPositive)),
        (A, |p| p.velocity_limits.angular = -1.0, scalar("velocity_limits.angular", NotPositive)),
        (A, |p| p.velocity_limits.alpha_rate = 0.0, scalar("velocity_limits.alpha_rate", NotPositive)),
        (
            A,
            |p| p.velocity_limits.steering_rate = f64::NAN,
            scalar("velocity_limits.steering_rate", NonFinite),
        ),
        (A, |p| p.max_time_step = 0.0, scalar("max_time_step", NotPositive)),
        (A, |p| p.max_time_step = f64::NAN, scalar("max_time_step", NonFinite)),
        // The period bound: 0.1 / (largest rate) = 10 ms with the paper's rates (σ/ξ = 10/s).
        (A, |p| p.max_time_step = 0.0101, scalar("max_time_step", PeriodTooLong)),
        (A, |p| p.max_time_step = 2.0, scalar("max_time_step", TooLarge(Bound::Time))),
        (A, |p| p.primary.gain[1] = 20.0, scalar("max_time_step", PeriodTooLong)),
        // Upper bounds that keep every step computable (in f32 too).
        (
            A,
            |p| p.primary.regularisation_gain = 1e300,
            scalar("regularisation_gain", TooLarge(Bound::Magnitude)),
        ),
        (A, |p| p.primary.gain[0] = 1e7, joint("gain", 0, TooLarge(Bound::Magnitude))),
        (
            A,
            |p| p.secondary.preferred_pose = Pose::new(-1e30, 0.0, 0.0),
            scalar("preferred_pose", TooLarge(Bound::Length)),
        ),
        (A, |p| p.joint_limits.upper[1] = 1e4, joint("joint_limits.upper", 1, TooLarge(Bound::Length))),
        (B, |p| p.secondary.rest_reach = 0.0, scalar("rest_reach", NotPositive)),
        (B, |p| p.secondary.rest_reach = 1e9, scalar("rest_reach", TooLarge(Bound::Length))),
        (A, |p| p.max_delay = -1e-3, scalar("max_delay", Negative)),
        (A, |p| p.max_delay = 5.0, scalar("max_delay", TooLarge(Bound::Time))),
        (A, |p| p.max_turn_per_step = 0.0, scalar("max_turn_per_step", NotPositive)),
        (A, |p| p.max_turn_per_step = 4.0, scalar("max_turn_per_step", TooLarge(Bound::Length))),
    ]
}

#[test]
fn each_broken_rule_is_named() {
    for (i, (run, change, want)) in cases().into_iter().enumerate() {
        let mut p = P::paper(run);
        assert_eq!(p.validate(), Ok(()), "case {i}: the starting preset must be valid");
        change(&mut p);
        assert_eq!(p.validate(), Err(want), "case {i}");
        assert_eq!(validate(&p), Err(want), "case {i} through ControlLaw::new");
        // The message names the parameter (and the joint, counted from 1).
        let msg = format!("{want}");
        assert!(msg.contains(want.param), "{msg}");
        if let Some(j) = want.joint {
            assert!(msg.contains(&format!("joint {}", j + 1)), "{msg}");
        }
    }
}

/// The same rules for the other two weights that carry margins.
#[test]
fn weight_margins_are_checked_for_every_weight_kind() {
    let m = WeightMargins::paper(&P::paper_limits(), &P::paper_q_star());
    for weight in
        [Weight::PerJoint { margins: m, lambda: 1.66, xi: 1.0 }, Weight::FromFilteredJoints { margins: m }]
    {
        let mut p = P::paper(PaperRun::D);
        p.secondary.weight = weight;
        assert_eq!(p.validate(), Ok(()));
        margins_of(&mut p).upper_inner[0] = margins_of(&mut p).upper[0];
        assert_eq!(p.validate(), Err(joint("weight.margins.upper_inner", 0, Rule::WeightMarginOrder)));
    }
    let mut p = P::paper(PaperRun::D);
    p.secondary.weight = Weight::PerJoint { margins: m, lambda: -1.0, xi: 1.0 };
    assert_eq!(p.validate(), Err(scalar("weight.lambda", Rule::NotPositive)));
}

/// The heading filter's rate and `ξ`: positive and bounded, named as the config keys.
#[test]
fn the_heading_filter_is_checked() {
    use companion_core::HeadingFilter;
    for (rate, xi, name, rule) in [
        (0.0, 0.2, "heading_rate", Rule::NotPositive),
        (f64::NAN, 0.2, "heading_rate", Rule::NonFinite),
        (2e6, 0.2, "heading_rate", Rule::TooLarge(Bound::Magnitude)),
        (0.1, -1.0, "heading_xi", Rule::NotPositive),
        (0.1, f64::INFINITY, "heading_xi", Rule::NonFinite),
    ] {
        let mut p = P::paper(PaperRun::A);
        p.secondary.heading_filter = Some(HeadingFilter { rate, xi });
        assert_eq!(p.validate(), Err(scalar(name, rule)), "{rate} {xi}");
    }
    let mut p = P::paper(PaperRun::A);
    p.secondary.heading_filter = Some(HeadingFilter { rate: 0.05, xi: 0.2 });
    assert_eq!(p.validate(), Ok(()));
    // Its gain σ/ξ counts in the period bound: 0.1/(10/0.01) here.
    p.secondary.heading_filter = Some(HeadingFilter { rate: 10.0, xi: 0.01 });
    assert!((p.period_bound() - 1e-4).abs() < 1e-12, "{}", p.period_bound());
}

/// Every `Rule` variant is covered by the table above (or by the platform and arm checks
/// below): a new rule must get a case.
#[test]
fn every_rule_is_exercised() {
    let mut seen: Vec<Rule> = cases().iter().map(|c| c.2.rule).collect();
    seen.push(Rule::Transversality); // below and in transverse.rs
    seen.push(Rule::Geometry); // below
    seen.push(Rule::TooLarge(Bound::TransverseSize)); // below
                                                      // In arms.rs (arm descriptions) and spatial.rs (r*_ed in space).
    seen.extend([
        Rule::NotOrthonormal,
        Rule::NotUnitVector,
        Rule::TooFewJoints,
        Rule::HomeOutsideLimits,
        Rule::NotPlanar,
    ]);
    for rule in [
        Rule::NonFinite,
        Rule::NotPositive,
        Rule::Negative,
        Rule::NotInUnitInterval,
        Rule::EmptyInterval,
        Rule::PenaltyMarginTooWide,
        Rule::WeightMarginOrder,
        Rule::Transversality,
        Rule::Decomposition51NeedsPsiOne,
        Rule::Geometry,
        Rule::TooLarge(Bound::Time),
        Rule::TooLarge(Bound::Magnitude),
        Rule::TooLarge(Bound::Length),
        Rule::TooLarge(Bound::TransverseSize),
        Rule::PeriodTooLong,
        Rule::NotOrthonormal,
        Rule::NotUnitVector,
        Rule::TooFewJoints,
        Rule::HomeOutsideLimits,
        Rule::NotPlanar,
    ] {
        assert!(seen.contains(&rule), "{rule:?} has no case");
        // Exhaustiveness: this match fails to compile when a rule is added.
        match rule {
            Rule::NonFinite
            | Rule::NotPositive
            | Rule::Negative
            | Rule::NotInUnitInterval
            | Rule::EmptyInterval
            | Rule::PenaltyMarginTooWide
            | Rule::WeightMarginOrder
            | Rule::Transversality
            | Rule::Decomposition51NeedsPsiOne
            | Rule::Geometry
            | Rule::TooLarge(_)
            | Rule::PeriodTooLong
            | Rule::NotOrthonormal
            | Rule::NotUnitVector
            | Rule::TooFewJoints
            | Rule::HomeOutsideLimits
            | Rule::NotPlanar => {}
        }
        assert!(!format!("{rule}").is_empty());
    }
}

#[test]
fn platform_and_arm_rules() {
    let p = P::paper(PaperRun::C);
    let bad_car = CarLike::new(0.3, [1.0, 1.0, 1.0], 1.0);
    assert_eq!(ControlLaw::new(p, bad_car, Rpr::paper()).unwrap_err(), scalar("eta", Rule::Transversality));
    let arm = |l: f64, l_e: f64| ControlLaw::new(p, Omnidirectional, Rpr { l, l_e }).map(|_| ());
    assert_eq!(arm(-0.4, 0.15), Err(scalar("l", Rule::Geometry)));
    assert_eq!(arm(0.4, -0.01), Err(scalar("l_e", Rule::Geometry)));
    assert_eq!(arm(f64::NAN, 0.15), Err(scalar("l", Rule::NonFinite)));
    assert_eq!(arm(0.4, f64::INFINITY), Err(scalar("l_e", Rule::NonFinite)));
    assert_eq!(arm(0.0, 0.0), Ok(()), "zero offsets are a valid geometry");
    assert_eq!(
        ControlLaw::new(p, Unicycle::new(0.0, 0.4), Rpr::paper()).unwrap_err(),
        scalar("epsilon_1", Rule::NotPositive)
    );
    // Sizes that would overflow a step (ε³ of Lemma 2 in f32) are refused when built.
    assert_eq!(
        ControlLaw::new(p, CarLike::new(1e30, [2.0, 3.0, 2.0], 5.0), Rpr::paper()).unwrap_err(),
        scalar("epsilon", Rule::TooLarge(Bound::TransverseSize))
    );
    assert_eq!(
        ControlLaw::new(p, Unicycle::new(20.0, 0.4), Rpr::paper()).unwrap_err(),
        scalar("epsilon_1", Rule::TooLarge(Bound::TransverseSize))
    );
    assert_eq!(arm(1e30, 0.15), Err(scalar("l", Rule::TooLarge(Bound::Length))));
    // The period bound follows the rates: halving the fastest rate doubles it.
    let mut slow = P::paper(PaperRun::B);
    assert!((slow.period_bound() - 0.01).abs() < 1e-15, "0.1 / (σ/ξ = 10/s)");
    slow.primary.filter_sigma = 5.0;
    slow.secondary.rest_sigma = crate::common::V3::repeat(5.0);
    assert!((slow.period_bound() - 0.02).abs() < 1e-15, "then the gain 3/s and σ/ξ = 5/s: 0.1/5");
    slow.max_time_step = 0.02;
    assert_eq!(slow.validate(), Ok(()));
}

/// The preset holds the values listed in SPEC §4 (read from the SPEC, not from the code).
#[test]
fn paper_preset_holds_the_spec_values() {
    let close = |a: f64, b: f64| (a - b).abs() < 1e-15;
    for run in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
        let p = P::paper(run);
        let lim = &p.joint_limits;
        assert!(close(lim.lower[0], -PI / 3.0) && close(lim.upper[0], PI / 3.0));
        assert!(lim.lower[1] == 0.0 && close(lim.upper[1], 0.7));
        assert!(close(lim.lower[2], -PI / 2.0) && close(lim.upper[2], PI / 2.0));
        let pr = &p.primary;
        assert_eq!(pr.target_in_effector, Pose::new(0.5, 0.0, 0.0), "r*_ed = (X*, 0, 0), X* = 0.5");
        assert_eq!(pr.penalty_weight, crate::common::Q::repeat(1.0), "αᵢ = 1");
        for i in 0..3 {
            assert!(close(pr.penalty_margin[i], 0.05 * (lim.upper[i] - lim.lower[i])), "δᵢ = 0.05 (q⁺ − q⁻)");
        }
        assert!(pr.regularisation_gain == 0.2 && pr.regularisation_decay == 1.0, "Γ(t) = 0.2 e^(−t) I₃");
        assert!(pr.filter_sigma == 10.0 && pr.filter_xi == 1.0, "q̂ filter (26): σ = 10, ξ = 1");
        assert_eq!(pr.gain, crate::common::Q::repeat(3.0), "G = −3 I₃ (gain 3)");
        let s = &p.secondary;
        assert!(close(s.preferred_pose.x, -(0.5 + 0.15 + 0.4 + 0.45)) && s.preferred_pose.y == 0.0);
        assert!(s.gamma_1 == 1.0 && s.gamma_2 == 1.0);
        assert!(s.rest_sigma == crate::common::V3::repeat(10.0) && s.rest_xi == 1.0);
        assert_eq!(s.k_bar, crate::common::V3::new(1.0, 1.0, 100.0));
        assert_eq!(s.d, crate::common::V3::repeat(1.0));
        assert_eq!(s.mu, 1e-4);
        assert!(!s.psi_rate_in_drift, "the paper preset leaves Ψ̇ (h_s1 − h_s2) out (SPEC §3)");
        assert_eq!(p.velocity_limits, VelocityLimits::unlimited());
        match run {
            PaperRun::A => {
                assert_eq!(s.weight, Weight::Constant(1.0));
                assert_eq!(s.precompensation, Precompensation::Full51);
            }
            _ => {
                let Weight::Filtered { margins: m, lambda, xi } = s.weight else { panic!("(53) expected") };
                assert!(lambda == 1.66 && xi == 1.0);
                let q_star = [0.0, 0.45, 0.0];
                for (i, q_s) in q_star.iter().enumerate() {
                    assert!(close(m.lower[i], 0.2 * (q_s - lim.lower[i])));
                    assert!(close(m.upper[i], 0.2 * (lim.upper[i] - q_s)));
                    assert!(close(m.lower_inner[i], m.lower[i] * 2.0 / 3.0));
                    assert!(close(m.upper_inner[i], m.upper[i] * 2.0 / 3.0));
                }
                let want = match run {
                    PaperRun::B => Precompensation::Full40 { nu: 1e-4 },
                    PaperRun::C => Precompensation::Off,
                    _ => Precompensation::Partial,
                };
                assert_eq!(s.precompensation, want);
            }
        }
    }
    assert_eq!(Unicycle::<f64>::paper(), Unicycle::new(0.2, 0.4));
    assert_eq!(Rpr::<f64>::paper(), Rpr { l: 0.4, l_e: 0.15 });
}

/// The preset validates for every run and platform (f64 and f32) and reports exactly the
/// paper's q₂ exception: `δ₂⁺⁺ = ⅔ · 0.2 · (0.7 − 0.45) = 0.0333 < δ₂ = 0.05 · 0.7 = 0.035`.
/// Run (a) uses no weight margins (Ψ ≡ 1), so it has nothing to report.
#[test]
fn paper_preset_validates_and_reports_the_q2_exception() {
    let mut b = P::paper(PaperRun::B);
    let delta_2 = b.primary.penalty_margin[1];
    let delta_2_pp = margins_of(&mut b).upper_inner[1];
    assert!((delta_2 - 0.035).abs() < 1e-15 && (delta_2_pp - 0.2 * 0.25 * 2.0 / 3.0).abs() < 1e-15);
    assert!(delta_2_pp < delta_2);
    for run in [PaperRun::A, PaperRun::B, PaperRun::C, PaperRun::D] {
        let p = P::paper(run);
        assert_eq!(p.validate(), Ok(()));
        let uni = ControlLaw::new(p, Unicycle::paper(), Rpr::paper()).expect("valid");
        assert!(ControlLaw::new(p, CarLike::new(0.3, [1.0, 2.0, 1.0], 1.0), Rpr::paper()).is_ok());
        assert!(ControlLaw::new(p, Omnidirectional, Rpr::paper()).is_ok());
        assert!(ControlLaw::new(Params::<f32, 3>::paper(run), Unicycle::<f32>::paper(), Rpr::<f32>::paper())
            .is_ok());
        let want: &[Warning] =
            if run == PaperRun::A { &[] } else { &[Warning::UpperWeightMarginInsidePenalty(1)] };
        assert_eq!(p.warnings().as_slice(), want, "{run:?}");
        assert_eq!(uni.warnings().as_slice(), want);
        assert_eq!(Params::<f32, 3>::paper(run).warnings().as_slice(), want, "f32 {run:?}");
        for w in want {
            assert!(format!("{w}").contains("joint 2"));
        }
    }
    // A lower margin inside the penalty band is reported too.
    let mut p = P::paper(PaperRun::B);
    let delta = p.primary.penalty_margin[0];
    margins_of(&mut p).lower_inner[0] = delta;
    assert_eq!(p.validate(), Ok(()));
    assert_eq!(
        p.warnings().as_slice(),
        &[Warning::LowerWeightMarginInsidePenalty(0), Warning::UpperWeightMarginInsidePenalty(1)]
    );
}
