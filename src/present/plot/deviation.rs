//! The heading-model figure: the deviation curve (deviation against heading, with the
//! fitted Eq. 12 curve and the residuals, for the base whose model fits best), the
//! residual histogram (the PDR paper's Fig. 7), the heading error over time of the raw
//! heading and the best method, and the online model's coefficients converging.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::circle_fit::{CORRECTED_COLOR, RAW_COLOR};
use super::{thinned_indices, PlotError, MAX_POINTS_PER_SERIES};
use crate::analysis::calibration::row_key::RowKey;
use crate::analysis::headings::HeadingAnalysis;
use crate::base::angle::heading_difference_rad;

const RESIDUAL_COLOR: RGBColor = RGBColor(120, 120, 120);

/// The four panels, two by two. This is what `compass-pdr heading --plot` writes.
pub fn draw_deviation_figure<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &HeadingAnalysis,
) -> Result<(), PlotError> {
    area.fill(&WHITE)
        .map_err(PlotError::from_backend("figure"))?;
    let panels = area.split_evenly((2, 2));
    let [curve, histogram, over_time, online] = panels.as_slice() else {
        return Err(PlotError {
            plot: "figure",
            reason: "the drawing area did not split in four".to_string(),
        });
    };
    draw_deviation_curve(curve, analysis)?;
    draw_residual_histogram(histogram, analysis)?;
    draw_heading_errors(over_time, analysis)?;
    draw_online_convergence(online, analysis)?;
    area.present().map_err(PlotError::from_backend("figure"))
}

/// The featured base heading's series (raw when no model was fitted), its key and label.
fn base_series(analysis: &HeadingAnalysis) -> (&[f64], String) {
    let featured = analysis.report.featured_fourier();
    let key = featured.map_or(RowKey::RAW, |report| report.base_key);
    let label = featured.map_or("uncalibrated".to_string(), |report| {
        report.base_label.clone()
    });
    let series = analysis
        .headings_deg
        .iter()
        .find(|(series_key, _)| *series_key == key)
        .map_or(&[][..], |(_, headings)| headings.as_slice());
    (series, label)
}

/// Deviation (reference − raw) against raw heading, the fitted curve, the residuals.
pub fn draw_deviation_curve<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &HeadingAnalysis,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("deviation curve");
    let (raw_deg, base_label) = base_series(analysis);
    let model = analysis
        .report
        .featured_fourier()
        .map(|report| report.fit.model);
    let points: Vec<(f64, f64)> = thinned_indices(raw_deg.len(), MAX_POINTS_PER_SERIES)
        .filter_map(|idx| {
            let raw = *raw_deg.get(idx)?;
            let reference = (*analysis.reference_deg.get(idx)?)?;
            Some((
                raw.rem_euclid(360.0),
                heading_difference_rad(reference.to_radians(), raw.to_radians()).to_degrees(),
            ))
        })
        .collect();
    let curve: Vec<(f64, f64)> = model.map_or_else(Vec::new, |model| {
        (0..=360)
            .map(|deg| {
                let raw_deg = f64::from(deg);
                (
                    raw_deg,
                    crate::base::angle::wrap_to_pi(model.deviation_rad(raw_deg.to_radians()))
                        .to_degrees(),
                )
            })
            .collect()
    });
    let residuals: Vec<(f64, f64)> = model.map_or_else(Vec::new, |model| {
        points
            .iter()
            .map(|&(raw_deg, deviation_deg)| {
                (
                    raw_deg,
                    crate::base::angle::wrap_to_pi(
                        (deviation_deg.to_radians()) - model.deviation_rad(raw_deg.to_radians()),
                    )
                    .to_degrees(),
                )
            })
            .collect()
    });
    let limit_deg = points
        .iter()
        .chain(&curve)
        .map(|&(_, deviation_deg)| deviation_deg.abs())
        .fold(10.0, f64::max)
        .min(180.0)
        * 1.1;
    let mut chart = super::styled_chart(
        area,
        format!("Deviation curve (Eq. 12) of {base_label}"),
        0.0..360.0,
        -limit_deg..limit_deg,
        "heading before the model (°)",
        "reference − heading (°)",
    )
    .map_err(&error)?;
    super::draw_dots(&mut chart, &points, RAW_COLOR, "deviation").map_err(&error)?;
    if !residuals.is_empty() {
        super::draw_dots(&mut chart, &residuals, RESIDUAL_COLOR, "residual").map_err(&error)?;
        chart
            .draw_series(LineSeries::new(curve, CORRECTED_COLOR.stroke_width(2)))
            .map_err(&error)?
            .label("fitted A…E")
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], CORRECTED_COLOR.stroke_width(2))
            });
    }
    super::draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&error)?;
    Ok(())
}

/// The residual histogram of the featured Fourier model (train part).
pub fn draw_residual_histogram<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &HeadingAnalysis,
) -> Result<(), PlotError> {
    let error =
        PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("residual histogram");
    let fit = analysis.report.featured_fourier().map(|report| &report.fit);
    let (bars, max_count, caption) = match fit {
        Some(fit) => {
            let histogram = &fit.histogram;
            let bars: Vec<(f64, f64, usize)> = histogram
                .counts
                .iter()
                .enumerate()
                .map(|(idx, &count)| {
                    let from_deg = histogram.min_deg + idx as f64 * histogram.bin_width_deg;
                    (from_deg, from_deg + histogram.bin_width_deg, count)
                })
                .collect();
            let max_count = bars.iter().map(|bar| bar.2).max().unwrap_or(1).max(1);
            (
                bars,
                max_count,
                format!("Residuals: {:.0} % within ±5°", fit.within_5_deg_pct),
            )
        }
        None => (Vec::new(), 1, "Residuals (no model fitted)".to_string()),
    };
    let mut chart = super::styled_chart(
        area,
        caption,
        -20.0..20.0,
        0.0..(max_count as f64 * 1.1),
        "residual (°)",
        "pairs (1 s means)",
    )
    .map_err(&error)?;
    chart
        .draw_series(bars.iter().map(|&(from_deg, to_deg, count)| {
            Rectangle::new(
                [(from_deg, 0.0), (to_deg, count as f64)],
                CORRECTED_COLOR.mix(0.7).filled(),
            )
        }))
        .map_err(&error)?;
    Ok(())
}

/// Heading error over time of the raw heading (rings) and of the row the comparison
/// chose (dots): the heading the answer's headline names, as the answer's picture.
/// Returns the chosen row's label, as the legend gives it.
pub fn draw_heading_errors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &HeadingAnalysis,
) -> Result<String, PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("heading error");
    let t_s = &analysis.t_s;
    let series = |key: RowKey| -> Vec<(f64, f64)> {
        let Some((_, headings_deg)) = analysis
            .headings_deg
            .iter()
            .find(|(series_key, _)| *series_key == key)
        else {
            return Vec::new();
        };
        thinned_indices(t_s.len(), MAX_POINTS_PER_SERIES)
            .filter_map(|idx| {
                let heading = *headings_deg.get(idx)?;
                let reference = (*analysis.reference_deg.get(idx)?)?;
                Some((
                    *t_s.get(idx)?,
                    heading_difference_rad(heading.to_radians(), reference.to_radians())
                        .to_degrees(),
                ))
            })
            .collect()
    };
    let best_key = analysis.report.choice.key;
    let best_label = analysis
        .report
        .row(best_key)
        .map_or_else(|| best_key.text(), |row| row.label.clone());
    let (raw, best) = (series(RowKey::RAW), series(best_key));
    let limit_deg = raw
        .iter()
        .chain(&best)
        .map(|&(_, e)| e.abs())
        .fold(5.0, f64::max)
        .min(180.0)
        * 1.1;
    let (first_s, last_s) = (
        t_s.first().copied().unwrap_or(0.0),
        t_s.last().copied().unwrap_or(1.0),
    );
    let mut chart = super::styled_chart(
        area,
        "Heading error against the reference heading",
        first_s..last_s.max(first_s + 1e-3),
        -limit_deg..limit_deg,
        "time (s)",
        "error (°)",
    )
    .map_err(&error)?;
    if let Some(until_s) = analysis
        .report
        .train_until_s
        .filter(|until_s| *until_s < last_s)
    {
        chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(until_s, -limit_deg), (until_s, limit_deg)],
                BLACK.mix(0.4).stroke_width(1),
            )))
            .map_err(&error)?
            .label("train | check")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.mix(0.4)));
    }
    super::draw_rings(&mut chart, &raw, RAW_COLOR, "before calibration").map_err(&error)?;
    super::draw_dots(&mut chart, &best, CORRECTED_COLOR, best_label.as_str()).map_err(&error)?;
    super::draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&error)?;
    Ok(best_label)
}

/// The online model's coefficients A to E over time, as recursive least squares refits
/// them while the reference is good: they settle as the headings fill the circle.
pub fn draw_online_convergence<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &HeadingAnalysis,
) -> Result<(), PlotError> {
    let error =
        PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("online convergence");
    let (snapshots, caption) = match &analysis.report.online {
        Some(online) => (
            online.snapshots.as_slice(),
            format!(
                "Online A…E on {} (RLS, memory {:.0} s)",
                online.base_label, online.memory_s
            ),
        ),
        None => (
            &[][..],
            "Online A…E (no reference to learn from)".to_string(),
        ),
    };
    let coefficient = |snapshot: &crate::deviation::rls::RlsSnapshot, idx: usize| {
        let model = snapshot.model;
        [
            model.a_deg,
            model.b_deg,
            model.c_deg,
            model.d_deg,
            model.e_deg,
        ]
        .get(idx)
        .copied()
        .unwrap_or(0.0)
    };
    let limit_deg = snapshots
        .iter()
        .flat_map(|snapshot| (0..5).map(move |idx| coefficient(snapshot, idx).abs()))
        .fold(5.0, f64::max)
        .min(180.0)
        * 1.1;
    let (first_s, last_s) = (
        snapshots.first().map_or(0.0, |snapshot| snapshot.t_s),
        snapshots.last().map_or(1.0, |snapshot| snapshot.t_s),
    );
    let mut chart = super::styled_chart(
        area,
        caption,
        first_s..last_s.max(first_s + 1e-3),
        -limit_deg..limit_deg,
        "time (s)",
        "coefficient (°)",
    )
    .map_err(&error)?;
    let colors = [
        RGBColor(30, 100, 200),
        RGBColor(230, 120, 30),
        RGBColor(40, 150, 70),
        RGBColor(170, 50, 160),
        RGBColor(120, 120, 120),
    ];
    for (idx, (name, color)) in ["A", "B", "C", "D", "E"].iter().zip(colors).enumerate() {
        chart
            .draw_series(LineSeries::new(
                snapshots
                    .iter()
                    .map(|snapshot| (snapshot.t_s, coefficient(snapshot, idx))),
                color.stroke_width(2),
            ))
            .map_err(&error)?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
            });
    }
    super::draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&error)?;
    Ok(())
}
