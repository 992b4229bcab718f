//! Zoom and pan on a plot, and the value under the pointer.
//!
//! A [`Zoom`] is the window shown, as fractions of the whole plot's range on each axis
//! (the whole plot is `0..1`), so that it means the same whatever the data: the page
//! keeps one per zoomable canvas and the plot applies it to the ranges it computes. A
//! plot drawn with a zoom returns its [`PlotFrame`]: where its plotting area lies in
//! pixels and which ranges it shows, which is all the page needs to turn a pointer's
//! position into a value, a zoom about the pointer or a pan.

use std::ops::Range;

/// The window shown, as fractions of the whole range on each axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Zoom {
    x: (f64, f64),
    y: (f64, f64),
}

/// The narrowest window, as a fraction of the whole range (a 10,000-fold zoom).
const MIN_WIDTH: f64 = 1e-4;

impl Default for Zoom {
    fn default() -> Zoom {
        Zoom::WHOLE
    }
}

impl Zoom {
    /// The whole plot.
    pub const WHOLE: Zoom = Zoom {
        x: (0.0, 1.0),
        y: (0.0, 1.0),
    };

    pub fn is_whole(&self) -> bool {
        *self == Zoom::WHOLE
    }

    /// The part of `whole` the window shows along x.
    pub fn x_of(&self, whole: Range<f64>) -> Range<f64> {
        window_of(self.x, whole)
    }

    /// The part of `whole` the window shows along y.
    pub fn y_of(&self, whole: Range<f64>) -> Range<f64> {
        window_of(self.y, whole)
    }

    /// Zoomed in by `factor` (> 1 in, < 1 out) about the point at `at`, given as
    /// fractions (0..1, y upward) of the plotting area as now shown; along x only, or
    /// along both axes (a map, whose scale stays equal). Never beyond the whole plot.
    pub fn zoomed(self, at: (f64, f64), factor: f64, both_axes: bool) -> Zoom {
        let factor = if factor.is_finite() && factor > 0.0 {
            factor
        } else {
            1.0
        };
        self.each_axis(at, both_axes, |window, fraction| {
            let centre = window.0 + fraction.clamp(0.0, 1.0) * (window.1 - window.0);
            let width = ((window.1 - window.0) / factor).clamp(MIN_WIDTH, 1.0);
            let start = centre - (centre - window.0) / (window.1 - window.0) * width;
            clamped(start, width)
        })
    }

    /// Moved by `by`, fractions of the plotting area as now shown (a drag to the right
    /// moves the window left: the plot follows the pointer). Never beyond the whole
    /// plot.
    pub fn panned(self, by: (f64, f64), both_axes: bool) -> Zoom {
        self.each_axis(by, both_axes, |window, fraction| {
            let width = window.1 - window.0;
            clamped(window.0 - fraction * width, width)
        })
    }

    /// `change` applied to the x window with `amounts.0`, and to the y window with
    /// `amounts.1` when the plot zooms along both axes.
    fn each_axis(
        self,
        amounts: (f64, f64),
        both_axes: bool,
        change: impl Fn((f64, f64), f64) -> (f64, f64),
    ) -> Zoom {
        Zoom {
            x: change(self.x, amounts.0),
            y: if both_axes {
                change(self.y, amounts.1)
            } else {
                self.y
            },
        }
    }
}

/// A window of `width` starting at `start`, moved inside `0..1`.
fn clamped(start: f64, width: f64) -> (f64, f64) {
    let start = if start.is_finite() { start } else { 0.0 };
    let start = start.clamp(0.0, 1.0 - width);
    (start, start + width)
}

fn window_of(window: (f64, f64), whole: Range<f64>) -> Range<f64> {
    let span = whole.end - whole.start;
    (whole.start + window.0 * span)..(whole.start + window.1 * span)
}

/// Where a plot's plotting area lies on its canvas and what it shows.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotFrame {
    /// The plotting area's left and right edges, in the canvas's CSS pixels.
    pub x_px: Range<i32>,
    /// Its top and bottom edges.
    pub y_px: Range<i32>,
    /// The ranges shown.
    pub x: Range<f64>,
    pub y: Range<f64>,
    /// The axes' descriptions, units included ("time (s)").
    pub x_desc: &'static str,
    pub y_desc: &'static str,
    /// Whether the plot zooms along both axes (a map) or along x only.
    pub both_axes: bool,
}

impl PlotFrame {
    /// The position `(x, y)` in CSS pixels as fractions of the plotting area (y upward),
    /// `None` outside it.
    pub fn fraction_at(&self, (x_px, y_px): (f64, f64)) -> Option<(f64, f64)> {
        let width = f64::from(self.x_px.end - self.x_px.start);
        let height = f64::from(self.y_px.end - self.y_px.start);
        let fx = (x_px - f64::from(self.x_px.start)) / width;
        let fy = (f64::from(self.y_px.end) - y_px) / height;
        ((0.0..=1.0).contains(&fx) && (0.0..=1.0).contains(&fy)).then_some((fx, fy))
    }

    /// A move of `(dx, dy)` CSS pixels as fractions of the plotting area (y upward).
    pub fn fraction_of_move(&self, (dx_px, dy_px): (f64, f64)) -> (f64, f64) {
        let width = f64::from((self.x_px.end - self.x_px.start).max(1));
        let height = f64::from((self.y_px.end - self.y_px.start).max(1));
        (dx_px / width, -dy_px / height)
    }

    /// The values at `(x, y)` CSS pixels, `None` outside the plotting area.
    pub fn value_at(&self, at_px: (f64, f64)) -> Option<(f64, f64)> {
        let (fx, fy) = self.fraction_at(at_px)?;
        Some((
            self.x.start + fx * (self.x.end - self.x.start),
            self.y.start + fy * (self.y.end - self.y.start),
        ))
    }

    /// The values under the pointer as a person reads them ("time (s) 12.40, error
    /// (°) −3.1"), to the precision the ranges shown allow.
    pub fn readout(&self, at_px: (f64, f64)) -> Option<String> {
        let (x, y) = self.value_at(at_px)?;
        let width_px = f64::from((self.x_px.end - self.x_px.start).max(1));
        let height_px = f64::from((self.y_px.end - self.y_px.start).max(1));
        Some(format!(
            "{} {}, {} {}",
            self.x_desc,
            to_pixel(x, (self.x.end - self.x.start) / width_px),
            self.y_desc,
            to_pixel(y, (self.y.end - self.y.start) / height_px),
        ))
    }
}

/// `value` with as many decimals as a pixel's worth of the axis resolves.
fn to_pixel(value: f64, per_pixel: f64) -> String {
    let decimals = if per_pixel.is_finite() && per_pixel > 0.0 {
        (-per_pixel.log10()).ceil().clamp(0.0, 6.0) as usize
    } else {
        2
    };
    format!("{value:.decimals$}")
}

/// The indices of the samples of `t_s` (ascending) inside `window`, one either side
/// included so that a line reaches the edges.
pub fn indices_within(t_s: &[f64], window: &Range<f64>) -> Range<usize> {
    let start = t_s.partition_point(|&t| t < window.start).saturating_sub(1);
    let end = (t_s.partition_point(|&t| t <= window.end) + 1).min(t_s.len());
    start..end.max(start)
}

/// The runs of a line's points that lie inside the window: plotters draws a point
/// outside its ranges on the edge instead of leaving it out, so a zoomed plot draws
/// only these.
pub fn runs_within(points: &[(f64, f64)], x: &Range<f64>, y: &Range<f64>) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for &point in points {
        let inside = x.contains(&point.0) && y.contains(&point.1);
        match runs.last_mut() {
            Some(run) if inside => run.push(point),
            Some(run) if !run.is_empty() => runs.push(Vec::new()),
            _ => {}
        }
    }
    runs.retain(|run| !run.is_empty());
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: (f64, f64), b: (f64, f64)) -> bool {
        (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12
    }

    /// Zooming about a point keeps that point where it was, and zooming out again
    /// comes back to the whole plot.
    #[test]
    fn a_zoom_keeps_the_point_under_the_pointer() {
        let zoom = Zoom::WHOLE.zoomed((0.25, 0.5), 4.0, false);
        assert!(
            close(zoom.x, (0.25 - 0.25 / 4.0, 0.25 + 0.75 / 4.0)),
            "{zoom:?}"
        );
        assert_eq!(zoom.y, (0.0, 1.0), "x only");
        let range = zoom.x_of(100.0..200.0);
        assert!((range.start - 118.75).abs() < 1e-9 && (range.end - 143.75).abs() < 1e-9);
        assert!(zoom.zoomed((0.5, 0.5), 0.1, false).is_whole());
        let map = Zoom::WHOLE.zoomed((0.5, 0.5), 2.0, true);
        assert!(close(map.x, (0.25, 0.75)) && close(map.y, (0.25, 0.75)));
    }

    /// A pan follows the pointer and stops at the ends; it cannot leave the data.
    #[test]
    fn a_pan_follows_the_pointer_and_stops_at_the_ends() {
        let zoom = Zoom::WHOLE.zoomed((0.5, 0.5), 2.0, true);
        let moved = zoom.panned((0.1, 0.0), true);
        assert!(close(moved.x, (0.2, 0.7)), "{moved:?}");
        let far = zoom.panned((-10.0, 10.0), true);
        assert!(
            close(far.x, (0.5, 1.0)) && close(far.y, (0.0, 0.5)),
            "{far:?}"
        );
        assert!(close(
            Zoom::WHOLE.zoomed((0.5, 0.5), 1e9, false).x,
            (0.49995, 0.50005)
        ));
        assert!(Zoom::WHOLE.zoomed((0.5, 0.5), f64::NAN, true).is_whole());
    }

    #[test]
    fn the_frame_reads_the_value_under_the_pointer() {
        let frame = PlotFrame {
            x_px: 60..560,
            y_px: 40..440,
            x: 0.0..100.0,
            y: -10.0..10.0,
            x_desc: "time (s)",
            y_desc: "error (°)",
            both_axes: false,
        };
        assert_eq!(frame.value_at((310.0, 240.0)), Some((50.0, 0.0)));
        assert_eq!(frame.value_at((10.0, 240.0)), None);
        assert_eq!(
            frame.readout((60.0, 40.0)).as_deref(),
            Some("time (s) 0.0, error (°) 10.00")
        );
        assert_eq!(frame.fraction_of_move((50.0, 40.0)), (0.1, -0.1));
    }

    #[test]
    fn only_what_lies_inside_the_window_is_drawn() {
        let t_s: Vec<f64> = (0..100).map(f64::from).collect();
        assert_eq!(indices_within(&t_s, &(10.5..20.5)), 10..22);
        assert_eq!(indices_within(&t_s, &(-5.0..200.0)), 0..100);
        assert_eq!(indices_within(&[], &(0.0..1.0)), 0..0);
        let line = [(0.0, 0.0), (1.0, 1.0), (2.0, 5.0), (3.0, 1.0), (4.0, 1.0)];
        assert_eq!(
            runs_within(&line, &(0.5..10.0), &(0.0..2.0)),
            vec![vec![(1.0, 1.0)], vec![(3.0, 1.0), (4.0, 1.0)]]
        );
    }
}
