//! PDR accuracy as the paper reports it (Chen et al., Tables I, III and IV).
//!
//! - Position error at reference points: RMS and maximum in metres and in % of the
//!   distance travelled (Table III); the distance is the reference path's length over
//!   the evaluated span.
//! - Travelled-distance error: the PDR's distance against the reference's, in %
//!   (Tables I and IV).
//! - Step-length error and heading error: mean and standard deviation (Table IV).
//! - For closed loops: the gap between end and start in % of the loop's length.
//! - Beyond the paper: the median and 75th percentile of the position errors (the IPIN
//!   competitions' P75), and the share of errors within 1 and 2 × the track's stated σ,
//!   which says whether the σ can be believed.

use serde::Serialize;

use super::fusion::TrackPoint;
use crate::base::angle::wrap_to_pi;
use crate::base::stats::MeanStd;

/// Position errors over a span.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PositionErrors {
    pub start_s: f64,
    pub end_s: f64,
    pub n_points: usize,
    pub rms_m: f64,
    pub max_m: f64,
    /// Distance travelled along the reference over the span (m).
    pub distance_m: f64,
    pub rms_pct: f64,
    pub max_pct: f64,
    /// PDR distance over the span minus the reference's, in % of the reference's.
    pub distance_error_pct: f64,
    /// The median and the 75th percentile of the errors (m): the IPIN competitions'
    /// metric is the latter.
    pub median_m: f64,
    pub p75_m: f64,
    /// The share of the errors within 1 and 2 × the track's stated `position_sigma_m`
    /// (%): a σ that holds covers about 63 % and 98 % (√(σ_E² + σ_N²) of a circular
    /// normal).
    pub within_1_sigma_pct: f64,
    pub within_2_sigma_pct: f64,
}

/// The loop-closure error of a walk that ends where it started.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoopClosure {
    pub gap_m: f64,
    pub length_m: f64,
    pub gap_pct: f64,
}

/// The track's position at `t_s`, linear between track points; `None` outside it.
pub fn position_at(track: &[TrackPoint], t_s: f64) -> Option<[f64; 2]> {
    Some([
        interpolate_at(track, t_s, |point| point.east_m)?,
        interpolate_at(track, t_s, |point| point.north_m)?,
    ])
}

/// The track's stated position σ at `t_s`, linearly interpolated.
pub fn sigma_at(track: &[TrackPoint], t_s: f64) -> Option<f64> {
    interpolate_at(track, t_s, |point| point.position_sigma_m)
}

/// One value of the track at `t_s`, linear between track points; `None` outside it.
fn interpolate_at(
    track: &[TrackPoint],
    t_s: f64,
    value: impl Fn(&TrackPoint) -> f64,
) -> Option<f64> {
    let first = track.first()?;
    let last = track.last()?;
    if !(first.t_s..=last.t_s).contains(&t_s) {
        return None;
    }
    let after = track
        .partition_point(|point| point.t_s < t_s)
        .min(track.len() - 1);
    let (a, b) = (track.get(after.saturating_sub(1))?, track.get(after)?);
    let span_s = b.t_s - a.t_s;
    let fraction = if span_s > 0.0 {
        (t_s - a.t_s) / span_s
    } else {
        1.0
    };
    Some(value(a) + (value(b) - value(a)) * fraction)
}

/// The length of the track between two times (m).
pub fn track_distance_m(track: &[TrackPoint], start_s: f64, end_s: f64) -> f64 {
    let mut points: Vec<[f64; 2]> = Vec::new();
    points.extend(position_at(track, start_s));
    points.extend(
        track
            .iter()
            .filter(|point| point.t_s > start_s && point.t_s < end_s)
            .map(|point| [point.east_m, point.north_m]),
    );
    points.extend(position_at(track, end_s));
    path_length_m(&points)
}

pub fn path_length_m(points: &[[f64; 2]]) -> f64 {
    points
        .windows(2)
        .map(|pair| ((pair[1][0] - pair[0][0]).powi(2) + (pair[1][1] - pair[0][1]).powi(2)).sqrt())
        .sum()
}

/// Position errors at the reference points `(t, [E, N])` within `[start_s, end_s]`.
/// `None` without two reference points in the span that the track covers.
pub fn position_errors(
    track: &[TrackPoint],
    reference: &[(f64, [f64; 2])],
    start_s: f64,
    end_s: f64,
) -> Option<PositionErrors> {
    let in_span: Vec<&(f64, [f64; 2])> = reference
        .iter()
        .filter(|(t_s, _)| (start_s..=end_s).contains(t_s))
        .collect();
    let (errors, sigmas): (Vec<f64>, Vec<f64>) = in_span
        .iter()
        .filter_map(|(t_s, truth)| {
            let estimate = position_at(track, *t_s)?;
            let error_m =
                ((estimate[0] - truth[0]).powi(2) + (estimate[1] - truth[1]).powi(2)).sqrt();
            Some((error_m, sigma_at(track, *t_s)?))
        })
        .unzip();
    if errors.len() < 2 {
        return None;
    }
    let reference_points: Vec<[f64; 2]> = in_span.iter().map(|(_, point)| *point).collect();
    let distance_m = path_length_m(&reference_points);
    let first_s = in_span.first().map_or(start_s, |(t_s, _)| *t_s);
    let last_s = in_span.last().map_or(end_s, |(t_s, _)| *t_s);
    let pdr_distance_m = track_distance_m(track, first_s, last_s);
    let rms_m = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let max_m = errors.iter().copied().fold(0.0, f64::max);
    let pct = |metres: f64| {
        if distance_m > 0.0 {
            100.0 * metres / distance_m
        } else {
            f64::NAN
        }
    };
    let within = |k: f64| {
        100.0
            * errors
                .iter()
                .zip(&sigmas)
                .filter(|(e, s)| **e <= k * **s)
                .count() as f64
            / errors.len() as f64
    };
    let mut sorted = errors.clone();
    sorted.sort_by(f64::total_cmp);
    Some(PositionErrors {
        median_m: crate::base::stats::quantile_sorted(&sorted, 0.5),
        p75_m: crate::base::stats::quantile_sorted(&sorted, 0.75),
        within_1_sigma_pct: within(1.0),
        within_2_sigma_pct: within(2.0),
        start_s: first_s,
        end_s: last_s,
        n_points: errors.len(),
        rms_m,
        max_m,
        distance_m,
        rms_pct: pct(rms_m),
        max_pct: pct(max_m),
        distance_error_pct: pct(pdr_distance_m - distance_m),
    })
}

/// Heading errors (estimate minus reference), wrapped, in degrees.
pub fn heading_error_deg(pairs: impl IntoIterator<Item = (f64, f64)>) -> Option<MeanStd> {
    MeanStd::of(
        pairs.into_iter().map(|(estimate_rad, reference_rad)| {
            wrap_to_pi(estimate_rad - reference_rad).to_degrees()
        }),
    )
}

/// The gap between the track's end and start, against the loop's length.
pub fn loop_closure(track: &[TrackPoint], length_m: f64) -> Option<LoopClosure> {
    let (first, last) = (track.first()?, track.last()?);
    let gap_m =
        ((last.east_m - first.east_m).powi(2) + (last.north_m - first.north_m).powi(2)).sqrt();
    (length_m > 0.0).then_some(LoopClosure {
        gap_m,
        length_m,
        gap_pct: 100.0 * gap_m / length_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(t_s: f64, east_m: f64, north_m: f64) -> TrackPoint {
        TrackPoint {
            t_s,
            east_m,
            north_m,
            length_m: 0.7,
            heading_rad: 0.0,
            position_sigma_m: 1.0,
            gnss_used: false,
        }
    }

    #[test]
    fn errors_are_measured_against_the_reference_path() {
        // The track runs 10 % long on a straight 100 m reference.
        let track: Vec<TrackPoint> = (0..=100)
            .map(|k| point(k as f64, 0.0, 1.1 * k as f64))
            .collect();
        let reference: Vec<(f64, [f64; 2])> = (0..=10)
            .map(|k| (10.0 * k as f64, [0.0, 10.0 * k as f64]))
            .collect();
        let errors = position_errors(&track, &reference, 0.0, 100.0).expect("errors");
        assert_eq!(errors.n_points, 11);
        assert!((errors.max_m - 10.0).abs() < 1e-9);
        assert!((errors.distance_m - 100.0).abs() < 1e-9);
        assert!((errors.max_pct - 10.0).abs() < 1e-9);
        assert!((errors.distance_error_pct - 10.0).abs() < 1e-9);
        assert!(position_errors(&track, &reference, 200.0, 300.0).is_none());
    }

    #[test]
    fn interpolation_and_loop_closure() {
        let track = vec![
            point(0.0, 0.0, 0.0),
            point(2.0, 2.0, 0.0),
            point(4.0, 0.0, 3.0),
        ];
        assert_eq!(position_at(&track, 1.0), Some([1.0, 0.0]));
        assert_eq!(position_at(&track, 5.0), None);
        let closure = loop_closure(&track, 50.0).expect("closure");
        assert!((closure.gap_m - 3.0).abs() < 1e-12 && (closure.gap_pct - 6.0).abs() < 1e-12);
        let headings = heading_error_deg([(0.1, 6.2), (0.0, 0.0)]).expect("stats");
        assert!(headings.mean > 0.0 && headings.mean < 10.0, "{headings:?}");
    }
}
