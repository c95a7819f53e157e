//! Transverse functions and the companion omnidirectional frame — §2.3 and §5.
//!
//! A nonholonomic platform cannot move sideways, but the frame `r̄_b = r_b f(α)⁻¹`
//! (eq. 11) can: with a *transverse* function `f` the map from the platform inputs and
//! `α̇` to the companion frame's body velocity `ū_b` is onto (eqs. 13–15, 57–60). The law
//! controls `ū_b` as if the platform were omnidirectional and recovers the platform's
//! inputs as `H̄(α)⁻¹ ū_b`.
//!
//! Every platform here maps a 3-vector `w` of "generalised inputs" to `ū_b = H̄(α) w`:
//!
//! | platform | `w` | `α` |
//! |---|---|---|
//! | [`Unicycle`] | `(v, ω, α̇)` | `α ∈ S¹` |
//! | [`CarLike`] | `(v, α̇₁, α̇₂)` | `α ∈ T²` |
//! | [`Omnidirectional`] | `(v₁, v₂, ω)` | none (`f = 0`, `H̄ = I₃`) |

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::error::{ParamError, Rule};
use crate::scalar::Real;
use crate::se2::{inverse3, Pose};

/// The kind of wheeled platform.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlatformKind {
    /// Unicycle-like (differential drive): `u_b = (v, 0, ω)`.
    Unicycle,
    /// Car-like, eq. (55): `u_b = (v, 0, v ξ)`, `ξ̇ = v_ξ`.
    Car,
    /// Omnidirectional: `u_b = (v₁, v₂, ω)`.
    Omni,
}

/// The companion frame's data at one `α`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompanionFrame<T> {
    /// `f(α)` as a pose `(p_f, θ_f)`.
    pub f: Pose<T>,
    /// `(sin θ_f, cos θ_f)`, known algebraically for both transverse functions.
    pub sin_cos_theta_f: (T, T),
    /// `H̄(α)`, eq. (15) (unicycle) or (60) (car); `I₃` for the omnidirectional platform.
    pub hbar: Matrix3<T>,
    /// `H̄(α)⁻¹`.
    pub hbar_inv: Matrix3<T>,
    /// `det H(α) = det H̄(α)` (Lemma 1 / Lemma 2); 1 for the omnidirectional platform.
    pub det_h: T,
    /// `ξ_f(α)`, the steering the car-like function prescribes (0 otherwise).
    pub xi_f: T,
    /// `∂ξ_f/∂α` (car-like; 0 otherwise).
    pub dxi_f: Vector2<T>,
}

/// Velocity limits of a platform, met by one common scale factor (end of §3.4.2).
///
/// A limit of `+∞` means "no limit". Units: m/s, rad/s, and (for `v_ξ`) 1/(m·s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VelocityLimits<T> {
    /// Largest `|v₁|` (forward speed), m/s.
    pub forward: T,
    /// Largest `|v₂|` (lateral speed, omnidirectional platform), m/s.
    pub lateral: T,
    /// Largest `|ω|` (unicycle and omnidirectional platforms), rad/s.
    pub angular: T,
    /// Largest `|α̇ᵢ|` of the transverse-function variables, rad/s.
    pub alpha_rate: T,
    /// Largest `|v_ξ|` (car-like platform), 1/(m·s).
    pub steering_rate: T,
}

impl<T: Real> VelocityLimits<T> {
    /// No limits (the paper's runs).
    pub fn unlimited() -> Self {
        let inf = T::of(f64::INFINITY);
        Self { forward: inf, lateral: inf, angular: inf, alpha_rate: inf, steering_rate: inf }
    }

    pub(crate) fn validate(&self) -> Result<(), ParamError> {
        for (name, v) in [
            ("limits.forward", self.forward),
            ("limits.lateral", self.lateral),
            ("limits.angular", self.angular),
            ("limits.alpha_rate", self.alpha_rate),
            ("limits.steering_rate", self.steering_rate),
        ] {
            // +∞ is allowed (no limit); NaN and non-positive values are not.
            if v.nan() {
                return Err(ParamError::new(name, Rule::NonFinite));
            }
            if v <= T::zero() {
                return Err(ParamError::new(name, Rule::NotPositive));
            }
        }
        Ok(())
    }
}

/// The platform command: the velocities sent to the wheeled base.
///
/// Which fields a platform uses: unicycle `v`, `omega`; car-like `v`, `v_xi` (and `omega`
/// reports the resulting yaw rate `v ξ`); omnidirectional `v`, `v_lat`, `omega`. Unused
/// fields are zero.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlatformCommand<T> {
    /// Forward speed `v₁` (m/s).
    pub v: T,
    /// Lateral speed `v₂` (m/s), omnidirectional platform only.
    pub v_lat: T,
    /// Angular speed `ω` (rad/s).
    pub omega: T,
    /// Steering rate `v_ξ = ξ̇` (1/(m·s)), car-like platform only, eq. (59).
    pub v_xi: T,
}

/// A wheeled platform with its transverse function.
pub trait Platform<T: Real>: Copy + core::fmt::Debug {
    /// Which platform this is.
    const KIND: PlatformKind;
    /// How many transverse-function variables `α` it has (0, 1 or 2).
    const ALPHA_DIM: usize;

    /// Checks the parameters (e.g. Lemma 1's `ε₁, ε₂ > 0`, Lemma 2's inequality).
    ///
    /// # Errors
    /// The first parameter that breaks a rule.
    fn validate(&self) -> Result<(), ParamError>;

    /// `f(α)`, `H̄(α)` and its inverse. `None` only if `H̄(α)` is numerically singular,
    /// which a validated transverse function excludes for finite `α`.
    fn companion(&self, alpha: &Vector2<T>) -> Option<CompanionFrame<T>>;

    /// The body velocity `u_b` that generalised inputs `w` give, with measured steering
    /// `ξ` (car-like only).
    fn body_velocity(w: &Vector3<T>, xi: T) -> Vector3<T>;

    /// `α̇` contained in the generalised inputs `w` (unused components zero).
    fn alpha_rate(w: &Vector3<T>) -> Vector2<T>;

    /// The steering rate `v_ξ`, eq. (59) (car-like; 0 otherwise).
    fn steering_rate(&self, companion: &CompanionFrame<T>, xi: T, alpha_rate: &Vector2<T>) -> T;

    /// The platform command for generalised inputs `w` and steering rate `v_ξ`.
    fn command(w: &Vector3<T>, v_xi: T, xi: T) -> PlatformCommand<T>;

    /// The largest ratio `|component| / limit` over the platform's velocities and `α̇`.
    fn saturation_ratio(limits: &VelocityLimits<T>, w: &Vector3<T>, v_xi: T) -> T;
}

#[inline]
fn ratio<T: Real>(x: T, limit: T) -> T {
    x.abs() / limit
}

#[inline]
fn max<T: Real>(a: T, b: T) -> T {
    if b > a {
        b
    } else {
        a
    }
}

/// `H̄ = [I₂ −S p_f; 0 1] H`, eqs. (15) and (60): adds `p_fy` times row 3 to row 1 and
/// subtracts `p_fx` times row 3 from row 2.
#[inline]
fn hbar_from_h<T: Real>(h: &Matrix3<T>, pf: (T, T)) -> Matrix3<T> {
    let mut hb = *h;
    for j in 0..3 {
        hb[(0, j)] += pf.1 * h[(2, j)];
        hb[(1, j)] -= pf.0 * h[(2, j)];
    }
    hb
}

/// Unicycle-like platform with Lemma 1's transverse function, eq. (16):
///
/// ```text
/// f(α) = ( ε₁ sin α,  ε₁ ε₂ sin 2α / 4,  arctan(ε₂ cos α) )
/// det H(α) = −(ε₁ ε₂ / 2) cos(arctan(ε₂ cos α))          (Lemma 1)
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unicycle<T> {
    /// `ε₁ > 0` (m): the size of the function along the platform's axis.
    pub epsilon_1: T,
    /// `ε₂ > 0` (dimensionless): the amplitude of the heading oscillation.
    pub epsilon_2: T,
}

impl<T: Real> Unicycle<T> {
    /// The function's parameters (m, dimensionless).
    pub fn new(epsilon_1: T, epsilon_2: T) -> Self {
        Self { epsilon_1, epsilon_2 }
    }

    /// The paper's §4.3 values `(ε₁, ε₂) = (0.2, 0.4)`.
    pub fn paper() -> Self {
        Self::new(T::of(0.2), T::of(0.4))
    }

    /// Lemma 1's closed form `det H(α) = −(ε₁ε₂/2) cos(arctan(ε₂ cos α))`.
    pub fn det_h_closed_form(&self, alpha: T) -> T {
        let (_, c) = alpha.sincos();
        let half = T::of(0.5);
        -(half * self.epsilon_1 * self.epsilon_2) * (self.epsilon_2 * c).arctan().sincos().1
    }
}

impl<T: Real> Platform<T> for Unicycle<T> {
    const KIND: PlatformKind = PlatformKind::Unicycle;
    const ALPHA_DIM: usize = 1;

    fn validate(&self) -> Result<(), ParamError> {
        positive("epsilon_1", self.epsilon_1)?;
        positive("epsilon_2", self.epsilon_2)
    }

    #[inline]
    fn companion(&self, alpha: &Vector2<T>) -> Option<CompanionFrame<T>> {
        let (e1, e2) = (self.epsilon_1, self.epsilon_2);
        let (s, c) = alpha[0].sincos();
        let half = T::of(0.5);
        let y = e2 * c;
        let k2 = T::one() / (T::one() + y * y);
        let k = k2.square_root();
        // cos θ_f = 1/√(1+y²), sin θ_f = y/√(1+y²) with y = ε₂ cos α: no extra trig.
        let (sf, cf) = (y * k, k);
        let f = Pose::new(e1 * s, half * e1 * e2 * s * c, y.arctan());
        // ∂f/∂α.
        let dx = e1 * c;
        let dy = half * e1 * e2 * (c * c - s * s);
        let dth = -e2 * s * k2;
        let z = T::zero();
        let h = Matrix3::new(cf, z, -dx, sf, z, -dy, z, T::one(), -dth);
        let hbar = hbar_from_h(&h, (f.x, f.y));
        let (hbar_inv, det_h) = inverse3(&hbar)?;
        Some(CompanionFrame {
            f,
            sin_cos_theta_f: (sf, cf),
            hbar,
            hbar_inv,
            det_h,
            xi_f: z,
            dxi_f: Vector2::zeros(),
        })
    }

    #[inline]
    fn body_velocity(w: &Vector3<T>, _xi: T) -> Vector3<T> {
        Vector3::new(w[0], T::zero(), w[1])
    }

    #[inline]
    fn alpha_rate(w: &Vector3<T>) -> Vector2<T> {
        Vector2::new(w[2], T::zero())
    }

    #[inline]
    fn steering_rate(&self, _: &CompanionFrame<T>, _: T, _: &Vector2<T>) -> T {
        T::zero()
    }

    #[inline]
    fn command(w: &Vector3<T>, _v_xi: T, _xi: T) -> PlatformCommand<T> {
        PlatformCommand { v: w[0], v_lat: T::zero(), omega: w[1], v_xi: T::zero() }
    }

    #[inline]
    fn saturation_ratio(l: &VelocityLimits<T>, w: &Vector3<T>, _: T) -> T {
        max(max(ratio(w[0], l.forward), ratio(w[1], l.angular)), ratio(w[2], l.alpha_rate))
    }
}

/// Car-like platform, eq. (55), with Lemma 2's transverse function on `T²`:
///
/// ```text
/// f̄(α) = ( ε (sin α₁ + η₂ sin α₂),
///          ε η₁ cos α₁,
///          ε² (η₁ sin 2α₁ / 4 − η₃ cos α₂),
///          ε³ (η₁ sin²α₁ cos α₁ / 6 − η₂ η₃ sin 2α₂ / 4 − η₃ sin α₁ cos α₂) )
/// f(α)  = ( f̄₁, f̄₄, arctan f̄₃, f̄₂ cos³(arctan f̄₃) ) = (x_f, y_f, θ_f, ξ_f)
/// ```
///
/// transverse when `ε, η₁, η₂, η₃ > 0` and `6 η₂ η₃ > 8 η₃ + η₁ η₂`. The steering follows
/// `ξ_f(α)` by eq. (59), `v_ξ = −k (ξ − ξ_f(α)) + ξ̇_f(α)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarLike<T> {
    /// `ε > 0`: the size of the function.
    pub epsilon: T,
    /// `η₁ > 0`.
    pub eta_1: T,
    /// `η₂ > 0`.
    pub eta_2: T,
    /// `η₃ > 0`.
    pub eta_3: T,
    /// Steering gain `k > 0` of eq. (59), 1/s.
    pub k: T,
}

/// The values of `f̄` and its partial derivatives for [`CarLike`].
#[derive(Clone, Copy, Debug)]
struct CarF<T> {
    fb: [T; 4],
    d1: [T; 4],
    d2: [T; 4],
}

impl<T: Real> CarLike<T> {
    /// The function's parameters and the steering gain.
    pub fn new(epsilon: T, eta: [T; 3], k: T) -> Self {
        Self { epsilon, eta_1: eta[0], eta_2: eta[1], eta_3: eta[2], k }
    }

    fn fbar(&self, alpha: &Vector2<T>) -> CarF<T> {
        let e = self.epsilon;
        let (n1, n2, n3) = (self.eta_1, self.eta_2, self.eta_3);
        let (s1, c1) = alpha[0].sincos();
        let (s2, c2) = alpha[1].sincos();
        let two = T::of(2.0);
        let (s21, c21) = (two * s1 * c1, c1 * c1 - s1 * s1);
        let (s22, c22) = (two * s2 * c2, c2 * c2 - s2 * s2);
        let e2 = e * e;
        let e3 = e2 * e;
        let q = T::of(0.25);
        let sixth = T::one() / T::of(6.0);
        let half = T::of(0.5);
        let fb = [
            e * (s1 + n2 * s2),
            e * n1 * c1,
            e2 * (n1 * s21 * q - n3 * c2),
            e3 * (n1 * s1 * s1 * c1 * sixth - n2 * n3 * s22 * q - n3 * s1 * c2),
        ];
        let d1 = [
            e * c1,
            -e * n1 * s1,
            e2 * n1 * c21 * half,
            e3 * (n1 * (two * s1 * c1 * c1 - s1 * s1 * s1) * sixth - n3 * c1 * c2),
        ];
        let d2 = [e * n2 * c2, T::zero(), e2 * n3 * s2, e3 * (-n2 * n3 * c22 * half + n3 * s1 * s2)];
        CarF { fb, d1, d2 }
    }
}

impl<T: Real> Platform<T> for CarLike<T> {
    const KIND: PlatformKind = PlatformKind::Car;
    const ALPHA_DIM: usize = 2;

    fn validate(&self) -> Result<(), ParamError> {
        positive("epsilon", self.epsilon)?;
        positive("eta_1", self.eta_1)?;
        positive("eta_2", self.eta_2)?;
        positive("eta_3", self.eta_3)?;
        positive("k", self.k)?;
        let lhs = T::of(6.0) * self.eta_2 * self.eta_3;
        let rhs = T::of(8.0) * self.eta_3 + self.eta_1 * self.eta_2;
        if lhs > rhs {
            Ok(())
        } else {
            Err(ParamError::new("eta", Rule::Transversality))
        }
    }

    #[inline]
    fn companion(&self, alpha: &Vector2<T>) -> Option<CompanionFrame<T>> {
        let CarF { fb, d1, d2 } = self.fbar(alpha);
        let u = fb[2];
        let k2 = T::one() / (T::one() + u * u); // cos² θ_f
        let k = k2.square_root(); // cos θ_f
        let (sf, cf) = (u * k, k);
        let f = Pose::new(fb[0], fb[3], u.arctan());
        let k3 = k2 * k; // cos³ θ_f = (1 + f̄₃²)^(−3/2)
        let xi_f = fb[1] * k3;
        // ∂ξ_f = ∂f̄₂ (1+f̄₃²)^(−3/2) − 3 f̄₂ f̄₃ ∂f̄₃ (1+f̄₃²)^(−5/2).
        let three = T::of(3.0);
        let dxi = |d: &[T; 4]| d[1] * k3 - three * fb[1] * u * d[2] * k3 * k2;
        let dxi_f = Vector2::new(dxi(&d1), dxi(&d2));
        // H(α), eq. (58): columns (cos θ_f, sin θ_f, ξ_f), −∂r_f/∂α₁, −∂r_f/∂α₂.
        let h = Matrix3::new(cf, -d1[0], -d2[0], sf, -d1[3], -d2[3], xi_f, -d1[2] * k2, -d2[2] * k2);
        let hbar = hbar_from_h(&h, (f.x, f.y));
        let (hbar_inv, det_h) = inverse3(&hbar)?;
        Some(CompanionFrame { f, sin_cos_theta_f: (sf, cf), hbar, hbar_inv, det_h, xi_f, dxi_f })
    }

    #[inline]
    fn body_velocity(w: &Vector3<T>, xi: T) -> Vector3<T> {
        Vector3::new(w[0], T::zero(), w[0] * xi)
    }

    #[inline]
    fn alpha_rate(w: &Vector3<T>) -> Vector2<T> {
        Vector2::new(w[1], w[2])
    }

    #[inline]
    fn steering_rate(&self, c: &CompanionFrame<T>, xi: T, alpha_rate: &Vector2<T>) -> T {
        -self.k * (xi - c.xi_f) + c.dxi_f.dot(alpha_rate)
    }

    #[inline]
    fn command(w: &Vector3<T>, v_xi: T, xi: T) -> PlatformCommand<T> {
        PlatformCommand { v: w[0], v_lat: T::zero(), omega: w[0] * xi, v_xi }
    }

    #[inline]
    fn saturation_ratio(l: &VelocityLimits<T>, w: &Vector3<T>, v_xi: T) -> T {
        let a = max(ratio(w[1], l.alpha_rate), ratio(w[2], l.alpha_rate));
        max(max(ratio(w[0], l.forward), a), ratio(v_xi, l.steering_rate))
    }
}

/// Omnidirectional platform: `f = 0`, the companion frame is the platform's frame and
/// `ū_b = u_b` (§2.3).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Omnidirectional;

impl<T: Real> Platform<T> for Omnidirectional {
    const KIND: PlatformKind = PlatformKind::Omni;
    const ALPHA_DIM: usize = 0;

    fn validate(&self) -> Result<(), ParamError> {
        Ok(())
    }

    #[inline]
    fn companion(&self, _alpha: &Vector2<T>) -> Option<CompanionFrame<T>> {
        Some(CompanionFrame {
            f: Pose::identity(),
            sin_cos_theta_f: (T::zero(), T::one()),
            hbar: Matrix3::identity(),
            hbar_inv: Matrix3::identity(),
            det_h: T::one(),
            xi_f: T::zero(),
            dxi_f: Vector2::zeros(),
        })
    }

    #[inline]
    fn body_velocity(w: &Vector3<T>, _xi: T) -> Vector3<T> {
        *w
    }

    #[inline]
    fn alpha_rate(_w: &Vector3<T>) -> Vector2<T> {
        Vector2::zeros()
    }

    #[inline]
    fn steering_rate(&self, _: &CompanionFrame<T>, _: T, _: &Vector2<T>) -> T {
        T::zero()
    }

    #[inline]
    fn command(w: &Vector3<T>, _v_xi: T, _xi: T) -> PlatformCommand<T> {
        PlatformCommand { v: w[0], v_lat: w[1], omega: w[2], v_xi: T::zero() }
    }

    #[inline]
    fn saturation_ratio(l: &VelocityLimits<T>, w: &Vector3<T>, _: T) -> T {
        max(max(ratio(w[0], l.forward), ratio(w[1], l.lateral)), ratio(w[2], l.angular))
    }
}

pub(crate) fn positive<T: Real>(name: &'static str, v: T) -> Result<(), ParamError> {
    if !v.finite() {
        Err(ParamError::new(name, Rule::NonFinite))
    } else if v <= T::zero() {
        Err(ParamError::new(name, Rule::NotPositive))
    } else {
        Ok(())
    }
}
