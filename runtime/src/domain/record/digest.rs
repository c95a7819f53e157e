//! The trajectory digest: one 64-bit fingerprint of every step a run took.
//!
//! FNV-1a over the IEEE-754 bit patterns (little-endian) of, per step, the plant's time,
//! pose, steering and joints and the command applied (`v`, `v_lat`, `ω`, `v_ξ`, `u_q`).
//! Two runs share a digest only if every one of these numbers is bit-identical at every step,
//! so it catches any drift — a changed operation order, a different libm, another
//! compiler's contraction — that the summary's rounded figures would hide. The repository
//! keeps the digests of reference runs (`runtime/tests/golden/digests.txt`), checked by a
//! fresh process in `runtime/tests/golden.rs`; `summary.json` reports it as 16 hex digits.

use companion_core::Space;

use super::row::Row;

/// FNV-1a's 64-bit offset basis.
const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a's 64-bit prime.
const PRIME: u64 = 0x0000_0100_0000_01b3;

/// A streaming FNV-1a (64 bits) over the steps of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TrajectoryDigest(u64);

impl Default for TrajectoryDigest {
    fn default() -> Self {
        Self(OFFSET)
    }
}

impl TrajectoryDigest {
    /// Folds bytes in.
    pub fn bytes(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 ^ u64::from(*b)).wrapping_mul(PRIME);
        }
    }

    /// Folds one number in (its bit pattern: `0.0` and `-0.0` differ, every NaN payload too).
    pub fn number(&mut self, x: f64) {
        self.bytes(&x.to_bits().to_le_bytes());
    }

    /// Folds one step in: the plant's state and the command applied (of either arm: the
    /// target is not folded in, the joints are as many as the arm has).
    pub fn add<S: Space<f64>, const N: usize>(&mut self, row: &Row<S, N>) {
        let p = &row.plant;
        let c = &row.report.command;
        for x in [p.t, p.base.x, p.base.y, p.base.theta, p.steering] {
            self.number(x);
        }
        for q in p.joints.iter() {
            self.number(*q);
        }
        for x in [c.platform.v, c.platform.v_lat, c.platform.omega, c.platform.v_xi] {
            self.number(x);
        }
        for u in c.joints.iter() {
            self.number(*u);
        }
    }

    /// The digest.
    pub fn value(&self) -> u64 {
        self.0
    }

    /// The digest as 16 lower-case hex digits (how `summary.json` and the golden file
    /// write it: a JSON number would lose bits).
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_fnv1a_reference_values() {
        // The published FNV-1a 64 test vectors.
        let mut d = TrajectoryDigest::default();
        assert_eq!(d.value(), 0xcbf2_9ce4_8422_2325);
        d.bytes(b"a");
        assert_eq!(d.value(), 0xaf63_dc4c_8601_ec8c);
        let mut d = TrajectoryDigest::default();
        d.bytes(b"foobar");
        assert_eq!(d.value(), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn sees_the_sign_of_zero() {
        let (mut a, mut b) = (TrajectoryDigest::default(), TrajectoryDigest::default());
        a.number(0.0);
        b.number(-0.0);
        assert_ne!(a, b);
        assert_eq!(a.hex().len(), 16);
    }
}
