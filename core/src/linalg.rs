//! Small dense linear algebra for the spatial law's 6×6 and 7×7 matrices.
//!
//! nalgebra inverts matrices above 4×4 through its general LU decomposition and triangular
//! solves, written for any size and storage; on a Cortex-M4F in `f32` a 6×6 inverse and a
//! determinant that way cost ~4 000 instructions. These are the textbook algorithms for a
//! size known at compile time: Gauss–Jordan elimination with partial pivoting (the inverse)
//! and Gaussian elimination with partial pivoting (the determinant). Up to 4×4 the law
//! keeps nalgebra's closed forms, so the planar law's arithmetic is unchanged.

use nalgebra::SMatrix;

use crate::scalar::Real;

/// `A⁻¹` by Gauss–Jordan elimination with partial pivoting; `None` when a pivot is zero or
/// not finite (`A` singular to working precision, or not finite).
pub(crate) fn inverse<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> Option<SMatrix<T, N, N>> {
    if N <= 4 {
        return a.try_inverse();
    }
    let mut m = *a;
    let mut inv = SMatrix::<T, N, N>::identity();
    for col in 0..N {
        let (piv, best) = pivot(&m, col);
        if best <= T::zero() || !best.finite() {
            return None;
        }
        if piv != col {
            m.swap_rows(piv, col);
            inv.swap_rows(piv, col);
        }
        let d = T::one() / m[(col, col)];
        for c in 0..N {
            m[(col, c)] *= d;
            inv[(col, c)] *= d;
        }
        for r in 0..N {
            if r == col {
                continue;
            }
            let f = m[(r, col)];
            if f == T::zero() {
                continue;
            }
            for c in 0..N {
                let (mc, ic) = (m[(col, c)], inv[(col, c)]);
                m[(r, c)] -= f * mc;
                inv[(r, c)] -= f * ic;
            }
        }
    }
    Some(inv)
}

/// `det A` by Gaussian elimination with partial pivoting (0 for a zero pivot).
pub(crate) fn determinant<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> T {
    let mut m = *a;
    let mut det = T::one();
    for col in 0..N {
        let (piv, best) = pivot(&m, col);
        if best == T::zero() {
            return T::zero();
        }
        if piv != col {
            m.swap_rows(piv, col);
            det = -det;
        }
        let p = m[(col, col)];
        det *= p;
        let d = T::one() / p;
        for r in col + 1..N {
            let f = m[(r, col)] * d;
            for c in col + 1..N {
                let mc = m[(col, c)];
                m[(r, c)] -= f * mc;
            }
        }
    }
    det
}

/// Partial pivoting: the row of the largest magnitude in column `col`, at or below the
/// diagonal (the first of equals), and that magnitude.
#[inline(always)]
fn pivot<T: Real, const N: usize>(m: &SMatrix<T, N, N>, col: usize) -> (usize, T) {
    let mut piv = col;
    let mut best = m[(col, col)].abs();
    for r in col + 1..N {
        let v = m[(r, col)].abs();
        if v > best {
            best = v;
            piv = r;
        }
    }
    (piv, best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix6;
    use proptest::prelude::*;

    fn matrix() -> impl Strategy<Value = Matrix6<f64>> {
        prop::collection::vec(-2.0..2.0f64, 36).prop_map(|v| Matrix6::from_row_slice(&v))
    }

    proptest! {
        /// Against nalgebra's LU: the same inverse and determinant to rounding.
        #[test]
        fn agrees_with_nalgebra(a in matrix()) {
            let det = a.determinant();
            let ours = determinant(&a);
            prop_assert!((ours - det).abs() <= 1e-10 * det.abs().max(1.0), "det {ours} vs {det}");
            if det.abs() > 1e-3 {
                let inv = inverse(&a).expect("invertible");
                prop_assert!((inv * a - Matrix6::identity()).amax() < 1e-9);
                prop_assert!((inv - a.try_inverse().expect("invertible")).amax() < 1e-9 * inv.amax().max(1.0));
            }
        }
    }

    #[test]
    fn singular_and_non_finite() {
        let mut a = Matrix6::<f64>::identity();
        a[(3, 3)] = 0.0;
        assert!(inverse(&a).is_none());
        assert_eq!(determinant(&a), 0.0);
        a[(3, 3)] = f64::NAN;
        assert!(inverse(&a).is_none());
        // A permutation: det −1, inverse its transpose.
        let mut p = Matrix6::<f64>::zeros();
        for i in 0..6 {
            p[(i, (i + 1) % 6)] = 1.0;
        }
        assert_eq!(determinant(&p), -1.0);
        assert_eq!(inverse(&p), Some(p.transpose()));
    }
}
