//! Field magnitude |B| over time, raw and corrected, against the field the World
//! Magnetic Model expects there ([`crate::earth::wmm`]).
//!
//! A good calibration turns the raw magnitude, which swings with orientation when hard
//! and soft iron are present, into a flat line; the WMM value says where that line
//! should lie. Indoors, steel in the building moves it by several µT, so a corrected
//! line that is flat but off the WMM value points at the environment, not the fit.
//! Without a position and date there is no WMM value, and the caption says so.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::circle_fit::{CORRECTED_COLOR, RAW_COLOR};
use super::zoom::{indices_within, PlotFrame, Zoom};
use super::{thinned_indices, PlotError, MAX_POINTS_PER_SERIES};

const EXPECTED_COLOR: RGBColor = RGBColor(40, 150, 70);

/// Draws |B| over time: `raw_ut` and `corrected_ut` are magnitudes at times `t_s`
/// (lengths may differ; the shorter one sets how many samples are drawn, and samples
/// that are not finite are left out). `expected_ut` is the WMM total intensity, drawn
/// as a horizontal line, or `None` when it is not known.
pub fn draw_field_magnitude<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    t_s: &[f64],
    raw_ut: &[f64],
    corrected_ut: &[f64],
    expected_ut: Option<f64>,
    zoom: Zoom,
) -> Result<PlotFrame, PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("field-magnitude");
    let expected_ut = expected_ut.filter(|value| value.is_finite());

    // Each series as (t, |B|): the window's samples (all of them unzoomed), thinned
    // within it, without non-finite samples. The window is the zoom's part of the
    // whole log, so that the whole plot and a zoomed one share one time axis.
    let finite_t = || t_s.iter().copied().filter(|t| t.is_finite());
    let whole = match (finite_t().reduce(f64::min), finite_t().reduce(f64::max)) {
        (Some(first_s), Some(last_s)) => first_s..last_s.max(first_s + 1e-3),
        _ => 0.0..1.0,
    };
    let time_range = zoom.x_of(whole);
    let shown = indices_within(t_s, &time_range);
    let series = |magnitudes_ut: &[f64]| -> Vec<(f64, f64)> {
        let n_samples = shown
            .len()
            .min(magnitudes_ut.len().saturating_sub(shown.start));
        thinned_indices(n_samples, MAX_POINTS_PER_SERIES)
            .filter_map(|idx| {
                let idx = shown.start + idx;
                let point = (*t_s.get(idx)?, *magnitudes_ut.get(idx)?);
                let inside = (time_range.start..=time_range.end).contains(&point.0);
                (inside && point.1.is_finite()).then_some(point)
            })
            .collect()
    };
    let raw = series(raw_ut);
    let corrected = series(corrected_ut);

    let (mut low_ut, mut high_ut) = (f64::INFINITY, f64::NEG_INFINITY);
    for &(_, magnitude_ut) in raw.iter().chain(&corrected) {
        low_ut = low_ut.min(magnitude_ut);
        high_ut = high_ut.max(magnitude_ut);
    }
    if let Some(value) = expected_ut {
        low_ut = low_ut.min(value);
        high_ut = high_ut.max(value);
    }
    if !(low_ut.is_finite() && high_ut.is_finite()) {
        (low_ut, high_ut) = (0.0, 100.0);
    }
    // A margin of a tenth of the span, and at least 1 µT, so a flat line is visible.
    let margin_ut = ((high_ut - low_ut) * 0.1).max(1.0);
    let magnitude_range = (low_ut - margin_ut).max(0.0)..high_ut + margin_ut;

    let caption = match expected_ut {
        Some(value) => format!("Field magnitude |B| against WMM {value:.1} µT"),
        None => "Field magnitude |B| (no WMM value: needs a position and a date)".to_owned(),
    };
    let mut chart = super::styled_chart(
        area,
        caption,
        time_range.clone(),
        magnitude_range.clone(),
        "time (s)",
        "|B| (µT)",
    )
    .map_err(&error)?;
    let frame = super::frame_of(
        &chart,
        (time_range.clone(), magnitude_range),
        ("time (s)", "|B| (µT)"),
        false,
    );

    chart
        .draw_series(LineSeries::new(raw, RAW_COLOR.stroke_width(1)))
        .map_err(&error)?
        .label("raw |B|")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RAW_COLOR.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(corrected, CORRECTED_COLOR.stroke_width(1)))
        .map_err(&error)?
        .label("corrected |B|")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 16, y)], CORRECTED_COLOR.stroke_width(2))
        });
    if let Some(value) = expected_ut {
        chart
            .draw_series(DashedLineSeries::new(
                [(time_range.start, value), (time_range.end, value)],
                8,
                5,
                EXPECTED_COLOR.stroke_width(2),
            ))
            .map_err(&error)?
            .label(format!("WMM {value:.1} µT"))
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], EXPECTED_COLOR.stroke_width(2))
            });
    }
    super::draw_legend(&mut chart, SeriesLabelPosition::UpperRight).map_err(&error)?;
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A turn in a 48 µT field with 20 µT of hard iron: raw |B| swings, corrected is flat.
    fn turn() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let t_s: Vec<f64> = (0..500).map(|idx| idx as f64 * 0.02).collect();
        let raw_ut = t_s
            .iter()
            .map(|&time_s| {
                let angle_rad = time_s * 0.6;
                let (x_ut, y_ut) = (34.0 * angle_rad.cos() + 20.0, 34.0 * angle_rad.sin());
                (x_ut * x_ut + y_ut * y_ut + 34.0 * 34.0).sqrt()
            })
            .collect();
        let corrected_ut = t_s
            .iter()
            .map(|&time_s| 48.1 + 0.2 * time_s.sin())
            .collect();
        (t_s, raw_ut, corrected_ut)
    }

    fn draw(t_s: &[f64], raw_ut: &[f64], corrected_ut: &[f64], expected_ut: Option<f64>) -> String {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (800, 400)).into_drawing_area();
            root.fill(&WHITE).expect("fillable");
            draw_field_magnitude(&root, t_s, raw_ut, corrected_ut, expected_ut, Zoom::WHOLE)
                .expect("drawable");
            root.present().expect("presentable");
        }
        svg
    }

    #[test]
    fn the_plot_draws_both_series_and_the_wmm_line() {
        let (t_s, raw_ut, corrected_ut) = turn();
        let svg = draw(&t_s, &raw_ut, &corrected_ut, Some(48.76));
        assert!(svg.starts_with("<svg"));
        assert!(svg.contains("Field magnitude |B| against WMM 48.8 µT"));
        assert!(svg.contains("raw |B|") && svg.contains("corrected |B|"));
        assert!(svg.contains("WMM 48.8 µT"), "the line's label");
        // Raw and corrected are one polyline each (plus the legend's); the dashed WMM
        // line is drawn as short segments.
        assert!(svg.matches("<polyline").count() >= 4, "{svg}");
        assert!(svg.contains("stroke=\"#289646\""), "the WMM line's colour");
    }

    #[test]
    fn without_a_wmm_value_the_caption_says_why() {
        let (t_s, raw_ut, corrected_ut) = turn();
        let svg = draw(&t_s, &raw_ut, &corrected_ut, None);
        assert!(svg.contains("no WMM value: needs a position and a date"));
        assert!(!svg.contains("#289646"), "no WMM line");
        assert!(svg.contains("corrected |B|"));
    }

    #[test]
    fn empty_uneven_and_non_finite_input_still_draws() {
        let svg = draw(&[], &[], &[], Some(f64::NAN));
        assert!(svg.contains("no WMM value"));
        let svg = draw(
            &[0.0, 1.0, 2.0],
            &[50.0, f64::NAN],
            &[48.0, 48.0, 48.0, 48.0],
            None,
        );
        assert!(svg.contains("Field magnitude"));
        let svg = draw(&[5.0], &[50.0], &[48.0], Some(49.0));
        assert!(svg.contains("WMM 49.0 µT"));
    }
}
