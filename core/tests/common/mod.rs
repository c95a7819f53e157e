//! Helpers shared by the core's integration tests.
//!
//! Everything here is written *independently* of the core, from the paper's formulas, so
//! that a test compares the core against a second derivation and never against itself:
//!
//! - SE(2) through 3×3 homogeneous matrices (§2.1) and `std`'s trigonometry (the core
//!   uses closed forms and `libm`);
//! - closed-form curves whose body velocity is derived by hand, `u = R̄(θ)ᵀ ṙ` (eq. 3);
//! - the SE(2) exponential, for curves of constant body velocity (a unicycle or car arc);
//! - central finite differences and a "relative error with a floor" comparison;
//! - an exact kinematic plant (eqs. 3, 55 and `q̇ = u_q`) integrated by RK4 under a
//!   zero-order-hold command, for the closed-loop tests;
//! - proptest strategies (all randomness lives there, so failures shrink and replay).
//!
//! Not every test binary uses every helper.
#![allow(dead_code)]

use companion_core::nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};
use companion_core::{
    CarLike, Command, ControlLaw, Measurement, Omnidirectional, Output, PaperRun, Params, Platform,
    PlatformKind, Pose, Real, Rpr, State, Unicycle,
};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

pub type V3 = Vector3<f64>;
pub type Q = SVector<f64, 3>;

// ---------------------------------------------------------------------------------------
// SE(2), independently: homogeneous matrices. Angles are *not* wrapped (θ_a + θ_b), so
// that curves stay continuous and can be differentiated numerically.

/// The homogeneous matrix `[R(θ) p; 0 1]` of a pose `(x, y, θ)`.
pub fn hom(r: &V3) -> Matrix3<f64> {
    let (s, c) = r[2].sin_cos();
    Matrix3::new(c, -s, r[0], s, c, r[1], 0.0, 0.0, 1.0)
}

/// Group product `a b`, eq. (1), via the matrix product.
pub fn mul(a: &V3, b: &V3) -> V3 {
    let m = hom(a) * hom(b);
    V3::new(m[(0, 2)], m[(1, 2)], a[2] + b[2])
}

/// Group inverse, via the matrix inverse.
pub fn inv(a: &V3) -> V3 {
    let m = hom(a).try_inverse().expect("a homogeneous matrix is invertible");
    V3::new(m[(0, 2)], m[(1, 2)], -a[2])
}

/// `R̄(θ) = diag(R(θ), 1)`.
pub fn rbar(theta: f64) -> Matrix3<f64> {
    let (s, c) = theta.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// The body velocity of a curve with pose `r` and coordinate rate `ṙ`: `u = R̄(θ)ᵀ ṙ`.
pub fn body(r: &V3, r_dot: &V3) -> V3 {
    rbar(r[2]).transpose() * r_dot
}

/// `d_γ(a, b)`, eq. (2), from the relative pose `a⁻¹ b`.
pub fn d_gamma(a: &V3, b: &V3, gamma: f64) -> f64 {
    let r = mul(&inv(a), b);
    (r[0] * r[0] + r[1] * r[1] + 2.0 * gamma * (1.0 - r[2].cos())).sqrt()
}

/// The SE(2) exponential of the twist `u = (v₁, v₂, ω)`: the pose reached from the
/// identity after one second at constant body velocity `u`.
pub fn exp(u: &V3) -> V3 {
    let w = u[2];
    // V(w) = [sin w / w, −(1 − cos w)/w; (1 − cos w)/w, sin w / w], with series near 0.
    let (a, b) = if w.abs() < 1e-6 {
        (1.0 - w * w / 6.0, w / 2.0 - w * w * w / 24.0)
    } else {
        (w.sin() / w, (1.0 - w.cos()) / w)
    };
    V3::new(a * u[0] - b * u[1], b * u[0] + a * u[1], w)
}

/// Pose `r` moved for `t` seconds at constant body velocity `u`: `r · exp(t u)`.
pub fn flow(r: &V3, u: &V3, t: f64) -> V3 {
    mul(r, &exp(&(u * t)))
}

pub fn v3(p: &Pose<f64>) -> V3 {
    V3::new(p.x, p.y, p.theta)
}

pub fn pose(v: &V3) -> Pose<f64> {
    Pose::new(v[0], v[1], v[2])
}

/// An angle wrapped to (−π, π] (independently of the core's `wrap_angle`).
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * core::f64::consts::PI);
    if w > core::f64::consts::PI {
        w - 2.0 * core::f64::consts::PI
    } else {
        w
    }
}

// ---------------------------------------------------------------------------------------
// Closed-form curves.

/// A smooth curve on SE(2) with closed-form coordinates
/// `r_i(t) = p0_i + v_i t + a_i sin(w_i t + φ_i)`, so `ṙ_i = v_i + a_i w_i cos(w_i t + φ_i)`.
#[derive(Clone, Copy, Debug)]
pub struct Curve {
    pub p0: V3,
    pub v: V3,
    pub a: V3,
    pub w: V3,
    pub phi: V3,
}

impl Curve {
    pub fn at(&self, t: f64) -> V3 {
        V3::from_fn(|i, _| self.p0[i] + self.v[i] * t + self.a[i] * (self.w[i] * t + self.phi[i]).sin())
    }

    pub fn rate(&self, t: f64) -> V3 {
        V3::from_fn(|i, _| self.v[i] + self.a[i] * self.w[i] * (self.w[i] * t + self.phi[i]).cos())
    }

    /// The body velocity, derived by hand: `u = R̄(θ)ᵀ ṙ`.
    pub fn body(&self, t: f64) -> V3 {
        body(&self.at(t), &self.rate(t))
    }
}

pub fn vec3(lo: f64, hi: f64) -> impl Strategy<Value = V3> {
    (lo..hi, lo..hi, lo..hi).prop_map(|(a, b, c)| V3::new(a, b, c))
}

/// A pose with `|x|, |y| ≤ pos` and `|θ| ≤ ang`.
pub fn pose_in(pos: f64, ang: f64) -> impl Strategy<Value = V3> {
    (-pos..pos, -pos..pos, -ang..ang).prop_map(|(x, y, t)| V3::new(x, y, t))
}

pub fn curve() -> impl Strategy<Value = Curve> {
    (pose_in(3.0, 3.0), vec3(-1.0, 1.0), vec3(-1.0, 1.0), vec3(-2.0, 2.0), vec3(-3.0, 3.0))
        .prop_map(|(p0, v, a, w, phi)| Curve { p0, v, a, w, phi })
}

// ---------------------------------------------------------------------------------------
// Finite differences and comparisons.

/// Central difference `(f(x + h) − f(x − h)) / 2h` of a matrix-valued function. Its error
/// is `h² f'''/6` (truncation) plus about `ε |f| / h` (rounding, ε = 2.2e−16): for
/// functions whose values and derivatives are O(1), `h = 1e−5` balances the two at ~1e−10.
pub fn central<const R: usize, const C: usize>(
    f: impl Fn(f64) -> SMatrix<f64, R, C>,
    x: f64,
    h: f64,
) -> SMatrix<f64, R, C> {
    (f(x + h) - f(x - h)) / (2.0 * h)
}

pub fn central_scalar(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
    (f(x + h) - f(x - h)) / (2.0 * h)
}

/// `max |got − want| ≤ rtol · max(max |want|, floor)`: a relative error with a floor, so
/// that a derivative that happens to be near zero is not held to an impossible relative
/// accuracy.
pub fn check_close<const R: usize, const C: usize>(
    what: &str,
    got: &SMatrix<f64, R, C>,
    want: &SMatrix<f64, R, C>,
    rtol: f64,
    floor: f64,
) -> Result<(), TestCaseError> {
    let err = (got - want).amax();
    let scale = want.amax().max(floor);
    if err.is_nan() || err > rtol * scale {
        return Err(TestCaseError::fail(format!(
            "{what}: error {err:.3e} > {rtol:.1e} * {scale:.3e}\n got  {got}\n want {want}"
        )));
    }
    Ok(())
}

/// Element by element: `|got_ij − want_ij| ≤ rtol · max(|want_ij|, floor)`. For matrices
/// whose entries have very different sizes (a joint-limit penalty makes one diagonal entry
/// of `∂e_m/∂q` large), so that a large entry does not loosen the check of a small one.
pub fn check_close_elementwise<const R: usize, const C: usize>(
    what: &str,
    got: &SMatrix<f64, R, C>,
    want: &SMatrix<f64, R, C>,
    rtol: f64,
    floor: f64,
) -> Result<(), TestCaseError> {
    for i in 0..R {
        for j in 0..C {
            let (g, w) = (got[(i, j)], want[(i, j)]);
            let err = (g - w).abs();
            if err.is_nan() || err > rtol * w.abs().max(floor) {
                return Err(TestCaseError::fail(format!(
                    "{what}[{i},{j}]: got {g:e}, want {w:e} (error {err:.3e})\n got  {got}\n want {want}"
                )));
            }
        }
    }
    Ok(())
}

pub fn check_close_scalar(
    what: &str,
    got: f64,
    want: f64,
    rtol: f64,
    floor: f64,
) -> Result<(), TestCaseError> {
    let err = (got - want).abs();
    let scale = want.abs().max(floor);
    if err.is_nan() || err > rtol * scale {
        return Err(TestCaseError::fail(format!(
            "{what}: error {err:.3e} > {rtol:.1e} * {scale:.3e} (got {got:e}, want {want:e})"
        )));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// The paper's arm and limits, and laws for the three platforms.

pub const PI: f64 = core::f64::consts::PI;

/// Paper limits: q₁ ∈ (−π/3, π/3), q₂ ∈ (0, 0.7), q₃ ∈ (−π/2, π/2).
pub const LOWER: [f64; 3] = [-PI / 3.0, 0.0, -PI / 2.0];
pub const UPPER: [f64; 3] = [PI / 3.0, 0.7, PI / 2.0];

/// Joints strictly inside the paper's limits, at least `frac` of the range away from each.
pub fn joints_inside(frac: f64) -> impl Strategy<Value = Q> {
    let r = |i: usize| {
        let m = frac * (UPPER[i] - LOWER[i]);
        (LOWER[i] + m)..(UPPER[i] - m)
    };
    (r(0), r(1), r(2)).prop_map(|(a, b, c)| Q::new(a, b, c))
}

/// The car-like platform used by these tests: Lemma 2's function with `η = (1, 2, 1)`
/// (6·2·1 = 12 > 8·1 + 1·2 = 10) and `ε = 0.4`, steering gain `k = 10 /s`.
pub fn car() -> CarLike<f64> {
    CarLike::new(0.4, [1.0, 2.0, 1.0], 10.0)
}

pub fn unicycle_law(params: Params<f64, 3>) -> ControlLaw<f64, Unicycle<f64>, Rpr<f64>, 3> {
    ControlLaw::new(params, Unicycle::paper(), Rpr::paper()).expect("valid parameters")
}

pub fn car_law(params: Params<f64, 3>) -> ControlLaw<f64, CarLike<f64>, Rpr<f64>, 3> {
    ControlLaw::new(params, car(), Rpr::paper()).expect("valid parameters")
}

pub fn omni_law(params: Params<f64, 3>) -> ControlLaw<f64, Omnidirectional, Rpr<f64>, 3> {
    ControlLaw::new(params, Omnidirectional, Rpr::paper()).expect("valid parameters")
}

/// The paper's parameters with [`Discretisation::Sampled`](companion_core::Discretisation):
/// the law evaluated at the measured state, where the tests re-derive its formulas. The
/// turn-per-step bound (a sampling bound, not in the paper) is as loose as validation
/// allows, so that random points far from the target rarely meet it; tests that need the
/// paper's formulas exactly skip points where it acts (`saturation > 1`). The hold-aware
/// default is tested by its own properties in `hold.rs`.
pub fn paper(run: PaperRun) -> Params<f64, 3> {
    let mut p = Params::paper(run);
    p.discretisation = companion_core::Discretisation::Sampled;
    p.max_turn_per_step = PI;
    p
}

/// [`paper`] in `f32`.
pub fn paper_f32(run: PaperRun) -> Params<f32, 3> {
    let mut p = Params::paper(run);
    p.discretisation = companion_core::Discretisation::Sampled;
    p.max_turn_per_step = core::f32::consts::PI;
    p
}

/// The body velocity `u_b` a platform command gives, with steering `ξ` (eqs. 3, 55).
pub fn base_velocity(kind: PlatformKind, cmd: &Command<f64, 3>, xi: f64) -> V3 {
    let p = &cmd.platform;
    match kind {
        PlatformKind::Unicycle => V3::new(p.v, 0.0, p.omega),
        PlatformKind::Car => V3::new(p.v, 0.0, p.v * xi),
        PlatformKind::Omni => V3::new(p.v, p.v_lat, p.omega),
    }
}

// ---------------------------------------------------------------------------------------
// A random "valid point" of the law: a measurement and an initialised state.

#[derive(Clone, Copy, Debug)]
pub struct Point {
    pub meas: Measurement<f64, 3>,
    pub state: State<f64, 3>,
}

/// One step of `law` from `pt` over `dt`: the output and the next state. A rejection is a
/// test failure.
pub fn step_point<P: Platform<f64>>(
    law: &ControlLaw<f64, P, Rpr<f64>, 3>,
    pt: &Point,
    dt: f64,
) -> Result<(Output<f64, 3>, State<f64, 3>), TestCaseError> {
    let mut st = pt.state;
    let out = law
        .step(&mut st, &pt.meas, dt)
        .map_err(|r| TestCaseError::fail(format!("valid point rejected: {:?}", r.error)))?;
    Ok((out, st))
}

/// A valid measurement and an initialised state: joints at least `joint_frac` of their
/// range inside the limits, target 0.5–3 m ahead, a moving target, `q̂` near `q`, a
/// non-trivial rest-filter state `r̃_b`, any `α`, any `Ψ`.
pub fn point(joint_frac: f64) -> impl Strategy<Value = Point> {
    (
        (pose_in(3.0, PI), (0.5..3.0, -1.5..1.5, -1.0..1.0f64), joints_inside(joint_frac)),
        (vec3(-0.5, 0.5), vec3(-0.05, 0.05), (-PI..PI, -PI..PI), 0.0..1.0f64),
        (pose_in(0.3, 0.5), 0.1..3.0f64, -1.0..1.0f64),
    )
        .prop_map(|((base, rbd, q), (u_d, dq_hat, (a1, a2), psi), (r_tilde, t, xi))| {
            let r_bd = V3::new(rbd.0, rbd.1, rbd.2);
            let target = mul(&base, &r_bd);
            let meas = Measurement {
                t,
                base: pose(&base),
                steering: xi,
                joints: q,
                target: pose(&target),
                target_velocity: u_d,
            };
            let mut state = State::new();
            state.alpha = Vector2::new(a1, a2);
            state.q_hat = q + dq_hat;
            state.psi = psi;
            state.sigma = Q::repeat(psi.sqrt());
            state.r_tilde = pose(&r_tilde);
            state.t0 = 0.0;
            state.initialized = true;
            Point { meas, state }
        })
}

// ---------------------------------------------------------------------------------------
// Transverse functions and the weight target, from the paper's text.

/// Eq. (16): `f(α) = (ε₁ sin α, ε₁ ε₂ sin 2α / 4, arctan(ε₂ cos α))`.
pub fn f_unicycle(e1: f64, e2: f64, a: f64) -> V3 {
    V3::new(e1 * a.sin(), e1 * e2 * (2.0 * a).sin() / 4.0, (e2 * a.cos()).atan())
}

/// Lemma 2: `f = (f̄₁, f̄₄, arctan f̄₃, f̄₂ cos³(arctan f̄₃))`; returns `(r_f, ξ_f)`.
pub fn f_car(eps: f64, eta: [f64; 3], a: &Vector2<f64>) -> (V3, f64) {
    let [n1, n2, n3] = eta;
    let (a1, a2) = (a[0], a[1]);
    let fb1 = eps * (a1.sin() + n2 * a2.sin());
    let fb2 = eps * n1 * a1.cos();
    let fb3 = eps.powi(2) * (n1 * (2.0 * a1).sin() / 4.0 - n3 * a2.cos());
    let fb4 = eps.powi(3)
        * (n1 * a1.sin().powi(2) * a1.cos() / 6.0
            - n2 * n3 * (2.0 * a2).sin() / 4.0
            - n3 * a1.sin() * a2.cos());
    let theta = fb3.atan();
    (V3::new(fb1, fb4, theta), fb2 * theta.cos().powi(3))
}

/// `f(α)` of the test platforms: the paper's unicycle (ε = (0.2, 0.4)), [`car`], omni (0).
pub fn f_reference(kind: PlatformKind, alpha: &Vector2<f64>) -> V3 {
    match kind {
        PlatformKind::Unicycle => f_unicycle(0.2, 0.4, alpha[0]),
        PlatformKind::Car => f_car(0.4, [1.0, 2.0, 1.0], alpha).0,
        PlatformKind::Omni => V3::zeros(),
    }
}

/// `ξ_f(α)` of [`car`].
pub fn xi_f_reference(alpha: &Vector2<f64>) -> f64 {
    f_car(0.4, [1.0, 2.0, 1.0], alpha).1
}

/// `σ̃ᵢ(qᵢ)` of (52) in the SPEC's reading: 1 within `δ⁻⁻` of the lower limit (`δ⁺⁺` of
/// the upper), 0 farther than `δ⁻` (`δ⁺`), linear in between.
pub fn sigma_tilde_reference(m: &companion_core::WeightMargins<f64, 3>, i: usize, x: f64) -> f64 {
    let (lo, hi) = (LOWER[i], UPPER[i]);
    let (dm, dmm, dp, dpp) = (m.lower[i], m.lower_inner[i], m.upper[i], m.upper_inner[i]);
    if x - lo <= dmm || hi - x <= dpp {
        1.0
    } else if x - lo < dm {
        (lo + dm - x) / (dm - dmm)
    } else if hi - x < dp {
        (x - (hi - dp)) / (dp - dpp)
    } else {
        0.0
    }
}

/// `Ψ̃(q) = (1/3) Σ σ̃ᵢ(qᵢ)²`, eq. (52).
pub fn psi_tilde_reference(m: &companion_core::WeightMargins<f64, 3>, q: &Q) -> f64 {
    (0..3).map(|i| sigma_tilde_reference(m, i, q[i]).powi(2)).sum::<f64>() / 3.0
}

// ---------------------------------------------------------------------------------------
// The exact kinematic plant.

/// The plant state: base pose, steering `ξ` (car), joints, target pose, time.
#[derive(Clone, Copy, Debug)]
pub struct Plant {
    pub t: f64,
    pub base: V3,
    pub xi: f64,
    pub q: Q,
    pub target: V3,
}

type X = SVector<f64, 10>;

/// Target trajectory 1 of §4.3: `u_d(t) = −(π/20)(sin(πt/2), cos(πt/2), 0)`.
pub fn trajectory_1(t: f64) -> V3 {
    let k = -PI / 20.0;
    V3::new(k * (PI * t / 2.0).sin(), k * (PI * t / 2.0).cos(), 0.0)
}

impl Plant {
    /// The paper's start: platform at the origin, `r_bd(0)`, `q(0)`.
    pub fn paper_start(r_bd: V3, q: Q, xi: f64) -> Self {
        Self { t: 0.0, base: V3::zeros(), xi, q, target: r_bd }
    }

    pub fn measurement(&self, u_d: &dyn Fn(f64) -> V3) -> Measurement<f64, 3> {
        Measurement {
            t: self.t,
            base: pose(&self.base),
            steering: self.xi,
            joints: self.q,
            target: pose(&self.target),
            target_velocity: u_d(self.t),
        }
    }

    fn pack(&self) -> X {
        let mut x = X::zeros();
        x.fixed_rows_mut::<3>(0).copy_from(&self.base);
        x[3] = self.xi;
        x.fixed_rows_mut::<3>(4).copy_from(&self.q);
        x.fixed_rows_mut::<3>(7).copy_from(&self.target);
        x
    }

    fn unpack(&mut self, x: &X) {
        self.base = x.fixed_rows::<3>(0).into();
        self.xi = x[3];
        self.q = x.fixed_rows::<3>(4).into();
        self.target = x.fixed_rows::<3>(7).into();
    }

    /// The plant's vector field under the held command `cmd` (eqs. 3, 55, `q̇ = u_q`, and
    /// `ṙ_d = R̄(θ_d) u_d(t)`).
    fn field(kind: PlatformKind, cmd: &Command<f64, 3>, u_d: &dyn Fn(f64) -> V3, t: f64, x: &X) -> X {
        let p = &cmd.platform;
        let (u_b, xi_dot) = match kind {
            PlatformKind::Unicycle => (V3::new(p.v, 0.0, p.omega), 0.0),
            PlatformKind::Car => (V3::new(p.v, 0.0, p.v * x[3]), p.v_xi),
            PlatformKind::Omni => (V3::new(p.v, p.v_lat, p.omega), 0.0),
        };
        let mut d = X::zeros();
        d.fixed_rows_mut::<3>(0).copy_from(&(rbar(x[2]) * u_b));
        d[3] = xi_dot;
        d.fixed_rows_mut::<3>(4).copy_from(&cmd.joints);
        d.fixed_rows_mut::<3>(7).copy_from(&(rbar(x[9]) * u_d(t)));
        d
    }

    /// Applies `cmd` for `dt` seconds (zero-order hold) with `substeps` RK4 steps.
    pub fn advance(
        &mut self,
        kind: PlatformKind,
        cmd: &Command<f64, 3>,
        u_d: &dyn Fn(f64) -> V3,
        dt: f64,
        substeps: usize,
    ) {
        let h = dt / substeps as f64;
        let mut x = self.pack();
        let mut t = self.t;
        for _ in 0..substeps {
            let k1 = Self::field(kind, cmd, u_d, t, &x);
            let k2 = Self::field(kind, cmd, u_d, t + h / 2.0, &(x + k1 * (h / 2.0)));
            let k3 = Self::field(kind, cmd, u_d, t + h / 2.0, &(x + k2 * (h / 2.0)));
            let k4 = Self::field(kind, cmd, u_d, t + h, &(x + k3 * h));
            x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
            t += h;
        }
        self.unpack(&x);
        self.t = t;
    }
}

/// A measurement converted to another scalar type (f32 for the precision tests).
pub fn measurement_as<S: Real, T: Real>(m: &Measurement<S, 3>) -> Measurement<T, 3> {
    let c = |x: S| T::of(x.as_f64());
    let p = |p: &Pose<S>| Pose::new(c(p.x), c(p.y), c(p.theta));
    Measurement {
        t: c(m.t),
        base: p(&m.base),
        steering: c(m.steering),
        joints: m.joints.map(c),
        target: p(&m.target),
        target_velocity: m.target_velocity.map(c),
    }
}

/// A command converted to f64.
pub fn command_f64<T: Real>(c: &Command<T, 3>) -> Command<f64, 3> {
    let p = &c.platform;
    Command {
        platform: companion_core::PlatformCommand {
            v: p.v.as_f64(),
            v_lat: p.v_lat.as_f64(),
            omega: p.omega.as_f64(),
            v_xi: p.v_xi.as_f64(),
        },
        joints: c.joints.map(Real::as_f64),
    }
}

/// Which platform a law drives (for the plant).
pub fn kind_of<P: Platform<f64>>() -> PlatformKind {
    P::KIND
}
