//! The PDR figure: the trajectory (reference, GNSS, the dead-reckoned track with the
//! outages highlighted, equal axes and a scale bar in metres), the step lengths over
//! time (the model's, the filter's and the references), and the position error over
//! time against the reference positions (else the filter's own σ).

use plotters::coord::Shift;
use plotters::prelude::*;

use super::zoom::{runs_within, PlotFrame, Zoom};
use super::{thinned_indices, PlotError, MAX_POINTS_PER_SERIES};
use crate::pdr::fusion::FixUse;
use crate::pdr::metrics::position_at;
use crate::pdr::PdrAnalysis;

const REFERENCE_COLOR: RGBColor = RGBColor(30, 30, 30);
const GNSS_COLOR: RGBColor = RGBColor(31, 119, 180);
const IGNORED_COLOR: RGBColor = RGBColor(170, 170, 170);
const TRACK_COLOR: RGBColor = RGBColor(214, 39, 40);
const OUTAGE_COLOR: RGBColor = RGBColor(255, 127, 14);
const SIGMA_COLOR: RGBColor = RGBColor(150, 150, 150);
/// How many rings of the position's σ a trajectory shows along its track.
const SIGMA_RINGS: usize = 12;
/// The narrowest trajectory (px) that draws its legend.
const MIN_LEGEND_WIDTH_PX: u32 = 480;

/// The trajectory on the left, step lengths and position error on the right. This is
/// what `compass-pdr pdr --plot` writes.
pub fn draw_pdr_figure<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &PdrAnalysis,
) -> Result<(), PlotError> {
    area.fill(&WHITE)
        .map_err(PlotError::from_backend("figure"))?;
    let (width, _) = area.dim_in_pixel();
    let (left, right) = area.split_horizontally(width * 55 / 100);
    let panels = right.split_evenly((2, 1));
    let [lengths, errors] = panels.as_slice() else {
        return Err(PlotError {
            plot: "figure",
            reason: "the drawing area did not split in two".to_string(),
        });
    };
    draw_trajectory(&left, analysis, Zoom::WHOLE)?;
    draw_step_lengths(lengths, analysis)?;
    draw_position_error(errors, analysis)?;
    area.present().map_err(PlotError::from_backend("figure"))
}

/// A range that holds `values` with a margin, at least `min_span` wide.
fn padded(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return (-min_span / 2.0, min_span / 2.0);
    }
    let span = (hi - lo).max(min_span);
    let centre = 0.5 * (lo + hi);
    (centre - 0.55 * span, centre + 0.55 * span)
}

/// A round length for a scale bar about a fifth of `span_m`.
fn scale_bar_m(span_m: f64) -> f64 {
    let target = span_m / 5.0;
    let power = 10f64.powf(target.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|step| step * power)
        .rfind(|length| *length <= target)
        .unwrap_or(power)
}

/// The trajectory in metres east and north of the origin, on equal axes: the reference,
/// the GNSS fixes used and ignored, the dead-reckoned track with rings of its position's
/// σ and its stretches without GNSS, its start and end, and a scale bar; `zoom` picks
/// the window.
pub fn draw_trajectory<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &PdrAnalysis,
    zoom: Zoom,
) -> Result<PlotFrame, PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("trajectory");
    let track: Vec<(f64, f64)> = analysis
        .track
        .iter()
        .map(|point| (point.east_m, point.north_m))
        .collect();
    let reference: Vec<(f64, f64)> =
        thinned_indices(analysis.reference_en_m.len(), MAX_POINTS_PER_SERIES)
            .filter_map(|idx| analysis.reference_en_m.get(idx))
            .map(|(_, en)| (en[0], en[1]))
            .collect();
    let FixesDrawn {
        mut used,
        mut ignored,
    } = FixesDrawn::of(analysis);
    let all = || track.iter().chain(&reference).chain(&used).chain(&ignored);
    let (x_range, y_range) = map_ranges(area.dim_in_pixel(), all(), zoom);
    let window = Window {
        x_m: x_range.clone(),
        y_m: y_range.clone(),
    };
    used.retain(|point| window.contains(point));
    ignored.retain(|point| window.contains(point));
    let mut chart = super::styled_chart(
        area,
        trajectory_caption(analysis),
        x_range.clone(),
        y_range.clone(),
        "east (m)",
        "north (m)",
    )
    .map_err(&error)?;
    let frame = super::frame_of(
        &chart,
        (x_range.clone(), y_range.clone()),
        ("east (m)", "north (m)"),
        true,
    );
    draw_reference(&mut chart, &reference, &window).map_err(&error)?;
    if !used.is_empty() {
        super::draw_dots(&mut chart, &used, GNSS_COLOR, "GNSS used").map_err(&error)?;
    }
    if !ignored.is_empty() {
        super::draw_dots(
            &mut chart,
            &ignored,
            IGNORED_COLOR,
            "GNSS ignored (outage, gate)",
        )
        .map_err(&error)?;
    }
    draw_uncertainty(&mut chart, analysis, &window).map_err(&error)?;
    draw_track(&mut chart, &track, &window).map_err(&error)?;
    draw_without_gnss(&mut chart, analysis, &window).map_err(&error)?;
    draw_track_ends(&mut chart, &track, &window).map_err(&error)?;
    draw_scale_bar(&mut chart, &x_range, &y_range).map_err(&error)?;
    // On a plot narrower than this the legend would hide much of the track: the
    // caption under the page's picture says what each line is instead.
    if area.dim_in_pixel().0 >= MIN_LEGEND_WIDTH_PX {
        super::draw_legend(&mut chart, SeriesLabelPosition::UpperRight).map_err(&error)?;
    }
    Ok(frame)
}

/// The trajectory's window (metres east and north): plotters would draw what lies
/// outside it on its edges, so only what lies inside is drawn.
struct Window {
    x_m: std::ops::Range<f64>,
    y_m: std::ops::Range<f64>,
}

impl Window {
    /// Whether `point` lies inside the window.
    fn contains(&self, point: &(f64, f64)) -> bool {
        self.x_m.contains(&point.0) && self.y_m.contains(&point.1)
    }

    /// The runs of `line` that lie inside the window.
    fn runs(&self, line: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
        runs_within(line, &self.x_m, &self.y_m)
    }
}

/// The fixes drawn (m east, m north): those the track used, and those it ignored (in an
/// outage, beyond the gate); the others are not drawn.
struct FixesDrawn {
    used: Vec<(f64, f64)>,
    ignored: Vec<(f64, f64)>,
}

impl FixesDrawn {
    /// The fixes of `analysis` to draw, by what became of them.
    fn of(analysis: &PdrAnalysis) -> FixesDrawn {
        let mut used: Vec<(f64, f64)> = Vec::new();
        let mut ignored: Vec<(f64, f64)> = Vec::new();
        for (fix, decision) in &analysis.fixes {
            let point = (fix.en_m[0], fix.en_m[1]);
            match decision {
                FixUse::Used | FixUse::UsedAfterReset => used.push(point),
                FixUse::InOutage | FixUse::Rejected => ignored.push(point),
                // Fixes of hundreds of metres of error would only stretch the axes.
                FixUse::PoorAccuracy
                | FixUse::DownWeighted
                | FixUse::BeforeWalk
                | FixUse::AfterWalk => {}
            }
        }
        FixesDrawn { used, ignored }
    }
}

/// The trajectory's caption: the steps, and the RMS error where there is a reference,
/// else the distance.
fn trajectory_caption(analysis: &PdrAnalysis) -> String {
    match &analysis.report.position_error {
        Some(errors) => format!(
            "Trajectory: {} steps, RMS error {:.1} m ({:.1} %)",
            analysis.report.n_steps, errors.rms_m, errors.rms_pct
        ),
        None => format!(
            "Trajectory: {} steps, {:.0} m",
            analysis.report.n_steps, analysis.report.pdr_distance_m
        ),
    }
}

/// The reference track as a line, and its points as crosses when there are few.
fn draw_reference<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    reference: &[(f64, f64)],
    window: &Window,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    for (run_idx, run) in window.runs(reference).into_iter().enumerate() {
        let series = chart.draw_series(LineSeries::new(run, REFERENCE_COLOR.stroke_width(1)))?;
        if run_idx == 0 {
            series
                .label("reference")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], REFERENCE_COLOR));
        }
    }
    if reference.len() < 200 {
        chart.draw_series(
            reference
                .iter()
                .filter(|point| window.contains(point))
                .map(|&p| Cross::new(p, 4, REFERENCE_COLOR.stroke_width(2))),
        )?;
    }
    Ok(())
}

/// The dead-reckoned track.
fn draw_track<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    track: &[(f64, f64)],
    window: &Window,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    for (run_idx, run) in window.runs(track).into_iter().enumerate() {
        let series = chart.draw_series(LineSeries::new(run, TRACK_COLOR.stroke_width(2)))?;
        if run_idx == 0 {
            series.label("PDR").legend(|(x, y)| {
                PathElement::new([(x, y), (x + 16, y)], TRACK_COLOR.stroke_width(2))
            });
        }
    }
    Ok(())
}

/// The track's uncertainty: a ring of radius 1σ (√(σ_E² + σ_N²), which holds: on the
/// IPIN walks 65 % of the landmark errors lie within it, as a σ that holds gives 63 %)
/// at a dozen points spread along the track, thin and grey, under the track.
fn draw_uncertainty<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    analysis: &PdrAnalysis,
    window: &Window,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (x_px, _) = chart.plotting_area().get_pixel_range();
    let span_px = f64::from((x_px.end - x_px.start).max(1));
    let px_per_m = span_px / (window.x_m.end - window.x_m.start).max(1e-9);
    let track = &analysis.track;
    let stride = track.len().div_ceil(SIGMA_RINGS).max(1);
    let rings: Vec<((f64, f64), i32)> = track
        .iter()
        .skip(stride / 2)
        .step_by(stride)
        .filter(|point| point.position_sigma_m.is_finite())
        .map(|point| {
            (
                (point.east_m, point.north_m),
                (point.position_sigma_m * px_per_m).round(),
            )
        })
        .filter(|(centre, radius_px)| {
            window.contains(centre) && *radius_px >= 3.0 && *radius_px <= span_px
        })
        .map(|(centre, radius_px)| (centre, radius_px as i32))
        .collect();
    if rings.is_empty() {
        return Ok(());
    }
    chart
        .draw_series(rings.into_iter().map(|(centre, radius_px)| {
            Circle::new(centre, radius_px, SIGMA_COLOR.stroke_width(1))
        }))?
        .label("1σ of the position")
        .legend(|(x, y)| Circle::new((x + 8, y), 5, SIGMA_COLOR.stroke_width(1)));
    Ok(())
}

/// The track's stretches without GNSS (outages and gaps), over the track.
fn draw_without_gnss<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    analysis: &PdrAnalysis,
    window: &Window,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let mut labelled = false;
    for (start_s, end_s) in without_gnss(analysis) {
        let segment: Vec<(f64, f64)> = analysis
            .track
            .iter()
            .filter(|point| (start_s..=end_s).contains(&point.t_s))
            .map(|point| (point.east_m, point.north_m))
            .collect();
        for run in window.runs(&segment) {
            if run.len() < 2 {
                continue;
            }
            let series = chart.draw_series(LineSeries::new(run, OUTAGE_COLOR.stroke_width(3)))?;
            if !labelled {
                series.label("PDR without GNSS").legend(|(x, y)| {
                    PathElement::new([(x, y), (x + 16, y)], OUTAGE_COLOR.stroke_width(3))
                });
                labelled = true;
            }
        }
    }
    Ok(())
}

/// The track's start (a filled circle) and end (a ring), where they lie in the window.
fn draw_track_ends<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    track: &[(f64, f64)],
    window: &Window,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    if let (Some(first), Some(last)) = (track.first(), track.last()) {
        chart.draw_series(
            [
                (*first, TRACK_COLOR.filled()),
                (*last, TRACK_COLOR.stroke_width(2)),
            ]
            .into_iter()
            .filter(|(point, _)| window.contains(point))
            .map(|(point, style)| Circle::new(point, 5, style)),
        )?;
    }
    Ok(())
}

/// The trajectory's ranges: every point with a margin, on equal axes (the range short
/// for the plot area's aspect widened), then zoomed alike on both axes, so that the
/// scale stays equal.
fn map_ranges<'a>(
    (width_px, height_px): (u32, u32),
    points: impl Iterator<Item = &'a (f64, f64)> + Clone,
    zoom: Zoom,
) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (x_lo, x_hi) = padded(points.clone().map(|p| p.0), 10.0);
    let (y_lo, y_hi) = padded(points.map(|p| p.1), 10.0);
    let plot_w = f64::from(width_px.saturating_sub(80).max(1));
    let plot_h = f64::from(height_px.saturating_sub(90).max(1));
    let metres_per_px = ((x_hi - x_lo) / plot_w).max((y_hi - y_lo) / plot_h);
    let (x_mid, y_mid) = (0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi));
    (
        zoom.x_of((x_mid - 0.5 * metres_per_px * plot_w)..(x_mid + 0.5 * metres_per_px * plot_w)),
        zoom.y_of((y_mid - 0.5 * metres_per_px * plot_h)..(y_mid + 0.5 * metres_per_px * plot_h)),
    )
}

/// A scale bar of a round length, bottom left.
fn draw_scale_bar<DB: DrawingBackend>(
    chart: &mut super::XyChart<'_, DB>,
    x_range: &std::ops::Range<f64>,
    y_range: &std::ops::Range<f64>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let span_m = x_range.end - x_range.start;
    let bar_m = scale_bar_m(span_m);
    let x0 = x_range.start + 0.05 * span_m;
    let y0 = y_range.start + 0.05 * (y_range.end - y_range.start);
    chart.draw_series([PathElement::new(
        [(x0, y0), (x0 + bar_m, y0)],
        BLACK.stroke_width(3),
    )])?;
    chart.draw_series([Text::new(
        format!("{bar_m} m"),
        (x0, y0 + 0.02 * (y_range.end - y_range.start)),
        ("sans-serif", 13),
    )])?;
    Ok(())
}

pub fn draw_step_lengths<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &PdrAnalysis,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("step lengths");
    let model: Vec<(f64, f64)> = analysis
        .steps
        .iter()
        .zip(&analysis.step_lengths_m)
        .map(|(step, length)| (step.t_end_s, *length))
        .collect();
    let references: Vec<(f64, f64)> = analysis
        .steps
        .iter()
        .zip(&analysis.step_references_m)
        .filter_map(|(step, reference)| reference.map(|length| (step.t_end_s, length)))
        .collect();
    let filtered: Vec<(f64, f64)> = analysis
        .track
        .iter()
        .skip(1)
        .map(|p| (p.t_s, p.length_m))
        .collect();
    let (t_lo, t_hi) = padded(model.iter().map(|p| p.0), 1.0);
    let (l_lo, l_hi) = padded(model.iter().chain(&references).map(|p| p.1), 0.3);
    let mut chart = super::styled_chart(
        area,
        format!(
            "Step length: {}",
            analysis.report.step_model.model.kind().label()
        ),
        t_lo..t_hi,
        l_lo.max(0.0)..l_hi,
        "time (s)",
        "step length (m)",
    )
    .map_err(&error)?;
    if !references.is_empty() {
        super::draw_dots(&mut chart, &references, IGNORED_COLOR, "reference").map_err(&error)?;
    }
    super::draw_dots(&mut chart, &model, GNSS_COLOR, "model").map_err(&error)?;
    chart
        .draw_series(LineSeries::new(filtered, TRACK_COLOR.stroke_width(1)))
        .map_err(&error)?
        .label("EKF l")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], TRACK_COLOR));
    super::draw_legend(&mut chart, SeriesLabelPosition::UpperRight).map_err(&error)
}

pub fn draw_position_error<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    analysis: &PdrAnalysis,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("position error");
    let against_reference: Vec<(f64, f64)> =
        thinned_indices(analysis.reference_en_m.len(), MAX_POINTS_PER_SERIES)
            .filter_map(|idx| {
                let (t_s, truth) = analysis.reference_en_m.get(idx)?;
                let estimate = position_at(&analysis.track, *t_s)?;
                Some((
                    *t_s,
                    ((estimate[0] - truth[0]).powi(2) + (estimate[1] - truth[1]).powi(2)).sqrt(),
                ))
            })
            .collect();
    let sigma: Vec<(f64, f64)> = analysis
        .track
        .iter()
        .map(|p| (p.t_s, p.position_sigma_m))
        .collect();
    let (t_lo, t_hi) = padded(sigma.iter().map(|p| p.0), 1.0);
    let top = against_reference
        .iter()
        .chain(&sigma)
        .map(|p| p.1)
        .filter(|v| v.is_finite())
        .fold(1.0, f64::max)
        * 1.1;
    let caption = if against_reference.is_empty() {
        "Position uncertainty (no reference positions)"
    } else {
        "Position error against the reference"
    };
    let mut chart = super::styled_chart(area, caption, t_lo..t_hi, 0.0..top, "time (s)", "metres")
        .map_err(&error)?;
    for (start_s, end_s) in without_gnss(analysis) {
        chart
            .draw_series([Rectangle::new(
                [(start_s.max(t_lo), 0.0), (end_s.min(t_hi), top)],
                OUTAGE_COLOR.mix(0.15).filled(),
            )])
            .map_err(&error)?;
    }
    if !against_reference.is_empty() {
        chart
            .draw_series(LineSeries::new(
                against_reference,
                TRACK_COLOR.stroke_width(2),
            ))
            .map_err(&error)?
            .label("error")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], TRACK_COLOR.stroke_width(2)));
    }
    chart
        .draw_series(LineSeries::new(sigma, GNSS_COLOR.stroke_width(1)))
        .map_err(&error)?
        .label("filter σ")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], GNSS_COLOR));
    super::draw_legend(&mut chart, SeriesLabelPosition::UpperLeft).map_err(&error)
}

/// The spans the dead reckoning bridged alone: the user's outages (GNSS ignored) and the
/// gaps without any fix in the log.
fn without_gnss(analysis: &PdrAnalysis) -> Vec<(f64, f64)> {
    let report = &analysis.report;
    report
        .outages
        .iter()
        .map(|outage| (outage.start_s, outage.end_s))
        .chain(report.gnss_gaps.iter().map(|gap| (gap.start_s, gap.end_s)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_bars_are_round() {
        assert_eq!(scale_bar_m(100.0), 20.0);
        assert_eq!(scale_bar_m(40.0), 5.0);
        assert_eq!(scale_bar_m(700.0), 100.0);
        assert_eq!(padded([].into_iter(), 10.0), (-5.0, 5.0));
    }
}
