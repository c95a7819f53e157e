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
///
/// In place (one array holds what is left of `A` and the inverse's columns found so far):
/// the textbook `[A | I]` elimination spends half of its work on entries known to be zero
/// or one — `A`'s eliminated columns and `I`'s columns not yet reached. Here the column
/// eliminated at step `k` is replaced by the inverse's column of the pivot row's original
/// index, and only the live entries are updated, with the same operations in the same order
/// as the `[A | I]` form: the same bits (but possibly the sign of an entry that is exactly
/// zero), for half the arithmetic (measured: 3 034 → ~1 400 instructions for a 6×6 in `f32`
/// on a Cortex-M4F).
pub(crate) fn inverse<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> Option<SMatrix<T, N, N>> {
    let mut m = *a;
    invert(&mut m).then_some(m)
}

/// [`inverse`] in place: `m` becomes `m⁻¹` and `true`, or `false` (and `m` undefined) when a
/// pivot is zero or not finite. Spares the copies of a matrix returned by value (two of
/// 144 B for a 6×6 in `f32`, ~250 instructions on the Cortex-M4F).
pub(crate) fn invert<T: Real, const N: usize>(m: &mut SMatrix<T, N, N>) -> bool {
    if N <= 4 {
        return m.try_inverse_mut();
    }
    // The original row index of each row (row swaps permute them): the inverse's column
    // that the pivot of step k starts (a unit vector at that row in `[A | I]`).
    let mut origin = [0usize; N];
    for (i, o) in origin.iter_mut().enumerate() {
        *o = i;
    }
    for col in 0..N {
        let (piv, best) = pivot(m, col);
        if best <= T::zero() || !best.finite() {
            return false;
        }
        if piv != col {
            m.swap_rows(piv, col);
            origin.swap(piv, col);
        }
        let d = T::one() / m[(col, col)];
        for c in 0..N {
            m[(col, c)] *= d;
        }
        // The pivot row's entry of the new inverse column: 1 · d (in place of A's, which
        // is not needed any more).
        m[(col, col)] = d;
        for r in 0..N {
            if r == col {
                continue;
            }
            let f = m[(r, col)];
            if f == T::zero() {
                continue;
            }
            // Every column, also `col` (a fixed trip count, unrolled), which is then set.
            for c in 0..N {
                let mc = m[(col, c)];
                m[(r, c)] -= f * mc;
            }
            // 0 − f·d: the other rows' entries of the new inverse column.
            m[(r, col)] = -(f * d);
        }
    }
    // Column k holds the inverse's column `origin[k]`: put each where it belongs (a cycle
    // of swaps, no copy of the matrix).
    for k in 0..N {
        while origin[k] != k {
            let o = origin[k];
            m.swap_columns(k, o);
            origin.swap(k, o);
        }
    }
    true
}

/// `A B`, summed as nalgebra sums it (`c_ij = a_i0 b_0j`, then `+ a_ik b_kj` for `k = 1, 2, …`:
/// the same bits), with each sum kept in a register: nalgebra's product of fixed-size matrices
/// loads and stores every partial sum (measured on the Cortex-M4F in `f32`: 6×6 by 6×3,
/// 516 instructions against ~330).
#[inline]
pub(crate) fn mul<T: Real, const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<T, R, K>,
    b: &SMatrix<T, K, C>,
) -> SMatrix<T, R, C> {
    let mut c = SMatrix::<T, R, C>::zeros();
    for j in 0..C {
        for i in 0..R {
            let mut s = a[(i, 0)] * b[(0, j)];
            for k in 1..K {
                s += a[(i, k)] * b[(k, j)];
            }
            c[(i, j)] = s;
        }
    }
    c
}

/// `det A` by Gaussian elimination with partial pivoting (0 for a zero pivot).
pub(crate) fn determinant<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> T {
    let mut m = *a;
    determinant_in_place(&mut m)
}

/// [`determinant`] of `m`, which it overwrites (no copy).
pub(crate) fn determinant_in_place<T: Real, const N: usize>(m: &mut SMatrix<T, N, N>) -> T {
    let mut det = T::one();
    for col in 0..N {
        let (piv, best) = pivot(m, col);
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
            // Every column (a fixed trip count, unrolled): those up to `col` are never read
            // again, those after it get the textbook update.
            for c in 0..N {
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

    /// The textbook `[A | I]` Gauss–Jordan elimination that [`inverse`] does in place.
    fn inverse_augmented<const N: usize>(a: &SMatrix<f64, N, N>) -> Option<SMatrix<f64, N, N>> {
        let mut m = *a;
        let mut inv = SMatrix::<f64, N, N>::identity();
        for col in 0..N {
            let (piv, best) = pivot(&m, col);
            if best <= 0.0 || !best.is_finite() {
                return None;
            }
            m.swap_rows(piv, col);
            inv.swap_rows(piv, col);
            let d = 1.0 / m[(col, col)];
            for c in 0..N {
                m[(col, c)] *= d;
                inv[(col, c)] *= d;
            }
            for r in (0..N).filter(|&r| r != col) {
                let f = m[(r, col)];
                if f == 0.0 {
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

    proptest! {
        /// The in-place elimination gives the `[A | I]` form's bits (a zero's sign aside),
        /// also for f32 and with exact zeros in `A`.
        #[test]
        fn in_place_inverse_is_the_augmented_one_bit_for_bit(a in matrix(), zeros in prop::collection::vec(0usize..36, 0..8)) {
            let mut a = a;
            for z in zeros {
                a[(z / 6, z % 6)] = 0.0;
            }
            let want = inverse_augmented(&a);
            let got = inverse(&a);
            prop_assert_eq!(want.is_some(), got.is_some());
            if let (Some(w), Some(g)) = (want, got) {
                for (x, y) in w.iter().zip(g.iter()) {
                    prop_assert!(x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0), "{x:e} vs {y:e}");
                }
            }
        }
    }

    proptest! {
        /// [`mul`] gives nalgebra's product bit for bit.
        #[test]
        fn mul_is_nalgebras_product_bit_for_bit(a in matrix(), b in matrix()) {
            let b3 = b.fixed_columns::<3>(0).into_owned();
            prop_assert_eq!(mul(&a, &b3), a * b3);
            prop_assert_eq!(mul(&a, &b), a * b);
            let v = b.column(4).into_owned();
            prop_assert_eq!(mul(&a, &v), a * v);
            let (af, bf) = (a.map(|x| x as f32), b3.map(|x| x as f32));
            prop_assert_eq!(mul(&af, &bf), af * bf);
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
