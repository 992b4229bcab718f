//! The live panel's plots (the live calibration): the raw samples seen along each pair
//! of sensor axes (MotionCal's view), the coverage of the sphere of directions, and a
//! heading dial.
//!
//! All three take what [`crate::live::LiveSession`] holds and draw nothing else; the page
//! redraws them a few times a second while samples arrive.

use std::f64::consts::TAU;

use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::circle_fit::equal_scale_ranges;
use super::{thinned_indices, PlotError};
use crate::fit::coverage::{region_bounds, SphereCoverage};
use crate::live::LiveQuality;

pub const RAW_COLOR: RGBColor = RGBColor(230, 120, 30);
pub const FIT_COLOR: RGBColor = RGBColor(30, 100, 200);
const EMPTY_COLOR: RGBColor = RGBColor(235, 225, 215);
const MISSING_EDGE_COLOR: RGBColor = RGBColor(200, 60, 40);

/// Points per panel at most, thinned evenly over the session.
const MAX_POINTS_PER_PANEL: usize = 3000;
const N_CURVE_POINTS: usize = 180;

/// The sensor-axis pairs MotionCal shows, as (first axis, second axis, name).
const PAIRS: [(usize, usize, &str); 3] = [(0, 1, "X-Y"), (1, 2, "Y-Z"), (2, 0, "Z-X")];

/// Three panels side by side: the raw samples (sensor axes, µT) projected on X-Y, Y-Z
/// and Z-X, with the fitted hard iron (a cross) and a circle of the fitted field around
/// it: a good sweep fills each panel's ring.
pub fn draw_live_clouds<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    samples_ut: &[Vector3<f64>],
    quality: Option<&LiveQuality>,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("live clouds");
    area.fill(&WHITE).map_err(&error)?;
    let panels = area.split_evenly((1, 3));
    for ((first, second, name), panel) in PAIRS.iter().zip(&panels) {
        let mut min = (f64::INFINITY, f64::INFINITY);
        let mut max = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut extend = |a: f64, b: f64| {
            min = (min.0.min(a), min.1.min(b));
            max = (max.0.max(a), max.1.max(b));
        };
        for sample in samples_ut {
            extend(sample[*first], sample[*second]);
        }
        if let Some(quality) = quality {
            let centre = quality.calibration.hard_iron_ut;
            let radius = quality.calibration.field_ut;
            extend(centre[*first] - radius, centre[*second] - radius);
            extend(centre[*first] + radius, centre[*second] + radius);
        }
        if !min.0.is_finite() {
            min = (-60.0, -60.0);
            max = (60.0, 60.0);
        }
        let (x_range, y_range) = equal_scale_ranges(panel, (min.0, max.0), (min.1, max.1));
        let axis = |idx: usize| ["X", "Y", "Z"].get(idx).copied().unwrap_or("?");
        let mut chart = super::styled_chart(
            panel,
            format!("{name} (µT), {} samples", samples_ut.len()),
            x_range,
            y_range,
            &format!("{} (µT)", axis(*first)),
            &format!("{} (µT)", axis(*second)),
        )
        .map_err(&error)?;
        chart
            .draw_series(
                thinned_indices(samples_ut.len(), MAX_POINTS_PER_PANEL)
                    .filter_map(|idx| samples_ut.get(idx))
                    .map(|sample| {
                        Circle::new(
                            (sample[*first], sample[*second]),
                            1,
                            RAW_COLOR.mix(0.6).filled(),
                        )
                    }),
            )
            .map_err(&error)?;
        if let Some(quality) = quality {
            let centre = quality.calibration.hard_iron_ut;
            let (cx, cy) = (centre[*first], centre[*second]);
            let radius = quality.calibration.field_ut;
            let circle = (0..=N_CURVE_POINTS).map(|idx| {
                let angle = TAU * idx as f64 / N_CURVE_POINTS as f64;
                (cx + radius * angle.cos(), cy + radius * angle.sin())
            });
            chart
                .draw_series(LineSeries::new(circle, FIT_COLOR.stroke_width(2)))
                .map_err(&error)?;
            chart
                .draw_series(std::iter::once(Cross::new(
                    (cx, cy),
                    6,
                    FIT_COLOR.stroke_width(2),
                )))
                .map_err(&error)?;
        }
    }
    Ok(())
}

/// The sphere of field directions (corrected, body axes) as MotionCal's 100 equal-area
/// regions on an equal-area map: filled where samples fell (darker with more), pale with
/// a red edge where none did yet.
pub fn draw_coverage_map<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    coverage: Option<&SphereCoverage>,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("coverage");
    area.fill(&WHITE).map_err(&error)?;
    let caption = match coverage {
        Some(coverage) => format!(
            "Coverage: {} of {} regions, gaps {:.0} %",
            coverage.n_covered, coverage.n_regions, coverage.gap_pct
        ),
        None => "Coverage: no fit yet".to_string(),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(-180.0..180.0, -1.0..1.0)
        .map_err(&error)?;
    chart
        .configure_mesh()
        .x_desc("azimuth of the field, atan2(y, x) (°)")
        .y_desc("elevation (°)")
        .x_labels(9)
        .y_labels(7)
        .y_label_formatter(&|sin: &f64| format!("{:.0}", sin.clamp(-1.0, 1.0).asin().to_degrees()))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(&error)?;
    let counts = coverage.map_or(&[][..], |coverage| coverage.counts_per_region.as_slice());
    let cells = (0..crate::fit::coverage::N_REGIONS).map(|region_idx| {
        let bounds = region_bounds(region_idx);
        let count = counts.get(region_idx).copied().unwrap_or(0);
        (bounds, count)
    });
    for (bounds, count) in cells {
        let corners = [
            (bounds.azimuth_start_deg, bounds.sin_elevation_low),
            (bounds.azimuth_end_deg, bounds.sin_elevation_high),
        ];
        let fill = match count {
            0 => EMPTY_COLOR.filled(),
            1..=2 => FIT_COLOR.mix(0.35).filled(),
            3..=9 => FIT_COLOR.mix(0.6).filled(),
            _ => FIT_COLOR.mix(0.9).filled(),
        };
        chart
            .draw_series(std::iter::once(Rectangle::new(corners, fill)))
            .map_err(&error)?;
        let edge = if count == 0 {
            MISSING_EDGE_COLOR.stroke_width(1)
        } else {
            WHITE.stroke_width(1)
        };
        chart
            .draw_series(std::iter::once(Rectangle::new(corners, edge)))
            .map_err(&error)?;
    }
    Ok(())
}

/// A compass dial with the heading of the latest sample through the latest fit
/// (magnetic, tilt-compensated when the stream has an accelerometer).
pub fn draw_heading_dial<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    heading_rad: Option<f64>,
    filter_heading_rad: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("heading dial");
    area.fill(&WHITE).map_err(&error)?;
    let (width_px, height_px) = area.dim_in_pixel();
    let (width, height) = (width_px as f64, height_px as f64);
    let radius = (width.min(height - 40.0) / 2.0 - 24.0).max(10.0);
    let centre = (width / 2.0, 20.0 + (height - 20.0) / 2.0);
    let at = |angle_rad: f64, distance: f64| {
        (
            (centre.0 + distance * angle_rad.sin()).round() as i32,
            (centre.1 - distance * angle_rad.cos()).round() as i32,
        )
    };
    let centre_px = (centre.0.round() as i32, centre.1.round() as i32);
    area.draw(&Circle::new(
        centre_px,
        radius.round() as i32,
        BLACK.mix(0.6).stroke_width(2),
    ))
    .map_err(&error)?;
    for tick_deg in (0..360).step_by(30) {
        let angle = f64::from(tick_deg).to_radians();
        area.draw(&PathElement::new(
            vec![at(angle, radius * 0.88), at(angle, radius)],
            BLACK.mix(0.6).stroke_width(2),
        ))
        .map_err(&error)?;
    }
    let label_style = TextStyle::from(("sans-serif", 16).into_font())
        .pos(Pos::new(HPos::Center, VPos::Center))
        .color(&BLACK);
    for (name, angle_deg) in [("N", 0.0f64), ("E", 90.0), ("S", 180.0), ("W", 270.0)] {
        area.draw(&Text::new(
            name,
            at(angle_deg.to_radians(), radius * 0.72),
            label_style.clone(),
        ))
        .map_err(&error)?;
    }
    let caption_style = TextStyle::from(("sans-serif", 16).into_font())
        .pos(Pos::new(HPos::Center, VPos::Top))
        .color(&BLACK);
    let filter = filter_heading_rad.filter(|(rad, sigma)| rad.is_finite() && sigma.is_finite());
    match heading_rad.filter(|rad| rad.is_finite()) {
        Some(heading_rad) => {
            let heading_rad = heading_rad.rem_euclid(TAU);
            area.draw(&PathElement::new(
                vec![
                    at(heading_rad + std::f64::consts::PI, radius * 0.25),
                    at(heading_rad, radius * 0.85),
                ],
                MISSING_EDGE_COLOR.stroke_width(4),
            ))
            .map_err(&error)?;
            if let Some((filter_rad, _)) = filter {
                // The attitude filter's needle: thinner, blue, over the compass's (the
                // two agree where the field is clean).
                area.draw(&PathElement::new(
                    vec![at(filter_rad, radius * 0.2), at(filter_rad, radius * 0.95)],
                    FIT_COLOR.stroke_width(3),
                ))
                .map_err(&error)?;
            }
            let caption = match filter {
                Some((filter_rad, sigma_rad)) => format!(
                    "Compass {:.0}°, gyro filter {:.0}° ± {:.0}° (magnetic)",
                    heading_rad.to_degrees(),
                    filter_rad.rem_euclid(TAU).to_degrees(),
                    sigma_rad.to_degrees().max(1.0)
                ),
                None => format!("Heading {:.0}° (magnetic)", heading_rad.to_degrees()),
            };
            area.draw(&Text::new(
                caption,
                ((width / 2.0).round() as i32, 4),
                caption_style,
            ))
            .map_err(&error)?;
        }
        None => {
            area.draw(&Text::new(
                "Heading: after the first fit",
                ((width / 2.0).round() as i32, 4),
                caption_style,
            ))
            .map_err(&error)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_live_plots_draw_a_session_to_svg() {
        let (session, quality) = crate::live::turned_session(600, 1.0);
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (1200, 400)).into_drawing_area();
            draw_live_clouds(&area, session.kept_samples_ut(), Some(&quality)).expect("draws");
        }
        assert!(
            svg.contains("X-Y (µT), 599 samples"),
            "{}",
            &svg[..svg.len().min(400)]
        );
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (600, 400)).into_drawing_area();
            draw_coverage_map(&area, Some(&quality.coverage)).expect("draws");
        }
        assert!(
            svg.contains("Coverage: 100 of 100 regions"),
            "{}",
            &svg[..svg.len().min(400)]
        );
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (400, 400)).into_drawing_area();
            draw_heading_dial(
                &area,
                session.latest_heading_rad(),
                session.filter_heading_rad(),
            )
            .expect("draws");
        }
        assert!(svg.contains("(magnetic)"));
        // Nothing yet: the plots say so rather than fail.
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (400, 400)).into_drawing_area();
            draw_live_clouds(&area, &[], None).expect("draws");
            draw_coverage_map(&area, None).expect("draws");
            draw_heading_dial(&area, None, None).expect("draws");
        }
        assert!(svg.contains("no fit yet"));
    }
}
