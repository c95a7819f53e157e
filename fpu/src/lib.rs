//! # companion-fpu
//!
//! The square root of an `f32` as the hardware computes it: on a hard-float ARM core (a
//! Cortex-M4F, any `eabihf` target) the FPU's `vsqrt.f32`, one instruction; elsewhere libm's
//! `sqrtf`. Both are the correctly rounded IEEE-754 square root, so they give the same bits
//! for every input but NaN payloads (a negative or NaN input gives a NaN either way): the law
//! is bit for bit the same on the host and on the firmware (`tests/tests/firmware_host.rs`,
//! and the firmware compares the two on a sweep of every 4 093rd `f32` bit pattern).
//!
//! Why a crate of its own: `core` has no `f32::sqrt` on a stable toolchain without `std`
//! (`core_float_math` is unstable in Rust 1.95) and the instruction needs inline assembly,
//! hence `unsafe`, which `companion-core` forbids. libm's `sqrtf` is integer code, ~50
//! instructions per call on the Cortex-M4F; the law takes three to six square roots a step
//! (`tests/firmware/README.md`).
#![no_std]

/// `√x`, correctly rounded (NaN for `x < 0` or NaN; `−0` for `−0`).
#[inline(always)]
pub fn sqrt_f32(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let bits: u32;
        // The operands go through core registers and `s0`: Rust's `sreg` register class
        // needs the double-precision `vfp2` feature, which a Cortex-M4F (`vfp4d16sp`) lacks.
        // SAFETY: the three instructions read `x`'s bits from a core register, take the root
        // in `s0` (declared clobbered, so the compiler keeps nothing there) and write its bits
        // to another core register; they touch no memory and no stack, and on an `eabihf`
        // target the FPU is enabled before any Rust code runs (the hard-float calling
        // convention passes every `f32` in its registers).
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {root}, s0",
                x = in(reg) x.to_bits(),
                root = lateout(reg) bits,
                out("s0") _,
                options(pure, nomem, nostack),
            );
        }
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

#[cfg(test)]
mod tests {
    use super::sqrt_f32;

    /// Correctly rounded: `r²` brackets `x` within half an ulp of `r` (checked in `f64`, where
    /// the products are exact), on a stride over every positive finite `f32`.
    #[test]
    fn the_root_is_correctly_rounded() {
        let mut bits = 0u32;
        while bits < 0x7f80_0000 {
            let x = f32::from_bits(bits);
            let r = sqrt_f32(x);
            let (lo, hi) = (
                f64::from(f32::from_bits(r.to_bits().wrapping_sub(1))),
                f64::from(f32::from_bits(r.to_bits() + 1)),
            );
            let (r, x) = (f64::from(r), f64::from(x));
            // x lies between the squares of the midpoints to r's neighbours.
            if bits > 0 {
                assert!(((lo + r) / 2.0).powi(2) <= x && x <= ((r + hi) / 2.0).powi(2), "{x:e}: {r:e}");
            }
            bits += 4093;
        }
        assert_eq!(sqrt_f32(0.0).to_bits(), 0);
        assert_eq!(sqrt_f32(-0.0).to_bits(), (-0.0f32).to_bits());
        assert!(sqrt_f32(-1.0).is_nan() && sqrt_f32(f32::NAN).is_nan());
        assert_eq!(sqrt_f32(f32::INFINITY), f32::INFINITY);
    }
}
