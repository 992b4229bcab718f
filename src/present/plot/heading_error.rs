//! Heading error over time, before calibration and after the best method, against the
//! reference heading. Without a reference, the two headings themselves are drawn. Zoomed
//! along time, the window's samples are drawn (thinned only within it) and the error
//! axis fits them.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::circle_fit::{CORRECTED_COLOR, RAW_COLOR};
use super::zoom::{indices_within, PlotFrame, Zoom};
use super::{thinned_indices, PlotError, MAX_POINTS_PER_SERIES};
use crate::analysis::calibration::CalibrationAnalysis;
use crate::base::angle::heading_difference_rad;

pub fn draw_heading_error<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &CalibrationAnalysis,
    zoom: Zoom,
) -> Result<PlotFrame, PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("heading");
    let best = analysis
        .report
        .best()
        .or_else(|| analysis.headings_deg.first().map(|(method, _)| *method));
    let best_headings_deg: &[f64] = analysis
        .headings_deg
        .iter()
        .find(|(method, _)| Some(*method) == best)
        .map_or(&[], |(_, headings_deg)| headings_deg.as_slice());
    let best_label = format!(
        "after {}",
        best.map_or("calibration", |method| method.label())
    );
    let t_s = &analysis.t_s;
    let (t_first_s, t_last_s) = (
        t_s.first().copied().unwrap_or(0.0),
        t_s.last().copied().unwrap_or(1.0),
    );
    let time_range = zoom.x_of(t_first_s..t_last_s.max(t_first_s + 1e-3));
    let shown = indices_within(t_s, &time_range);
    let has_reference = analysis.ref_heading_deg.iter().any(Option::is_some);

    // Each series as (t, value in degrees), thinned for drawing.
    let series = |headings_deg: &[f64]| -> Vec<(f64, f64)> {
        thinned_indices(shown.len(), MAX_POINTS_PER_SERIES)
            .map(|idx| shown.start + idx)
            .filter(|&idx| {
                t_s.get(idx)
                    .is_some_and(|t| (time_range.start..=time_range.end).contains(t))
            })
            .filter_map(|idx| {
                let heading_deg = *headings_deg.get(idx)?;
                if has_reference {
                    let reference_deg = (*analysis.ref_heading_deg.get(idx)?)?;
                    Some((
                        t_s[idx],
                        heading_difference_rad(
                            heading_deg.to_radians(),
                            reference_deg.to_radians(),
                        )
                        .to_degrees(),
                    ))
                } else {
                    Some((t_s[idx], heading_deg))
                }
            })
            .collect()
    };
    let before = series(&analysis.raw_heading_deg);
    let after = series(best_headings_deg);

    let (caption, y_desc, y_range) = if has_reference {
        let largest_deg = before
            .iter()
            .chain(&after)
            .map(|&(_, error_deg)| error_deg.abs())
            .fold(5.0, f64::max);
        let limit_deg = (largest_deg * 1.1).min(180.0);
        (
            "Heading error against the reference heading",
            "error (°)",
            -limit_deg..limit_deg,
        )
    } else {
        (
            "Heading (no reference in the log)",
            "heading (°)",
            0.0..360.0,
        )
    };

    let mut chart = super::styled_chart(
        area,
        caption,
        time_range.clone(),
        y_range.clone(),
        "time (s)",
        y_desc,
    )
    .map_err(&error)?;
    let frame = super::frame_of(&chart, (time_range, y_range), ("time (s)", y_desc), false);

    super::draw_rings(&mut chart, &before, RAW_COLOR, "before calibration").map_err(&error)?;
    super::draw_dots(&mut chart, &after, CORRECTED_COLOR, best_label.as_str()).map_err(&error)?;
    super::draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&error)?;
    Ok(frame)
}
