//! Heading-error statistics, as the papers report them (mean ± std) and as users
//! compare tools (RMS, 95th percentile, share within ±5°).

use serde::Serialize;

use crate::base::angle::wrap_to_pi;

/// Parts shorter than this are scored on one thread (a thread costs tens of µs).
const MIN_SAMPLES_PER_THREAD: usize = 20_000;

/// How much field magnitudes vary: their standard deviation over their mean, percent
/// (MotionCal's "variance"), non-finite values left out; `None` for fewer
/// than two or a zero mean.
pub fn spread_pct(magnitudes: impl Iterator<Item = f64>) -> Option<f64> {
    let values: Vec<f64> = magnitudes.filter(|value| value.is_finite()).collect();
    if values.len() < 2 {
        return None;
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let variance = values
        .iter()
        .map(|value| (value - mean).powi(2))
        .sum::<f64>()
        / values.len() as f64;
    (mean > 0.0).then(|| 100.0 * variance.sqrt() / mean)
}

/// The median of `values` (the upper one of an even count; `f64::total_cmp`, NaN
/// last), reordering them; `None` when empty. One selection compiled for the crate.
pub fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let middle = values.len() / 2;
    Some(*values.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// The `q` quantile (0-1) of sorted values, linearly interpolated between ranks (numpy's
/// default); NaN when empty.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        n => {
            let rank = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let (low, high) = (rank.floor() as usize, rank.ceil() as usize);
            sorted[low] + (sorted[high] - sorted[low]) * (rank - low as f64)
        }
    }
}

/// Mean and sample standard deviation (n − 1; 0 for one value), the papers' "mean ±
/// std". The one owner of both for the crate: [`HeadingErrorStats`] takes its mean and
/// std from here too.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeanStd {
    pub n: usize,
    pub mean: f64,
    pub std: f64,
}

impl MeanStd {
    /// Of the finite values; `None` when there is none.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<MeanStd> {
        let values: Vec<f64> = values.into_iter().filter(|v| v.is_finite()).collect();
        MeanStd::of_finite(&values)
    }

    /// Of values known to be finite; `None` when empty.
    fn of_finite(values: &[f64]) -> Option<MeanStd> {
        let n = values.len();
        if n == 0 {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Some(MeanStd { n, mean, std })
    }
}

/// Statistics of a set of heading errors (estimate minus reference), in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HeadingErrorStats {
    pub n_samples: usize,
    pub mean_deg: f64,
    /// Sample standard deviation (n − 1).
    pub std_deg: f64,
    pub rms_deg: f64,
    /// 95th percentile of the absolute error.
    pub p95_abs_deg: f64,
    pub max_abs_deg: f64,
    /// Share of samples with |error| ≤ 5°, in percent.
    pub within_5_deg_pct: f64,
}

impl HeadingErrorStats {
    /// Statistics of `headings_rad` against the reference on one part of a train/check
    /// split: the samples whose `is_train` is `want_train` and that have a reference.
    pub fn on_part(
        headings_rad: &[f64],
        reference_rad: &[Option<f64>],
        is_train: &[bool],
        want_train: bool,
    ) -> Option<Self> {
        Self::from_errors_rad(
            headings_rad
                .iter()
                .zip(reference_rad)
                .zip(is_train)
                .filter_map(|((&heading_rad, &reference_rad), &train)| {
                    (train == want_train).then_some(heading_rad - reference_rad?)
                }),
        )
    }

    /// [`Self::on_part`] of the train part and of the check part, side by side on two
    /// cores when the log is long (each part is a pass, a copy and a selection).
    pub fn on_both_parts(
        headings_rad: &[f64],
        reference_rad: &[Option<f64>],
        is_train: &[bool],
    ) -> (Option<Self>, Option<Self>) {
        let part = |want_train| Self::on_part(headings_rad, reference_rad, is_train, want_train);
        let long = headings_rad.len() >= 2 * MIN_SAMPLES_PER_THREAD;
        let parts = if long {
            crate::base::par::on_each_small_part([true, false].into_iter(), part)
        } else {
            None
        };
        match parts.as_deref() {
            Some(&[train, check]) => (train, check),
            _ => (part(true), part(false)),
        }
    }

    /// Statistics of heading errors given in radians (wrapped here to ±π). Non-finite
    /// values are left out; `None` when nothing is left.
    pub fn from_errors_rad(errors_rad: impl IntoIterator<Item = f64>) -> Option<Self> {
        let errors_rad = errors_rad.into_iter();
        // Sized once: a part of an hour's log holds hundreds of thousands of errors.
        let (_, at_most) = errors_rad.size_hint();
        let mut errors_deg = Vec::with_capacity(at_most.unwrap_or(0));
        errors_deg.extend(
            errors_rad
                .filter(|error_rad| error_rad.is_finite())
                .map(|error_rad| wrap_to_pi(error_rad).to_degrees()),
        );
        let MeanStd {
            n: n_samples,
            mean: mean_deg,
            std: std_deg,
        } = MeanStd::of_finite(&errors_deg)?;
        let n = n_samples as f64;
        let (mut sum_sq, mut within_5, mut max_abs_deg) = (0.0, 0, 0.0f64);
        for error_deg in &mut errors_deg {
            sum_sq += *error_deg * *error_deg;
            let abs_deg = error_deg.abs();
            within_5 += usize::from(abs_deg <= 5.0);
            max_abs_deg = max_abs_deg.max(abs_deg);
            *error_deg = abs_deg;
        }
        let rms_deg = (sum_sq / n).sqrt();
        // Nearest-rank percentile: a selection, not a sort (the heading comparison
        // scores hundreds of thousands of samples per method).
        let p95_rank = ((0.95 * n).ceil() as usize).clamp(1, n_samples);
        let (_, p95_abs_deg, _) = errors_deg.select_nth_unstable_by(p95_rank - 1, f64::total_cmp);
        Some(HeadingErrorStats {
            n_samples,
            mean_deg,
            std_deg,
            rms_deg,
            p95_abs_deg: *p95_abs_deg,
            max_abs_deg,
            within_5_deg_pct: 100.0 * within_5 as f64 / n,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_std_over_mean() {
        assert_eq!(spread_pct([50.0, 50.0].into_iter()), Some(0.0));
        let spread = spread_pct([45.0, 55.0].into_iter()).unwrap();
        assert!((spread - 10.0).abs() < 1e-12, "{spread}");
        assert_eq!(spread_pct([50.0].into_iter()), None);
        assert_eq!(spread_pct([f64::NAN, 1.0].into_iter()), None);
    }

    #[test]
    fn known_errors_give_known_statistics() {
        let errors_deg = [1.0, -1.0, 3.0, -3.0, 10.0];
        let stats =
            HeadingErrorStats::from_errors_rad(errors_deg.iter().map(|e: &f64| e.to_radians()))
                .expect("some errors");
        assert_eq!(stats.n_samples, 5);
        assert!((stats.mean_deg - 2.0).abs() < 1e-9);
        assert!((stats.rms_deg - (120.0f64 / 5.0).sqrt()).abs() < 1e-9);
        assert!((stats.std_deg - (100.0f64 / 4.0).sqrt()).abs() < 1e-9);
        assert!((stats.max_abs_deg - 10.0).abs() < 1e-9);
        assert!((stats.p95_abs_deg - 10.0).abs() < 1e-9);
        assert!((stats.within_5_deg_pct - 80.0).abs() < 1e-9);
    }

    #[test]
    fn errors_are_wrapped_before_averaging() {
        let stats = HeadingErrorStats::from_errors_rad([359f64.to_radians(), 1f64.to_radians()])
            .expect("two errors");
        assert!(stats.mean_deg.abs() < 1e-9);
        assert!((stats.rms_deg - 1.0).abs() < 1e-9);
    }

    #[test]
    fn nothing_finite_gives_nothing() {
        assert_eq!(HeadingErrorStats::from_errors_rad([f64::NAN]), None);
        assert_eq!(HeadingErrorStats::from_errors_rad([]), None);
    }
}
