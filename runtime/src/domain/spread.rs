//! The spread of one figure over repeated runs: median, quartiles, best and worst — what
//! `companion latency --repeat` reports per wait mode and load, and what its box plot draws.
//!
//! The quartiles interpolate linearly between order statistics: for `n` sorted values
//! `x₀ ≤ … ≤ x₍ₙ₋₁₎`, the `q`-quantile is `x_⌊h⌋ + (h − ⌊h⌋)(x_⌊h⌋₊₁ − x_⌊h⌋)` with
//! `h = q·(n − 1)` (numpy's and R's default, type 7): the median of an even count is the mean
//! of the middle two, and one run's spread is that run's value throughout.

use serde::Serialize;

/// Median, quartiles and extremes of a figure over runs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spread {
    /// Runs.
    pub runs: usize,
    /// The median.
    pub median: f64,
    /// The first quartile.
    pub q1: f64,
    /// The third quartile.
    pub q3: f64,
    /// The smallest value.
    pub best: f64,
    /// The largest value (for misses and latencies: the worst).
    pub worst: f64,
}

impl Spread {
    /// The spread of `values` (`None` if there are none or one is not finite).
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        Some(Self {
            runs: v.len(),
            median: quantile(&v, 0.5),
            q1: quantile(&v, 0.25),
            q3: quantile(&v, 0.75),
            best: v[0],
            worst: v[v.len() - 1],
        })
    }

    /// The interquartile range.
    pub fn iqr(&self) -> f64 {
        self.q3 - self.q1
    }
}

/// The `q`-quantile of sorted, non-empty `v` (see the module docs).
fn quantile(v: &[f64], q: f64) -> f64 {
    let h = q * (v.len() - 1) as f64;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(v.len() - 1);
    v[lo] + (h - lo as f64) * (v[hi] - v[lo])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_quartiles_interpolate_between_runs() {
        // 1..=10 in any order: median 5.5, quartiles at h = 2.25 and 6.75.
        let s = Spread::of(&[7.0, 1.0, 10.0, 3.0, 2.0, 9.0, 4.0, 8.0, 6.0, 5.0]).unwrap();
        assert_eq!((s.runs, s.median, s.q1, s.q3, s.best, s.worst), (10, 5.5, 3.25, 7.75, 1.0, 10.0));
        assert_eq!(s.iqr(), 4.5);
        // An odd count: the middle value.
        let s = Spread::of(&[40.0, 0.0, 3.0]).unwrap();
        assert_eq!((s.median, s.q1, s.q3), (3.0, 1.5, 21.5));
        // One run: its value throughout.
        let s = Spread::of(&[12.0]).unwrap();
        assert_eq!((s.median, s.q1, s.q3, s.best, s.worst), (12.0, 12.0, 12.0, 12.0, 12.0));
        assert_eq!(Spread::of(&[]), None);
        assert_eq!(Spread::of(&[1.0, f64::NAN]), None);
        // Negative values (misses beyond the bare transport's) sort below zero.
        let s = Spread::of(&[-15.0, -2.0, -3.0]).unwrap();
        assert_eq!((s.median, s.best, s.worst), (-3.0, -15.0, -2.0));
    }
}
