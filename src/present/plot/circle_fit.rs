//! The circle-fit plot: raw levelled field points, the ellipse a level-plane method
//! fitted to them, and the corrected points on their circle. Axes are drawn to equal
//! scale, so a circle looks like one.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{thinned_indices, PlotError, MAX_POINTS_PER_SERIES};
use crate::analysis::calibration::CalibrationAnalysis;

pub const RAW_COLOR: RGBColor = RGBColor(230, 120, 30);
pub const CORRECTED_COLOR: RGBColor = RGBColor(30, 100, 200);

const N_CURVE_POINTS: usize = 240;

pub fn draw_circle_fit<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &CalibrationAnalysis,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("circle-fit");
    let all_points = analysis
        .level_raw_ut
        .iter()
        .chain(&analysis.level_corrected_ut);
    let (mut min_x, mut max_x, mut min_y, mut max_y) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for point in all_points {
        min_x = min_x.min(point.x);
        max_x = max_x.max(point.x);
        min_y = min_y.min(point.y);
        max_y = max_y.max(point.y);
    }
    let (x_range, y_range) = equal_scale_ranges(area, (min_x, max_x), (min_y, max_y));

    let mut chart = super::styled_chart(
        area,
        "Level-plane field (µT): raw, fitted ellipse, corrected",
        x_range,
        y_range,
        "Xh (µT)",
        "Yh (µT)",
    )
    .map_err(&error)?;

    let raw = &analysis.level_raw_ut;
    chart
        .draw_series(
            thinned_indices(raw.len(), MAX_POINTS_PER_SERIES)
                .map(|idx| Circle::new((raw[idx].x, raw[idx].y), 1, RAW_COLOR.mix(0.5).filled())),
        )
        .map_err(&error)?
        .label("raw")
        .legend(|(x, y)| Circle::new((x + 8, y), 3, RAW_COLOR.filled()));

    // The fitted ellipse is the corrected circle mapped back: centre + M·(R cos t, R sin t).
    if let Some((center_ut, circle_to_ellipse, radius_ut)) = analysis.fitted_ellipse {
        let ellipse = (0..=N_CURVE_POINTS).map(|idx| {
            let angle_rad = std::f64::consts::TAU * idx as f64 / N_CURVE_POINTS as f64;
            let point = center_ut
                + circle_to_ellipse
                    * nalgebra::Vector2::new(
                        radius_ut * angle_rad.cos(),
                        radius_ut * angle_rad.sin(),
                    );
            (point.x, point.y)
        });
        chart
            .draw_series(LineSeries::new(ellipse, RAW_COLOR.stroke_width(2)))
            .map_err(&error)?
            .label("fitted ellipse")
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], RAW_COLOR.stroke_width(2))
            });
    }

    let corrected = &analysis.level_corrected_ut;
    chart
        .draw_series(
            thinned_indices(corrected.len(), MAX_POINTS_PER_SERIES).map(|idx| {
                Circle::new(
                    (corrected[idx].x, corrected[idx].y),
                    1,
                    CORRECTED_COLOR.mix(0.5).filled(),
                )
            }),
        )
        .map_err(&error)?
        .label("corrected")
        .legend(|(x, y)| Circle::new((x + 8, y), 3, CORRECTED_COLOR.filled()));

    let radius_ut = analysis.fitted_ellipse.map_or_else(
        || {
            let corrected = &analysis.level_corrected_ut;
            corrected.iter().map(nalgebra::Matrix::norm).sum::<f64>()
                / corrected.len().max(1) as f64
        },
        |(_, _, radius_ut)| radius_ut,
    );
    let circle = (0..=N_CURVE_POINTS).map(|idx| {
        let angle_rad = std::f64::consts::TAU * idx as f64 / N_CURVE_POINTS as f64;
        (radius_ut * angle_rad.cos(), radius_ut * angle_rad.sin())
    });
    chart
        .draw_series(LineSeries::new(circle, CORRECTED_COLOR.stroke_width(2)))
        .map_err(&error)?
        .label("circle")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 16, y)], CORRECTED_COLOR.stroke_width(2))
        });

    super::draw_legend(&mut chart, SeriesLabelPosition::UpperRight).map_err(&error)?;
    Ok(())
}

/// Widens one of the two ranges so that a unit on x is as long as a unit on y in the
/// plotting area (the area less caption, margins and label areas as configured above).
pub(super) fn equal_scale_ranges<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (min_x, max_x): (f64, f64),
    (min_y, max_y): (f64, f64),
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (width_px, height_px) = area.dim_in_pixel();
    let plot_width_px = (width_px as f64 - 2.0 * 12.0 - 48.0).max(10.0);
    let plot_height_px = (height_px as f64 - 2.0 * 12.0 - 36.0 - 24.0).max(10.0);
    let pad = 1.08;
    let (center_x, center_y) = ((min_x + max_x) / 2.0, (min_y + max_y) / 2.0);
    let half_x = ((max_x - min_x) / 2.0 * pad).max(1.0);
    let half_y = ((max_y - min_y) / 2.0 * pad).max(1.0);
    let ut_per_px = (half_x / (plot_width_px / 2.0)).max(half_y / (plot_height_px / 2.0));
    let (half_x, half_y) = (
        ut_per_px * plot_width_px / 2.0,
        ut_per_px * plot_height_px / 2.0,
    );
    (
        center_x - half_x..center_x + half_x,
        center_y - half_y..center_y + half_y,
    )
}
