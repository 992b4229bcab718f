//! Plots, generic over plotters' [`DrawingBackend`]: the page draws them on a canvas,
//! the CLI and the tests draw the very same plots to SVG.
//!
//! Each plot takes a drawing area and the analysis it shows, and draws nothing else:
//! sizes, backends and files belong to the caller.

pub mod answer;
pub mod circle_fit;
pub mod compass_errors;
pub mod deviation;
pub mod field_magnitude;
pub mod heading_error;
pub mod live_panel;
pub mod pdr;
pub mod sphere_view;
pub mod timeline;
pub mod zoom;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use thiserror::Error;

use crate::analysis::calibration::CalibrationAnalysis;
use zoom::{PlotFrame, Zoom};

pub use circle_fit::draw_circle_fit;
pub use deviation::draw_deviation_figure;
pub use field_magnitude::draw_field_magnitude;
pub use heading_error::draw_heading_error;
pub use pdr::draw_pdr_figure;

/// At most this many points of one series are drawn; longer series are thinned evenly.
pub const MAX_POINTS_PER_SERIES: usize = 4000;

/// A plot that could not be drawn (the backend failed).
#[derive(Debug, Error)]
#[error("could not draw the {plot} plot: {reason}")]
pub struct PlotError {
    pub plot: &'static str,
    pub reason: String,
}

impl PlotError {
    fn from_backend<E: std::fmt::Debug>(plot: &'static str) -> impl Fn(E) -> PlotError {
        move |error| PlotError {
            plot,
            reason: format!("{error:?}"),
        }
    }
}

/// The calibration figure: the circle fit, the heading error and |B| side by side. This
/// is what `compass-pdr calibrate --plot` writes.
pub fn draw_calibration_figure<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &CalibrationAnalysis,
) -> Result<(), PlotError> {
    area.fill(&WHITE)
        .map_err(PlotError::from_backend("figure"))?;
    let panels = area.split_evenly((1, 3));
    let [circle, heading, field] = panels.as_slice() else {
        return Err(PlotError {
            plot: "figure",
            reason: "the drawing area did not split in three".to_string(),
        });
    };
    draw_circle_fit(circle, analysis)?;
    draw_heading_error(heading, analysis, Zoom::WHOLE)?;
    draw_field_magnitude_of(field, analysis, Zoom::WHOLE)?;
    area.present().map_err(PlotError::from_backend("figure"))
}

/// |B| raw and corrected against the magnetic model's value.
pub fn draw_field_magnitude_of<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &CalibrationAnalysis,
    zoom: Zoom,
) -> Result<PlotFrame, PlotError> {
    let expected_ut = analysis
        .report
        .expected_field
        .as_ref()
        .map(|expected| expected.total_ut);
    draw_field_magnitude(
        area,
        &analysis.t_s,
        &analysis.field_raw_ut,
        &analysis.field_corrected_ut,
        expected_ut,
        zoom,
    )
}

/// The legend every plot draws, in one style, at `position`.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .draw()
}

/// A chart with two `f64` axes.
pub(crate) type XyChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart in the plots' common style: a 16 px sans-serif caption, 12 px margins, room
/// for the axis labels, both axes described and the light grid lines hidden.
pub(crate) fn styled_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: impl AsRef<str>,
    x_range: std::ops::Range<f64>,
    y_range: std::ops::Range<f64>,
    x_desc: &str,
    y_desc: &str,
) -> Result<XyChart<'a, DB>, DrawingAreaErrorKind<DB::ErrorType>> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption.as_ref(), ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(x_range, y_range)?;
    // Plotters' ten tick labels on a plot of 560 × 300 px or more; fewer on a narrower
    // one (a phone's), so that its labels do not run into each other.
    let (width_px, height_px) = area.dim_in_pixel();
    chart
        .configure_mesh()
        .x_labels((width_px / 56).clamp(4, 10) as usize)
        .y_labels((height_px / 30).clamp(4, 10) as usize)
        .x_desc(x_desc)
        .y_desc(y_desc)
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    Ok(chart)
}

/// Where `chart`'s plotting area lies and what it shows, for zooming and reading
/// values on the page.
pub(crate) fn frame_of<DB: DrawingBackend>(
    chart: &XyChart<'_, DB>,
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
    (x_desc, y_desc): (&'static str, &'static str),
    both_axes: bool,
) -> PlotFrame {
    let (x_px, y_px) = chart.plotting_area().get_pixel_range();
    PlotFrame {
        x_px,
        y_px,
        x,
        y,
        x_desc,
        y_desc,
        both_axes,
    }
}

/// Points as small dots, with a legend entry.
pub(crate) fn draw_dots<DB: DrawingBackend>(
    chart: &mut XyChart<'_, DB>,
    points: &[(f64, f64)],
    color: RGBColor,
    label: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    draw_markers(chart, points, (1, color.filled()), label)
}

/// Points as small rings, with a legend entry: a series that must be told from dots
/// without its colour (the heading error before calibration, beside the dots after).
pub(crate) fn draw_rings<DB: DrawingBackend>(
    chart: &mut XyChart<'_, DB>,
    points: &[(f64, f64)],
    color: RGBColor,
    label: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    draw_markers(chart, points, (2, color.stroke_width(1)), label)
}

/// Points as circles of `radius_px` in `style`, with a legend entry of the same style.
fn draw_markers<DB: DrawingBackend>(
    chart: &mut XyChart<'_, DB>,
    points: &[(f64, f64)],
    (radius_px, style): (i32, ShapeStyle),
    label: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .draw_series(
            points
                .iter()
                .map(|&point| Circle::new(point, radius_px, style)),
        )?
        .label(label)
        .legend(move |(x, y)| Circle::new((x + 8, y), 3, style));
    Ok(())
}

/// The indices of at most `max_points` evenly spaced elements of `0..len`.
pub(crate) fn thinned_indices(len: usize, max_points: usize) -> impl Iterator<Item = usize> {
    let stride = len.div_ceil(max_points.max(1)).max(1);
    (0..len).step_by(stride)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::calibration::{calibrate, CalibrationOptions};
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, WalkConfig};

    #[test]
    fn the_figure_draws_to_svg() {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(5, 60.0)));
        let report = import("sim.csv", text.as_bytes()).expect("readable");
        let analysis = calibrate(report, &CalibrationOptions::default()).expect("analysable");
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (1800, 500)).into_drawing_area();
            draw_calibration_figure(&root, &analysis).expect("drawable");
        }
        assert!(svg.starts_with("<svg"));
        assert!(svg.contains("Level-plane field"), "circle plot title");
        assert!(svg.contains("Heading error"), "heading plot title");
        assert!(
            svg.matches("<circle").count() > 1000,
            "the points are drawn"
        );
    }

    /// Zoomed, the time plots show the window asked for, read the value under the
    /// pointer in it, and draw only the samples inside it.
    #[test]
    fn the_time_plots_draw_the_window_of_a_zoom() {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(5, 60.0)));
        let report = import("sim.csv", text.as_bytes()).expect("readable");
        let analysis = calibrate(report, &CalibrationOptions::default()).expect("analysable");
        let frames = |zoom: Zoom| {
            let mut svg = String::new();
            let frames = {
                let root = SVGBackend::with_string(&mut svg, (560, 440)).into_drawing_area();
                let heading = draw_heading_error(&root, &analysis, zoom).expect("drawable");
                let field = draw_field_magnitude_of(&root, &analysis, zoom).expect("drawable");
                (heading, field)
            };
            (frames, svg.matches("<circle").count())
        };
        let ((whole, whole_field), _) = frames(Zoom::WHOLE);
        let zoom = Zoom::WHOLE.zoomed((0.5, 0.5), 10.0, false);
        let ((zoomed, zoomed_field), n_dots) = frames(zoom);
        for (whole, zoomed) in [(&whole, &zoomed), (&whole_field, &zoomed_field)] {
            let span = |frame: &PlotFrame| frame.x.end - frame.x.start;
            assert!(
                (span(zoomed) - span(whole) / 10.0).abs() < 1e-9,
                "{zoomed:?}"
            );
            assert!(zoomed.x.start > whole.x.start && zoomed.x.end < whole.x.end);
            let middle = (
                f64::from(zoomed.x_px.start + zoomed.x_px.end) / 2.0,
                f64::from(zoomed.y_px.start + zoomed.y_px.end) / 2.0,
            );
            let (time_s, _) = zoomed.value_at(middle).expect("inside");
            assert!((time_s - (zoomed.x.start + zoomed.x.end) / 2.0).abs() < span(zoomed) / 50.0);
        }
        // A tenth of the walk's samples, all drawn (60 s at 50 Hz: 300 per series).
        assert!((300..=700).contains(&n_dots), "{n_dots} dots");
    }

    #[test]
    fn thinning_keeps_short_series_whole() {
        assert_eq!(
            thinned_indices(5, 10).collect::<Vec<_>>(),
            vec![0, 1, 2, 3, 4]
        );
        assert_eq!(
            thinned_indices(10, 5).collect::<Vec<_>>(),
            vec![0, 2, 4, 6, 8]
        );
        assert_eq!(thinned_indices(0, 5).count(), 0);
    }
}
