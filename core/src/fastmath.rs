//! Elementary functions computed in `f32` arithmetic, for `impl Real for f32`.
//!
//! Why they exist: libm's `sincosf` evaluates in `f64`, which a Cortex-M4F does in
//! software: ~2 200 instructions per call on the emulated M4F, against ~60 here. A
//! unicycle step calls it six times or more; with libm's `f32` functions a unicycle `f32`
//! step of run (a) took ~29 000 instructions (an earlier law), with these it takes ~1 950
//! (`tests/firmware/measure`, which checks its counts by single-stepping). Everything here
//! uses only `f32` operations the FPU has (add, sub, mul, div, conversions), integer
//! operations, and, on the cold path of huge sin/cos arguments only, `u64`/`u128` integer
//! arithmetic.
//!
//! Determinism: every operation is an IEEE-754 single operation (Rust never contracts
//! `a * b + c` into a fused multiply-add), so the host (SSE) and the M4F (FPv4-SP, default
//! NaN and flush-to-zero off) give the same bits. Nothing here uses `mul_add`.
//!
//! Not here: the square root. No `unsafe` (the core forbids it), so no inline
//! `vsqrt.f32` here, and `core` has no stable `f32::sqrt` (Rust 1.95). A Heron iteration
//! from a bit-trick guess with an exact integer rounding check gave the correctly rounded
//! result (checked on all 2³¹ non-negative inputs) in ~80 instructions on the M4F, libm's
//! `sqrtf` (integer, table-driven, also correctly rounded) ~60; `Real for f32` takes the
//! FPU's instruction from the crate `companion-fpu` (one instruction, the same bits). libm 0.2.16's `atanf` and `expf` are `f32` code too (~55 and ~50
//! instructions per call through `dyn`; these take ~45 and ~55): only its `sincosf` works
//! in `f64` (~2 200).
//!
//! ## Accuracy
//!
//! Error in units in the last place (ulp) of the exact result, against `f64` libm (good to
//! 2⁻⁵², so the reference is exact at this scale). "Bound" is what the tests assert,
//! "measured" the largest error they found.
//!
//! ```text
//! function  bound   measured  tested on
//! sin, cos  1 ulp   0.935     every f32 with |x| ≤ 128 (ignored test: exhaustive); by
//!                             default every 17th f32 in [2⁻¹², 2π], a stride over all
//!                             2³² patterns, dense [128, 2²⁰] and [10³⁰, f32::MAX]
//! exp       1 ulp   0.976     every f32 with a finite non-zero result (ignored test:
//!                             exhaustive; by default every 101st); subnormal results in
//!                             units of 2⁻¹⁴⁹
//! atan      1 ulp   0.844     a stride over all patterns, every 31st f32 in [10⁻⁶, 64]
//! atan2     2 ulp   1.26      a grid of ~2 100 × 300 magnitudes over the whole range × 4
//!                             sign pairs; signed zeros, infinities, NaN as libm's atan2f
//! round     0       0         equal to libm's roundf (halfway away from zero, −0 kept)
//! ```
//!
//! Large arguments of sin/cos: |x| ≤ 128 is reduced by Cody–Waite in `f32` with a two-sum
//! (`r = hi + lo`, ~48 good bits even next to a multiple of π/2); beyond that an exact
//! integer (Payne–Hanek) reduction with 2/π to 224 bits (a cold, slower path), so the
//! bound holds over the whole finite range, up to `f32::MAX`. Non-finite inputs give NaN.
//! In the law the arguments are angles within a few π, where the fast path applies.
//!
//! Polynomial coefficients: weighted minimax (Remez exchange in 50-digit `mpmath`,
//! relative error of the final function as the weight), then rounded to `f32`. They are
//! stored as bit patterns so that the value is exactly the one that was checked.

// ---------------------------------------------------------------------------------------
// Constants (bit patterns are exact; the decimal in the comment is approximate).

/// 2/π ≈ 0.63661975.
const FRAC_2_PI: f32 = f32::from_bits(0x3f22_f983);
/// π/2 rounded to 17 bits, 1.57080078125: `k · P1` is exact for |k| < 2⁷.
const PIO2_1: f32 = f32::from_bits(0x3fc9_1000);
/// The next 17 bits of π/2, −4.45445767e−6 (the split rounds to nearest, so negative).
const PIO2_2: f32 = f32::from_bits(0xb695_7780);
/// The rest of π/2, 2.56334407e−12 (π/2 − P1 − P2 − P3 ≈ 8e−20).
const PIO2_3: f32 = f32::from_bits(0x2c34_611a);
/// Above this |x| the reduction is the exact integer one (k would need more than 7 bits).
const SINCOS_CW_MAX: f32 = 128.0;
/// 2⁻¹²: below it sin x = x and cos x = 1 to within 0.17 ulp.
const TWO_POW_M12: f32 = f32::from_bits(0x3980_0000);

/// sin r = r + r s (S0 + s (S1 + s S2)), s = r², |r| ≤ π/4 + 0.002; relative error of the
/// polynomial with these f32 coefficients ≤ 2^−26.9.
const S0: f32 = f32::from_bits(0xbe2a_aaa2); // −1.666665375e−1
const S1: f32 = f32::from_bits(0x3c08_8391); //  8.332149126e−3
const S2: f32 = f32::from_bits(0xb94c_9d7c); // −1.951362356e−4
/// cos r = 1 − s/2 + s² (C0 + s (C1 + s C2)); relative error ≤ 2^−32.
const C0: f32 = f32::from_bits(0x3d2a_aaa5); //  4.166664556e−2
const C1: f32 = f32::from_bits(0xbab6_060c); // −1.388730016e−3
const C2: f32 = f32::from_bits(0x37cc_f1bc); //  2.443126141e−5

/// The first 224 bits of 2/π after the binary point, behind one zero word (so that a
/// window can start before the point for moderate arguments).
const TWO_OVER_PI: [u32; 8] =
    [0x0000_0000, 0xa2f9_836e, 0x4e44_1529, 0xfc27_57d1, 0xf534_ddc0, 0xdb62_9599, 0x3c43_9041, 0xfe51_63ab];
/// π/2 · 2⁶² rounded to nearest.
const PIO2_Q62: u64 = 0x6487_ed51_10b4_611a;

/// log₂ e ≈ 1.44269502.
const LOG2_E: f32 = f32::from_bits(0x3fb8_aa3b);
/// ln 2 rounded to 16 bits, 0.693145751953125: `k · LN2_HI` is exact for |k| ≤ 2⁸.
const LN2_HI: f32 = f32::from_bits(0x3f31_7200);
/// ln 2 − LN2_HI ≈ 1.42860677e−6.
const LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
/// The largest x with e^x < f32::MAX (≈ 88.7228317).
const EXP_MAX: f32 = f32::from_bits(0x42b1_7217);
/// Below this e^x rounds to 0 (≈ −103.972076; ln 2⁻¹⁵⁰ ≈ −103.9720771).
const EXP_MIN: f32 = f32::from_bits(0xc2cf_f1b4);
/// e^r = 1 + r + r² (E0 + r (E1 + r (E2 + r (E3 + r E4)))), |r| ≤ (ln 2)/2 · (1 + 10⁻⁴);
/// relative error ≤ 2^−27.9.
const E0: f32 = f32::from_bits(0x3eff_fffe); // 4.999999404e−1
const E1: f32 = f32::from_bits(0x3e2a_aa49); // 1.666652113e−1
const E2: f32 = f32::from_bits(0x3d2a_ac79); // 4.166838899e−2
const E3: f32 = f32::from_bits(0x3c09_1cf1); // 8.368716575e−3
const E4: f32 = f32::from_bits(0x3ab5_121a); // 1.381459879e−3

/// atan t = t + t s (A0 + s (A1 + s (A2 + s (A3 + s A4)))), s = t², |t| ≤ 7/16 (1 + 10⁻⁴);
/// relative error ≤ 2^−28.1.
const A0: f32 = f32::from_bits(0xbeaa_aaa1); // −3.333330452e−1
const A1: f32 = f32::from_bits(0x3e4c_c6de); //  1.999773681e−1
const A2: f32 = f32::from_bits(0xbe11_b5eb); // −1.422955245e−1
const A3: f32 = f32::from_bits(0x3dd6_d8fa); //  1.049060374e−1
const A4: f32 = f32::from_bits(0xbd6e_549f); // −5.818616971e−2
/// atan(1/2) and atan(3/2) as f32 + the rest.
const ATAN_HALF_HI: f32 = f32::from_bits(0x3eed_6338);
const ATAN_HALF_LO: f32 = f32::from_bits(0x31ac_376a);
const ATAN_3HALF_HI: f32 = f32::from_bits(0x3f7b_985f);
const ATAN_3HALF_LO: f32 = f32::from_bits(0xb2d7_e096);
/// π/4, π/2, π and 3π/4 as f32 + the rest.
const PIO4_HI: f32 = f32::from_bits(0x3f49_0fdb);
const PIO4_LO: f32 = f32::from_bits(0xb2bb_bd2e);
const PIO2_HI: f32 = f32::from_bits(0x3fc9_0fdb);
const PIO2_LO: f32 = f32::from_bits(0xb33b_bd2e);
const PI_HI: f32 = f32::from_bits(0x4049_0fdb);
const PI_LO: f32 = f32::from_bits(0xb3bb_bd2e);
const PI3O4_HI: f32 = f32::from_bits(0x4016_cbe4);

const SIGN: u32 = 0x8000_0000;

#[inline]
fn abs(x: f32) -> f32 {
    f32::from_bits(x.to_bits() & !SIGN)
}

/// `x` with the sign bit of `s`.
#[inline]
fn copysign(x: f32, s: f32) -> f32 {
    f32::from_bits((x.to_bits() & !SIGN) | (s.to_bits() & SIGN))
}

/// 2ⁿ for −126 ≤ n ≤ 127.
#[inline]
fn pow2(n: i32) -> f32 {
    f32::from_bits(((n + 127) as u32) << 23)
}

// ---------------------------------------------------------------------------------------
// sin, cos

/// sin and cos of `r = hi + lo`, |r| ≤ π/4 + 0.002, |lo| ≲ ulp(hi).
#[inline]
fn sincos_kernel(hi: f32, lo: f32) -> (f32, f32) {
    let s = hi * hi;
    // sin(hi + lo) ≈ sin hi + lo (the dropped lo (cos hi − 1) is below 0.16 ulp).
    let sin = hi + (lo + hi * s * (S0 + s * (S1 + s * S2)));
    // cos(hi + lo) ≈ cos hi − hi lo.
    let half_s = 0.5 * s;
    let w = 1.0 - half_s;
    // (1 − w) − s/2 recovers the rounding error of w (exact: Sterbenz, s/2 ≤ 0.31).
    let cos = w + (((1.0 - w) - half_s) + (s * s * (C0 + s * (C1 + s * C2)) - hi * lo));
    (sin, cos)
}

/// Rotates `(sin r, cos r)` by `n` quarter turns: `(sin(r + nπ/2), cos(r + nπ/2))`.
#[inline]
fn quadrant(n: i32, (s, c): (f32, f32)) -> (f32, f32) {
    match n & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Exact reduction of a finite `a ≥ 2⁻³¹` (used for a > 128): returns `(n, hi, lo)` with
/// `a = n π/2 + hi + lo` (mod 2π), |hi + lo| ≤ π/4, `hi + lo` good to ~2⁻⁶⁰ relative.
#[cold]
#[inline(never)]
fn reduce_large(a: f32) -> (i32, f32, f32) {
    let bits = a.to_bits();
    // a = m · 2^(e − 23), m a 24-bit integer (a is normal here).
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = u128::from((bits & 0x007f_ffff) | 0x0080_0000);
    // Bits of 2/π of weight 2^−i with i < e − 24 contribute multiples of 4 (a full turn)
    // to a · 2/π: start the window at bit i0 = e − 24, global position i0 + 31 in the table.
    let g0 = (e + 7) as usize;
    let (w, sh) = (g0 / 32, g0 % 32);
    let word = |i: usize| u128::from(TWO_OVER_PI.get(w + i).copied().unwrap_or(0));
    let window = (word(0) << 96) | (word(1) << 64) | (word(2) << 32) | word(3);
    let bits96 = (window << sh) >> 32;
    // a · 2/π (mod 4) = m · bits96 · 2⁻⁹⁴.
    let prod = m * bits96;
    let mut n = ((prod >> 94) & 3) as i32;
    let frac = prod & ((1u128 << 94) - 1);
    let half = 1u128 << 93;
    let (mag, negative) = if frac >= half {
        n += 1;
        ((1u128 << 94) - frac, true)
    } else {
        (frac, false)
    };
    if mag == 0 {
        return (n, 0.0, 0.0);
    }
    let lz = mag.leading_zeros(); // ≥ 35
    let top = ((mag << lz) >> 64) as u64; // 64 significant bits
    let hp = ((u128::from(top) * u128::from(PIO2_Q62)) >> 64) as u64; // in [2⁶¹, 2⁶³)
                                                                      // r = hp · 2^(−28 − lz): hi = hp rounded to 24 bits, lo = the integer remainder.
    let hi = hp as f32;
    let rest = hp.wrapping_sub(hi as u64) as i64;
    let lo = rest as f32;
    // lz ≤ 98 (|r| > 2⁻⁶⁴ for every f32): the scale is a normal power of two, so exact.
    let scale = pow2((-28 - lz as i32).max(-126));
    let (hi, lo) = (hi * scale, lo * scale);
    if negative {
        (n, -hi, -lo)
    } else {
        (n, hi, lo)
    }
}

/// `(sin x, cos x)`. NaN for infinite or NaN `x`.
#[inline]
pub(crate) fn sin_cos(x: f32) -> (f32, f32) {
    let a = abs(x);
    if a <= PIO4_HI {
        if a < TWO_POW_M12 {
            // |x| < 2⁻¹²: sin x = x and cos x = 1 to within 0.17 ulp; keeps the sign of ±0.
            return (x, 1.0);
        }
        sincos_kernel(x, 0.0)
    } else if a <= SINCOS_CW_MAX {
        // Cody–Waite: k = round(x 2/π), r = x − k P1 − k P2 − k P3. k P1 and k P2 are
        // exact (7 + 17 bits); x − k P1 is exact (Sterbenz); the rounding of t − k P2 is
        // kept by a two-sum, so r = hi + lo carries ~48 good bits even next to a zero.
        let kf = x * FRAC_2_PI;
        let k = (kf + copysign(0.5, kf)) as i32;
        let kf = k as f32;
        let t = x - kf * PIO2_1;
        let c = kf * PIO2_2;
        let hi = t - c;
        let bb = hi - t;
        let err = (t - (hi - bb)) - (c + bb);
        let lo = err - kf * PIO2_3;
        quadrant(k, sincos_kernel(hi, lo))
    } else if a.is_finite() {
        let (n, hi, lo) = reduce_large(a);
        let (s, c) = quadrant(n, sincos_kernel(hi, lo));
        (if x < 0.0 { -s } else { s }, c)
    } else {
        (f32::NAN, f32::NAN)
    }
}

// ---------------------------------------------------------------------------------------
// exp

/// e^x. +∞ above ~88.72, +0 below ~−103.97, NaN for NaN.
#[inline]
pub(crate) fn exp(x: f32) -> f32 {
    if x.is_nan() {
        return x;
    }
    if x > EXP_MAX {
        return f32::INFINITY;
    }
    if x < EXP_MIN {
        return 0.0;
    }
    let kf = x * LOG2_E;
    let k = (kf + copysign(0.5, kf)) as i32; // |k| ≤ 150
    let kf = k as f32;
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    let p = 1.0 + (r + r * r * (E0 + r * (E1 + r * (E2 + r * (E3 + r * E4)))));
    if k > 127 {
        p * pow2(127) * pow2(k - 127)
    } else if k < -126 {
        // One rounding into the subnormal range (the first product is exact).
        p * pow2(k + 100) * pow2(-100)
    } else {
        p * pow2(k)
    }
}

// ---------------------------------------------------------------------------------------
// atan, atan2

/// atan of `a ≥ 0` (or NaN), in [0, π/2].
///
/// atan a = atan c + atan t with t = (a − c)/(1 + a c) for c ∈ {0, ½, 1, 3/2, ∞}, chosen
/// so that |t| ≤ 7/16; the numerators are exact (Sterbenz), so t carries ~1 ulp of
/// relative error, which is small next to atan c.
#[inline]
fn atan_pos(a: f32) -> f32 {
    let (t, base_hi, base_lo) = if a < 0.4375 {
        // (NaN fails every comparison and comes out of the last branch as NaN.)
        let s = a * a;
        return a + a * s * (A0 + s * (A1 + s * (A2 + s * (A3 + s * A4))));
    } else if a < 0.6875 {
        ((2.0 * a - 1.0) / (2.0 + a), ATAN_HALF_HI, ATAN_HALF_LO)
    } else if a < 1.1875 {
        ((a - 1.0) / (a + 1.0), PIO4_HI, PIO4_LO)
    } else if a < 2.4375 {
        ((a - 1.5) / (1.0 + 1.5 * a), ATAN_3HALF_HI, ATAN_3HALF_LO)
    } else {
        (-1.0 / a, PIO2_HI, PIO2_LO)
    };
    let s = t * t;
    let poly = t * s * (A0 + s * (A1 + s * (A2 + s * (A3 + s * A4))));
    base_hi + (t + (poly + base_lo))
}

/// atan x in [−π/2, π/2]; ±π/2 at ±∞, NaN for NaN.
#[inline]
pub(crate) fn atan(x: f32) -> f32 {
    copysign(atan_pos(abs(x)), x)
}

/// Four-quadrant atan(y/x) in [−π, π], with C99's signed zeros and infinities.
pub(crate) fn atan2(y: f32, x: f32) -> f32 {
    if x.is_nan() || y.is_nan() {
        return x + y;
    }
    let (ax, ay) = (abs(x), abs(y));
    let x_neg = x.to_bits() & SIGN != 0;
    let mag = if ay == 0.0 && ax == 0.0 {
        if x_neg {
            PI_HI
        } else {
            0.0
        }
    } else if ax.is_infinite() && ay.is_infinite() {
        if x_neg {
            PI3O4_HI
        } else {
            PIO4_HI
        }
    } else if ay <= ax {
        // |y/x| ≤ 1 (0 when x is infinite).
        let t = atan_pos(ay / ax);
        if x_neg {
            PI_HI - (t - PI_LO)
        } else {
            t
        }
    } else {
        let t = atan_pos(ax / ay);
        if x_neg {
            PIO2_HI + (t + PIO2_LO)
        } else {
            PIO2_HI - (t - PIO2_LO)
        }
    };
    copysign(mag, y)
}

// ---------------------------------------------------------------------------------------
// round

/// `x` rounded to the nearest integer, halfway cases away from zero (libm's `roundf`),
/// keeping the sign of zero; NaN and ±∞ unchanged.
#[inline]
pub(crate) fn round(x: f32) -> f32 {
    let a = abs(x);
    if a.is_nan() || a >= 8_388_608.0 {
        return x; // |x| ≥ 2²³ is an integer already; NaN, ±∞
    }
    let t = a as i32;
    let mut r = t as f32;
    if a - r >= 0.5 {
        r += 1.0;
    }
    copysign(r, x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// The error of `got` in ulps of the exact value `want` (f64 accurate to 2⁻⁵²).
    fn ulps(got: f32, want: f64) -> f64 {
        if got.is_nan() || want.is_nan() {
            return if got.is_nan() && want.is_nan() { 0.0 } else { f64::INFINITY };
        }
        if f64::from(got) == want {
            return 0.0;
        }
        let aw = want.abs();
        // ulp of the f32 binade of `want` (subnormal spacing below 2⁻¹²⁶).
        let e = if aw < f64::from(f32::MIN_POSITIVE) { -126 } else { aw.log2().floor() as i32 };
        let e = e.min(127);
        let ulp = 2f64.powi(e - 23);
        (f64::from(got) - want).abs() / ulp
    }

    /// A sampling stride for the default tests: 16× sparser in unoptimised builds, where
    /// they would otherwise take minutes (`cargo test --release` runs them as stated).
    fn thin(step: u32) -> u32 {
        if cfg!(debug_assertions) {
            step * 16 + 1
        } else {
            step
        }
    }

    /// All f32 bit patterns from `lo` to `hi` (inclusive) with the given step.
    fn patterns(lo: u32, hi: u32, step: u32) -> impl Iterator<Item = f32> {
        (lo..=hi).step_by(step as usize).map(f32::from_bits)
    }

    /// Positive floats in [a, b] and their negatives, every `step`-th pattern.
    fn range(a: f32, b: f32, step: u32) -> impl Iterator<Item = f32> {
        patterns(a.to_bits(), b.to_bits(), step).flat_map(|x| [x, -x])
    }

    /// A stride over all 2³² bit patterns (an odd stride, so every exponent and sign
    /// is visited with varied mantissas).
    fn all_strided(step: u32) -> impl Iterator<Item = f32> {
        (0..=u32::MAX / step).map(move |i| f32::from_bits(i.wrapping_mul(step)))
    }

    struct Worst {
        max: f64,
        at: f32,
    }

    fn worst(xs: impl Iterator<Item = f32>, f: impl Fn(f32) -> f32, g: impl Fn(f64) -> f64) -> Worst {
        let mut w = Worst { max: 0.0, at: 0.0 };
        for x in xs {
            let e = ulps(f(x), g(f64::from(x)));
            if e > w.max || e.is_nan() {
                w = Worst { max: e, at: x };
            }
        }
        w
    }

    /// [`worst`] over the bit patterns `lo..=hi` (and their negatives if `both_signs`), split
    /// over every core: the exhaustive sweeps of CI.
    fn worst_par(lo: u32, hi: u32, both_signs: bool, f: fn(f32) -> f32, g: fn(f64) -> f64) -> Worst {
        let threads = std::thread::available_parallelism().map_or(1, core::num::NonZeroUsize::get) as u32;
        let chunk = (hi - lo) / threads + 1;
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..threads)
                .map(|i| {
                    let a = lo.saturating_add(i * chunk);
                    let b = a.saturating_add(chunk - 1).min(hi);
                    scope.spawn(move || {
                        if a > hi {
                            return Worst { max: 0.0, at: 0.0 };
                        }
                        let xs = patterns(a, b, 1);
                        if both_signs {
                            worst(xs.flat_map(|x| [x, -x]), f, g)
                        } else {
                            worst(xs, f, g)
                        }
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("a sweep thread"))
                .fold(Worst { max: 0.0, at: 0.0 }, |a, b| if b.max > a.max || b.max.is_nan() { b } else { a })
        })
    }

    fn check(name: &str, w: &Worst, bound: f64) {
        std::eprintln!("{name}: max {:.3} ulp at {:e} ({:#010x})", w.max, w.at, w.at.to_bits());
        assert!(w.max <= bound, "{name}: {} ulp at {:e} ({:#010x})", w.max, w.at, w.at.to_bits());
    }

    fn sin_(x: f32) -> f32 {
        sin_cos(x).0
    }
    fn cos_(x: f32) -> f32 {
        sin_cos(x).1
    }

    /// Every `step`-th f32 in [−2π, 2π] from 2⁻¹² up; the binades below are sampled
    /// (sin x = x and cos x = 1 there to within an ulp).
    fn sin_cos_two_turns(step: u32) {
        let lo = 2f32.powi(-12);
        let hi = core::f32::consts::TAU; // just above 2π
        let dense = || range(lo, hi, step);
        check("sin [2^-12, 2π]", &worst(dense(), sin_, libm::sin), 1.0);
        check("cos [2^-12, 2π]", &worst(dense(), cos_, libm::cos), 1.0);
        let tiny = || range(f32::from_bits(1), lo, 101);
        check("sin tiny", &worst(tiny(), sin_, libm::sin), 1.0);
        check("cos tiny", &worst(tiny(), cos_, libm::cos), 1.0);
    }

    #[test]
    fn sin_cos_two_turns_dense() {
        sin_cos_two_turns(thin(17));
    }

    /// Every f32 in [−2π, 2π] (CI runs the `#[ignore]`d sweeps: `cargo test --release -p
    /// companion-core --lib fastmath -- --ignored`).
    #[test]
    #[ignore = "every f32 in [-2π, 2π]: run by CI (.ci/run), about a minute on 2 cores"]
    fn sin_cos_two_turns_exhaustive() {
        let (lo, hi) = (1, core::f32::consts::TAU.to_bits());
        check("sin |x| ≤ 2π, every f32", &worst_par(lo, hi, true, sin_, libm::sin), 1.0);
        check("cos |x| ≤ 2π, every f32", &worst_par(lo, hi, true, cos_, libm::cos), 1.0);
    }

    #[test]
    fn sin_cos_whole_range_strided() {
        let xs = || all_strided(thin(997)).filter(|x| x.is_finite());
        check("sin strided", &worst(xs(), sin_, libm::sin), 1.0);
        check("cos strided", &worst(xs(), cos_, libm::cos), 1.0);
        // The cold path, densely: [128, 2²⁰] and near the top of the range.
        let cold = || range(128.0, 1_048_576.0, thin(29)).chain(range(1e30, f32::MAX, thin(1_009)));
        check("sin large", &worst(cold(), sin_, libm::sin), 1.0);
        check("cos large", &worst(cold(), cos_, libm::cos), 1.0);
    }

    /// Every f32 in (2π, 128]: with the sweep above, every argument of the hot path.
    #[test]
    #[ignore = "every f32 in (2π, 128]: run by CI (.ci/run), a minute on 2 cores"]
    fn sin_cos_exhaustive_hot_range() {
        let (lo, hi) = (core::f32::consts::TAU.to_bits() + 1, 128f32.to_bits());
        check("sin 2π < |x| ≤ 128, every f32", &worst_par(lo, hi, true, sin_, libm::sin), 1.0);
        check("cos 2π < |x| ≤ 128, every f32", &worst_par(lo, hi, true, cos_, libm::cos), 1.0);
    }

    #[test]
    fn sin_cos_special() {
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "{x}");
        }
        assert_eq!(sin_cos(0.0).0.to_bits(), 0.0f32.to_bits());
        assert_eq!(sin_cos(-0.0).0.to_bits(), (-0.0f32).to_bits());
        assert_eq!(sin_cos(0.0).1, 1.0);
        assert_eq!(sin_cos(f32::from_bits(1)).0, f32::from_bits(1));
        // Next to multiples of π/2, where the reduction cancels.
        for k in 1..200 {
            let m = f64::from(k) * core::f64::consts::FRAC_PI_2;
            let x = m as f32;
            for x in [x, f32::from_bits(x.to_bits() + 1), f32::from_bits(x.to_bits() - 1)] {
                assert!(ulps(sin_(x), libm::sin(f64::from(x))) <= 1.0, "sin {x}");
                assert!(ulps(cos_(x), libm::cos(f64::from(x))) <= 1.0, "cos {x}");
            }
        }
        // sin² + cos² = 1 for finite huge arguments: never garbage.
        for x in [f32::MAX, -f32::MAX, 1e38, 3.0e20, 16_777_216.0] {
            let (s, c) = sin_cos(x);
            assert!((s * s + c * c - 1.0).abs() < 1e-6, "{x}: {s} {c}");
        }
    }

    /// Every `step`-th f32 whose e^x is neither 0 nor ∞ (normal results within 1 ulp,
    /// subnormal ones within one unit of 2⁻¹⁴⁹).
    fn exp_range(step: u32) {
        let xs = || patterns(0, EXP_MAX.to_bits(), step).chain(patterns(SIGN, EXP_MIN.to_bits(), step));
        check("exp", &worst(xs(), exp, libm::exp), 1.0);
    }

    #[test]
    fn exp_dense() {
        exp_range(thin(101));
    }

    #[test]
    #[ignore = "every f32 in [-104, 89]: run by CI (.ci/run), half a minute on 2 cores"]
    fn exp_exhaustive() {
        check("exp x ≥ 0, every f32", &worst_par(0, EXP_MAX.to_bits(), false, exp, libm::exp), 1.0);
        check("exp x < 0, every f32", &worst_par(SIGN, EXP_MIN.to_bits(), false, exp, libm::exp), 1.0);
    }

    #[test]
    fn exp_special() {
        assert!(exp(f32::NAN).is_nan());
        assert_eq!(exp(f32::INFINITY), f32::INFINITY);
        assert_eq!(exp(f32::NEG_INFINITY), 0.0);
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(89.0), f32::INFINITY);
        assert_eq!(exp(EXP_MAX), libm::expf(EXP_MAX));
        assert!(exp(EXP_MAX).is_finite());
        assert_eq!(exp(-104.0), 0.0);
        assert_eq!(exp(EXP_MIN), f32::from_bits(1));
    }

    #[test]
    fn atan_dense() {
        check("atan strided", &worst(all_strided(thin(257)), atan, libm::atan), 1.0);
        check("atan [-64, 64]", &worst(range(1e-6, 64.0, thin(31)), atan, libm::atan), 1.0);
    }

    #[test]
    fn atan_special() {
        assert!(atan(f32::NAN).is_nan());
        assert_eq!(atan(f32::INFINITY), PIO2_HI);
        assert_eq!(atan(f32::NEG_INFINITY), -PIO2_HI);
        assert_eq!(atan(-0.0).to_bits(), (-0.0f32).to_bits());
        assert_eq!(atan(f32::MAX), PIO2_HI);
    }

    #[test]
    fn atan2_grid_and_special() {
        let mags: Vec<f32> = all_strided(1_000_003).filter(|x| x.is_finite() && *x >= 0.0).collect();
        let mut w = Worst { max: 0.0, at: 0.0 };
        for &a in &mags {
            for &b in mags.iter().step_by(7) {
                for (y, x) in [(a, b), (-a, b), (a, -b), (-a, -b)] {
                    let e = ulps(atan2(y, x), libm::atan2(f64::from(y), f64::from(x)));
                    if e > w.max {
                        w = Worst { max: e, at: y / x };
                    }
                }
            }
        }
        check("atan2 grid", &w, 2.0);
        let inf = f32::INFINITY;
        let specials = [0.0, -0.0, 1.0, -1.0, inf, -inf, f32::NAN, f32::MAX, f32::from_bits(1)];
        for &y in &specials {
            for &x in &specials {
                let (got, want) = (atan2(y, x), libm::atan2f(y, x));
                let ok = (got.is_nan() && want.is_nan())
                    || got.to_bits() == want.to_bits()
                    || ulps(got, libm::atan2(f64::from(y), f64::from(x))) <= 2.0;
                assert!(ok, "atan2({y}, {x}) = {got}, libm {want}");
            }
        }
    }

    fn same_bits(name: &str, xs: impl Iterator<Item = f32>, f: impl Fn(f32) -> f32, g: impl Fn(f32) -> f32) {
        for x in xs {
            let (a, b) = (f(x), g(x));
            assert!(
                a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                "{name}({x:e}) = {a:e}, want {b:e}"
            );
        }
    }

    #[test]
    fn round_matches_libm() {
        same_bits("round", all_strided(thin(97)), round, libm::roundf);
        same_bits("round", range(1e-3, 1e7, thin(7)), round, libm::roundf);
        for x in [0.5f32, -0.5, 1.5, -2.5, 0.499_999_97, 8_388_607.5, -0.0, 0.0] {
            assert_eq!(round(x).to_bits(), libm::roundf(x).to_bits(), "{x}");
        }
    }
}
