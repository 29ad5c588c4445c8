//! Per-value error statistics of a test image against a reference.
//!
//! Sums are `f64` in the order values are added, so one pass over the same
//! data gives the same bits on every machine and thread count.

use serde::Serialize;

/// Errors above this are visible in an 8-bit image.
pub const VISIBLE_ERROR: f64 = 1.0 / 255.0;

/// Summary of `|test − reference|` over a set of values.
///
/// A non-finite value on either side (NaN, ±inf) is counted in `count` and
/// `non_finite`, counts as over [`VISIBLE_ERROR`], and makes `rmse`,
/// `mean_abs` and `max_abs` `+inf`, so no tolerance can pass it. An empty
/// set gives all zeros.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct ErrorMetrics {
    /// Values compared (finite and non-finite).
    pub count: u64,
    /// Root of the mean squared error.
    pub rmse: f64,
    /// Mean absolute error.
    pub mean_abs: f64,
    /// Largest absolute error.
    pub max_abs: f64,
    /// Fraction of `count` whose error exceeds [`VISIBLE_ERROR`].
    pub frac_over: f64,
    /// Values where the test or the reference was NaN or infinite.
    pub non_finite: u64,
}

/// Running sums behind [`ErrorMetrics`]: [`add`](Self::add) values one by
/// one, [`merge`](Self::merge) partial results (e.g. channels or tiles),
/// [`finish`](Self::finish) at the end.
///
/// Counts and the maximum merge exactly; the sums are `f64`, so a merge
/// equals one pass over the concatenated values up to rounding (exactly when
/// the partial sums are exact). Merge in a fixed order for fixed bits.
#[derive(Debug, Clone, Default)]
pub struct ErrorAccumulator {
    /// Finite errors added.
    finite: u64,
    /// Non-finite values added.
    non_finite: u64,
    /// Finite errors above [`VISIBLE_ERROR`].
    over: u64,
    sum_abs: f64,
    sum_sq: f64,
    max_abs: f64,
}

impl ErrorAccumulator {
    /// Adds one compared value.
    pub fn add(&mut self, test: f64, reference: f64) {
        if !test.is_finite() || !reference.is_finite() {
            self.non_finite += 1;
            return;
        }
        let e = (test - reference).abs();
        self.finite += 1;
        self.sum_abs += e;
        self.sum_sq += e * e;
        if e > self.max_abs {
            self.max_abs = e;
        }
        if e > VISIBLE_ERROR {
            self.over += 1;
        }
    }

    /// Adds everything `other` has accumulated.
    pub fn merge(&mut self, other: &ErrorAccumulator) {
        self.finite += other.finite;
        self.non_finite += other.non_finite;
        self.over += other.over;
        self.sum_abs += other.sum_abs;
        self.sum_sq += other.sum_sq;
        self.max_abs = self.max_abs.max(other.max_abs);
    }

    /// The metrics of everything added so far.
    pub fn finish(&self) -> ErrorMetrics {
        let count = self.finite + self.non_finite;
        if count == 0 {
            return ErrorMetrics::default();
        }
        let frac_over = (self.over + self.non_finite) as f64 / count as f64;
        if self.non_finite > 0 {
            return ErrorMetrics {
                count,
                rmse: f64::INFINITY,
                mean_abs: f64::INFINITY,
                max_abs: f64::INFINITY,
                frac_over,
                non_finite: self.non_finite,
            };
        }
        let n = self.finite as f64;
        ErrorMetrics {
            count,
            rmse: (self.sum_sq / n).sqrt(),
            mean_abs: self.sum_abs / n,
            max_abs: self.max_abs,
            frac_over,
            non_finite: 0,
        }
    }
}

/// Metrics of `test` against `reference` over the indices where `include(i)` holds.
///
/// Slices of different lengths are compared over their common prefix
/// (`min` of the lengths); callers that need equal sizes check them first.
pub fn error_metrics(
    test: &[f32],
    reference: &[f32],
    include: impl Fn(usize) -> bool,
) -> ErrorMetrics {
    let mut acc = ErrorAccumulator::default();
    for (i, (&t, &r)) in test.iter().zip(reference).enumerate() {
        if include(i) {
            acc.add(f64::from(t), f64::from(r));
        }
    }
    acc.finish()
}
