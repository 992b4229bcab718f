//! The live panel's 3D view (what MotionCal shows): the field directions after the
//! latest fit, on the fitted sphere, turned as the user drags it. MotionCal's 100
//! equal-area regions of direction with no sample yet are shaded red on the side facing
//! the viewer, and the board's axes are drawn from the centre, so that "turn the +x
//! axis down" can be read off the picture; a ring marks the latest sample, where the
//! board points now. Before a fit, the raw samples are shown about their mean.
//!
//! An orthographic projection: the sphere is turned about the board's vertical axis
//! (yaw), then tipped toward the viewer (pitch); what lies behind is drawn first and
//! paler.

use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::live_panel::{FIT_COLOR, RAW_COLOR};
use super::{thinned_indices, PlotError};
use crate::fit::coverage::{direction_at, region_bounds, N_REGIONS};
use crate::io::serial_lines::sensor_to_body;
use crate::live::LiveQuality;

/// Points drawn at most, thinned evenly over the session.
const MAX_POINTS: usize = 2500;
const MISSING_COLOR: RGBColor = RGBColor(200, 60, 40);
const GRID_COLOR: RGBColor = RGBColor(170, 178, 190);
/// The latest sample's ring.
const LATEST_COLOR: RGBColor = RGBColor(0, 150, 70);

/// How the sphere is turned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereView {
    /// About the board's vertical (z) axis; 0 puts the board's +x axis toward the viewer.
    pub yaw_rad: f64,
    /// Tipped toward the viewer: positive shows the top (the board's −z side).
    pub pitch_rad: f64,
}

impl Default for SphereView {
    /// Seen from the front right and a little above.
    fn default() -> SphereView {
        SphereView {
            yaw_rad: 0.6,
            pitch_rad: 0.35,
        }
    }
}

impl SphereView {
    /// Turned by a drag of `(dx, dy)` pixels on a view `size_px` across: a drag across
    /// the whole view turns it by about half a turn; the pitch stops at the poles.
    pub fn dragged(self, dx_px: f64, dy_px: f64, size_px: f64) -> SphereView {
        let rad_per_px = std::f64::consts::PI / size_px.max(1.0);
        SphereView {
            yaw_rad: (self.yaw_rad - dx_px * rad_per_px).rem_euclid(std::f64::consts::TAU),
            pitch_rad: (self.pitch_rad + dy_px * rad_per_px).clamp(-1.5, 1.5),
        }
    }

    /// A direction in body axes (x forward, y right, z down) as (right, up) on the
    /// screen, in units of the sphere's radius, and its depth (positive toward the
    /// viewer).
    pub fn project(&self, body: &Vector3<f64>) -> (f64, f64, f64) {
        let (sin_yaw, cos_yaw) = self.yaw_rad.sin_cos();
        let forward = cos_yaw * body.x - sin_yaw * body.y;
        let right = sin_yaw * body.x + cos_yaw * body.y;
        let up = -body.z;
        let (sin_pitch, cos_pitch) = self.pitch_rad.sin_cos();
        (
            right,
            up * cos_pitch - forward * sin_pitch,
            up * sin_pitch + forward * cos_pitch,
        )
    }
}

/// The body direction at azimuth `azimuth_deg` and the sine of the elevation.
fn direction(azimuth_deg: f64, sin_elevation: f64) -> Vector3<f64> {
    direction_at(azimuth_deg.to_radians(), sin_elevation)
}

/// Where each sample goes on the view: the corrected field over the fitted field's
/// strength (on the unit sphere when the fit holds), or, before a fit, the raw samples
/// about their mean, scaled by the farthest.
fn placement<'a>(
    samples_ut: &[Vector3<f64>],
    quality: Option<&'a LiveQuality>,
) -> Box<dyn Fn(Vector3<f64>) -> Vector3<f64> + 'a> {
    match quality {
        Some(quality) => {
            let calibration = &quality.calibration;
            let field_ut = calibration.field_ut.max(f64::MIN_POSITIVE);
            Box::new(move |raw_ut| sensor_to_body(calibration.apply(raw_ut)) / field_ut)
        }
        None => {
            let n = samples_ut.len().max(1) as f64;
            let mean = samples_ut.iter().sum::<Vector3<f64>>() / n;
            let scale = samples_ut
                .iter()
                .map(|sample| (sample - mean).norm())
                .fold(0.0, f64::max)
                .max(f64::MIN_POSITIVE);
            Box::new(move |raw_ut| sensor_to_body((raw_ut - mean) / scale))
        }
    }
}

/// A line on the screen, as pixels.
type Path = Vec<(i32, i32)>;

/// Where the sphere is drawn: the view, the centre and the radius in pixels.
struct Screen {
    view: SphereView,
    centre_px: (f64, f64),
    radius_px: f64,
}

impl Screen {
    /// (right, up) in units of the radius, as pixels.
    fn px(&self, (right, up): (f64, f64)) -> (i32, i32) {
        (
            (self.centre_px.0 + right * self.radius_px).round() as i32,
            (self.centre_px.1 - up * self.radius_px).round() as i32,
        )
    }

    /// A body direction's pixel and depth (positive toward the viewer).
    fn point(&self, body: &Vector3<f64>) -> ((i32, i32), f64) {
        let (right, up, depth) = self.view.project(body);
        (self.px((right, up)), depth)
    }

    /// The pieces of a curve on the sphere that lie on the near side, as pixels.
    fn near_side(&self, curve: impl Iterator<Item = Vector3<f64>>) -> Vec<Path> {
        let mut pieces = vec![Vec::new()];
        for point in curve {
            let (px, depth) = self.point(&point);
            if depth >= 0.0 {
                if let Some(piece) = pieces.last_mut() {
                    piece.push(px);
                }
            } else if pieces.last().is_some_and(|piece| !piece.is_empty()) {
                pieces.push(Vec::new());
            }
        }
        pieces.retain(|piece| piece.len() > 1);
        pieces
    }

    /// The equator and the meridians every 45°, on the near side.
    fn grid(&self) -> Vec<Path> {
        let mut grid = self.near_side((0..=72).map(|idx| direction(f64::from(idx) * 5.0, 0.0)));
        for meridian_deg in (0..180).step_by(45) {
            grid.extend(self.near_side((0..=72).map(|idx| {
                let elevation = f64::from(idx) * 5.0 - 180.0;
                let (sin_el, cos_el) = elevation.to_radians().sin_cos();
                let (sin_az, cos_az) = f64::from(meridian_deg).to_radians().sin_cos();
                Vector3::new(cos_el * cos_az, cos_el * sin_az, -sin_el)
            })));
        }
        grid
    }

    /// A coverage region's outline on the near side, and the shape to shade there
    /// (its near part, cut at the sphere's outline; `None` when under three points).
    fn region(&self, region_idx: usize) -> (Vec<Path>, Option<Path>) {
        let bounds = region_bounds(region_idx);
        let (az0, az1) = (bounds.azimuth_start_deg, bounds.azimuth_end_deg);
        let (low, high) = (bounds.sin_elevation_low, bounds.sin_elevation_high);
        let steps = 8;
        let along =
            |from: f64, to: f64, step: usize| from + (to - from) * step as f64 / steps as f64;
        let outline: Vec<Vector3<f64>> = (0..steps)
            .map(|step| direction(along(az0, az1, step), low))
            .chain((0..steps).map(|step| direction(az1, along(low, high, step))))
            .chain((0..steps).map(|step| direction(along(az1, az0, step), high)))
            .chain((0..=steps).map(|step| direction(az0, along(high, low, step))))
            .collect();
        let near: Path = outline
            .iter()
            .map(|point| self.point(point))
            .filter(|(_, depth)| *depth >= 0.0)
            .map(|(px, _)| px)
            .collect();
        (
            self.near_side(outline.into_iter()),
            (near.len() >= 3).then_some(near),
        )
    }
}

/// The view: the samples on the fitted sphere, the regions with no sample yet, the
/// board's axes, and a caption with the coverage.
pub fn draw_sphere_view<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    samples_ut: &[Vector3<f64>],
    quality: Option<&LiveQuality>,
    view: SphereView,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("sphere");
    area.fill(&WHITE).map_err(&error)?;
    let (width_px, height_px) = area.dim_in_pixel();
    let (width, height) = (f64::from(width_px), f64::from(height_px));
    let caption_px = 30.0;
    let screen = Screen {
        view,
        centre_px: (width / 2.0, caption_px + (height - caption_px) / 2.0),
        radius_px: ((height - caption_px).min(width) / 2.0 / 1.3).max(10.0),
    };
    let place = placement(samples_ut, quality);
    let points: Vec<((i32, i32), f64)> = thinned_indices(samples_ut.len(), MAX_POINTS)
        .filter_map(|idx| samples_ut.get(idx))
        .map(|&sample_ut| screen.point(&place(sample_ut)))
        .collect();
    let latest = samples_ut
        .last()
        .map(|&sample_ut| screen.point(&place(sample_ut)));
    let point_color = if quality.is_some() {
        FIT_COLOR
    } else {
        RAW_COLOR
    };
    // Back to front: the far samples, the sphere, the regions missing, the near samples.
    for (px, _) in points.iter().filter(|(_, depth)| *depth < 0.0) {
        area.draw(&Circle::new(*px, 2, point_color.mix(0.25).filled()))
            .map_err(&error)?;
    }
    area.draw(&Circle::new(
        screen.px((0.0, 0.0)),
        screen.radius_px.round() as i32,
        GRID_COLOR.stroke_width(2),
    ))
    .map_err(&error)?;
    for piece in screen.grid() {
        area.draw(&PathElement::new(piece, GRID_COLOR.mix(0.6)))
            .map_err(&error)?;
    }
    let counts = quality.map_or(&[][..], |quality| {
        quality.coverage.counts_per_region.as_slice()
    });
    let missing = (0..N_REGIONS).filter(|&idx| counts.get(idx).copied().unwrap_or(1) == 0);
    for region_idx in missing {
        let (outline, shade) = screen.region(region_idx);
        if let Some(shade) = shade {
            area.draw(&Polygon::new(shade, MISSING_COLOR.mix(0.18).filled()))
                .map_err(&error)?;
        }
        for piece in outline {
            area.draw(&PathElement::new(piece, MISSING_COLOR.mix(0.8)))
                .map_err(&error)?;
        }
    }
    for (px, _) in points.iter().filter(|(_, depth)| *depth >= 0.0) {
        area.draw(&Circle::new(*px, 2, point_color.mix(0.85).filled()))
            .map_err(&error)?;
    }
    draw_axes(area, &screen).map_err(&error)?;
    // Where the board points now: a ring, so that a person turning it sees which way
    // the shaded regions are.
    if let Some((px, depth)) = latest {
        let ring = if depth >= 0.0 {
            LATEST_COLOR.stroke_width(3)
        } else {
            LATEST_COLOR.mix(0.6).stroke_width(2)
        };
        area.draw(&Circle::new(px, 8, ring)).map_err(&error)?;
    }
    let caption = match quality {
        Some(quality) => format!(
            "Field directions after the fit: {} of {} regions covered (ring: now)",
            quality.coverage.n_covered, quality.coverage.n_regions
        ),
        None if samples_ut.is_empty() => "Field directions: no samples yet".to_string(),
        None => format!("Raw samples, {}: no fit yet", samples_ut.len()),
    };
    area.draw(&Text::new(
        caption,
        ((width / 2.0).round() as i32, 6),
        TextStyle::from(("sans-serif", 18).into_font())
            .pos(Pos::new(HPos::Center, VPos::Top))
            .color(&BLACK),
    ))
    .map_err(&error)?;
    Ok(())
}

/// The board's axes, from the centre to beyond the sphere, fainter when they point
/// away from the viewer.
fn draw_axes<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    screen: &Screen,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let label_style = TextStyle::from(("sans-serif", 18).into_font())
        .pos(Pos::new(HPos::Center, VPos::Center))
        .color(&BLACK);
    for (name, axis) in [
        ("+x", Vector3::x()),
        ("+y", Vector3::y()),
        ("+z", Vector3::z()),
    ] {
        let (right, up, depth) = screen.view.project(&axis);
        let style = if depth >= 0.0 {
            BLACK.mix(0.8).stroke_width(2)
        } else {
            BLACK.mix(0.35).stroke_width(1)
        };
        area.draw(&PathElement::new(
            vec![screen.px((0.0, 0.0)), screen.px((right * 1.15, up * 1.15))],
            style,
        ))?;
        area.draw(&Text::new(
            name,
            screen.px((right * 1.24, up * 1.24)),
            label_style.clone(),
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The board's +x axis faces the viewer at yaw 0 and no pitch; +y is to the right
    /// and −z up; a positive pitch brings the top toward the viewer.
    #[test]
    fn the_projection_keeps_the_board_axes_where_the_view_says() {
        let level = SphereView {
            yaw_rad: 0.0,
            pitch_rad: 0.0,
        };
        let close = |got: (f64, f64, f64), want: (f64, f64, f64)| {
            assert!(
                (got.0 - want.0).abs() < 1e-12
                    && (got.1 - want.1).abs() < 1e-12
                    && (got.2 - want.2).abs() < 1e-12,
                "{got:?} != {want:?}"
            );
        };
        close(level.project(&Vector3::x()), (0.0, 0.0, 1.0));
        close(level.project(&Vector3::y()), (1.0, 0.0, 0.0));
        close(level.project(&-Vector3::z()), (0.0, 1.0, 0.0));
        let from_above = SphereView {
            yaw_rad: 0.0,
            pitch_rad: std::f64::consts::FRAC_PI_2,
        };
        close(from_above.project(&-Vector3::z()), (0.0, 0.0, 1.0));
        // A quarter turn of yaw (the view goes round toward the board's left) faces −y.
        let turned = SphereView {
            yaw_rad: std::f64::consts::FRAC_PI_2,
            pitch_rad: 0.0,
        };
        close(turned.project(&-Vector3::y()), (0.0, 0.0, 1.0));
    }

    /// A projection is a rotation: lengths are kept whatever the view.
    #[test]
    fn the_projection_keeps_lengths() {
        for idx in 0..50 {
            let view = SphereView {
                yaw_rad: f64::from(idx) * 0.37,
                pitch_rad: f64::from(idx) * 0.11 - 1.4,
            };
            let point = Vector3::new(0.3, -0.5, 0.81);
            let (right, up, depth) = view.project(&point);
            assert!(
                ((right * right + up * up + depth * depth).sqrt() - point.norm()).abs() < 1e-12
            );
        }
    }

    #[test]
    fn a_drag_turns_the_view_and_stops_at_the_poles() {
        let view = SphereView::default();
        let turned = view.dragged(100.0, 0.0, 400.0);
        let expected =
            (view.yaw_rad - std::f64::consts::PI / 4.0).rem_euclid(std::f64::consts::TAU);
        assert!((turned.yaw_rad - expected).abs() < 1e-12);
        assert_eq!(view.dragged(0.0, 1e6, 400.0).pitch_rad, 1.5);
        assert_eq!(view.dragged(0.0, -1e6, 400.0).pitch_rad, -1.5);
    }

    fn fitted_session(share: f64) -> (crate::live::LiveSession, LiveQuality) {
        crate::live::turned_session(800, share)
    }

    fn svg_of(samples_ut: &[Vector3<f64>], quality: Option<&LiveQuality>) -> String {
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (600, 600)).into_drawing_area();
            draw_sphere_view(&area, samples_ut, quality, SphereView::default()).expect("draws");
        }
        svg
    }

    /// The regions the board never pointed through are shaded red; a full sweep leaves
    /// none; before a fit, the raw samples are drawn and said to be so.
    #[test]
    fn the_regions_with_no_sample_are_shaded_and_a_full_sweep_has_none() {
        let shaded = |svg: &str| svg.matches("fill=\"#C83C28\"").count();
        let (session, quality) = fitted_session(0.6);
        assert!(
            quality.coverage.n_covered < 100,
            "{:?}",
            quality.coverage.n_covered
        );
        let svg = svg_of(session.kept_samples_ut(), Some(&quality));
        assert!(
            svg.contains(&format!(
                "{} of 100 regions covered",
                quality.coverage.n_covered
            )),
            "{}",
            &svg[..svg.len().min(400)]
        );
        assert!(
            shaded(&svg) > 0,
            "no region shaded: {}",
            svg.lines()
                .filter(|l| l.contains("polygon") || l.contains("C83C28"))
                .take(3)
                .collect::<Vec<_>>()
                .join("\n")
        );
        let (session, quality) = fitted_session(1.0);
        assert_eq!(quality.coverage.n_covered, 100);
        assert_eq!(
            shaded(&svg_of(session.kept_samples_ut(), Some(&quality))),
            0
        );
        let raw = svg_of(session.kept_samples_ut(), None);
        let n_kept = session.kept_samples_ut().len();
        assert!(raw.contains(&format!("Raw samples, {n_kept}: no fit yet")));
        assert!(svg_of(&[], None).contains("no samples yet"));
    }
}
