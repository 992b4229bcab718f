//! Drawing the core's plots on canvas elements, through [`HiDpi`], a backend adapter
//! that lays the plots out in CSS pixels on a backing store of `devicePixelRatio` times
//! as many; a plot that cannot be drawn is replaced by a message ([`draw_message`]).

use plotters::prelude::*;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind,
};
use plotters_canvas::CanvasBackend;
use wasm_bindgen::JsCast;
use web_sys::HtmlCanvasElement;

use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::headings::HeadingAnalysis;
use crate::pdr::PdrAnalysis;
use crate::present::plot::deviation::{
    draw_deviation_curve, draw_online_convergence, draw_residual_histogram,
};
use crate::present::plot::pdr::{draw_position_error, draw_step_lengths, draw_trajectory};
use crate::present::plot::zoom::{PlotFrame, Zoom};
use crate::present::plot::{
    draw_circle_fit, draw_field_magnitude_of, draw_heading_error, PlotError,
};

/// Which plot goes on a canvas.
#[derive(Debug, Clone, Copy)]
pub enum Plot {
    CircleFit,
    HeadingError,
    FieldMagnitude,
}

/// Draws `plot` (zoomed by `zoom` where it zooms); the frame of a zoomable plot.
pub fn draw(
    canvas: &HtmlCanvasElement,
    plot: Plot,
    analysis: &CalibrationAnalysis,
    zoom: Zoom,
) -> Result<Option<PlotFrame>, String> {
    draw_with(canvas, |area| match plot {
        Plot::CircleFit => draw_circle_fit(area, analysis).map(|()| None),
        Plot::HeadingError => draw_heading_error(area, analysis, zoom).map(Some),
        Plot::FieldMagnitude => draw_field_magnitude_of(area, analysis, zoom).map(Some),
    })
}

/// Clears the canvas to white, draws one plot on it, and presents it.
fn draw_with<T>(
    canvas: &HtmlCanvasElement,
    plot: impl FnOnce(&DrawingArea<HiDpi, plotters::coord::Shift>) -> Result<T, PlotError>,
) -> Result<T, String> {
    let area = HiDpi::of(canvas)?.into_drawing_area();
    area.fill(&WHITE).map_err(|error| error.to_string())?;
    let drawn = plot(&area).map_err(|error| error.to_string())?;
    area.present().map_err(|error| error.to_string())?;
    Ok(drawn)
}

/// Which heading-model plot goes on a canvas.
#[derive(Debug, Clone, Copy)]
pub enum HeadingPlot {
    DeviationCurve,
    ResidualHistogram,
    OnlineConvergence,
}

pub fn draw_heading(
    canvas: &HtmlCanvasElement,
    plot: HeadingPlot,
    analysis: &HeadingAnalysis,
) -> Result<(), String> {
    draw_with(canvas, |area| match plot {
        HeadingPlot::DeviationCurve => draw_deviation_curve(area, analysis),
        HeadingPlot::ResidualHistogram => draw_residual_histogram(area, analysis),
        HeadingPlot::OnlineConvergence => draw_online_convergence(area, analysis),
    })
}

/// Which dead-reckoning plot goes on a canvas.
#[derive(Debug, Clone, Copy)]
pub enum PdrPlot {
    Trajectory,
    StepLengths,
    PositionError,
}

/// Draws `plot` (the trajectory zoomed by `zoom`); the trajectory's frame.
pub fn draw_pdr(
    canvas: &HtmlCanvasElement,
    plot: PdrPlot,
    analysis: &PdrAnalysis,
    zoom: Zoom,
) -> Result<Option<PlotFrame>, String> {
    draw_with(canvas, |area| match plot {
        PdrPlot::Trajectory => draw_trajectory(area, analysis, zoom).map(Some),
        PdrPlot::StepLengths => draw_step_lengths(area, analysis).map(|()| None),
        PdrPlot::PositionError => draw_position_error(area, analysis).map(|()| None),
    })
}

/// The live panel's point clouds (sensor axes, µT) with the latest fit.
pub fn draw_live_clouds(
    canvas: &HtmlCanvasElement,
    samples_ut: &[nalgebra::Vector3<f64>],
    quality: Option<&crate::live::LiveQuality>,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::present::plot::live_panel::draw_live_clouds(area, samples_ut, quality)
    })
}

/// The live panel's 3D view of the field directions on the fitted sphere.
pub fn draw_sphere(
    canvas: &HtmlCanvasElement,
    samples_ut: &[nalgebra::Vector3<f64>],
    quality: Option<&crate::live::LiveQuality>,
    view: crate::present::plot::sphere_view::SphereView,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::present::plot::sphere_view::draw_sphere_view(area, samples_ut, quality, view)
    })
}

/// The live panel's coverage map.
pub fn draw_coverage(
    canvas: &HtmlCanvasElement,
    coverage: Option<&crate::fit::coverage::SphereCoverage>,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::present::plot::live_panel::draw_coverage_map(area, coverage)
    })
}

/// The answer's picture ([`crate::present::plot::answer`]).
pub fn draw_answer_picture(
    canvas: &HtmlCanvasElement,
    verdict: &crate::present::verdict::Verdict,
    analyses: (&CalibrationAnalysis, Option<&HeadingAnalysis>),
    pdr: Option<&PdrAnalysis>,
) -> Result<Option<String>, String> {
    draw_with(canvas, |area| {
        crate::present::plot::answer::draw_answer_picture(area, verdict, analyses, pdr)
    })
}

/// The controls' timeline.
pub fn draw_timeline(
    canvas: &HtmlCanvasElement,
    timeline: &crate::present::plot::timeline::Timeline,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::present::plot::timeline::draw_timeline(area, timeline)
    })
}

/// The live panel's heading dial.
pub fn draw_dial(
    canvas: &HtmlCanvasElement,
    heading_rad: Option<f64>,
    filter_heading_rad: Option<(f64, f64)>,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::present::plot::live_panel::draw_heading_dial(area, heading_rad, filter_heading_rad)
    })
}

/// Replaces a plot by a message, so that a failed analysis never leaves a blank or
/// stale canvas.
pub fn draw_message(canvas: &HtmlCanvasElement, message: &str) -> Result<(), String> {
    let area = HiDpi::of(canvas)?.into_drawing_area();
    area.fill(&RGBColor(250, 246, 240))
        .map_err(|error| error.to_string())?;
    let (width_px, height_px) = area.dim_in_pixel();
    // About 8 px per character of a 15 px sans-serif font.
    let lines = wrap_words(message, (width_px as usize).saturating_sub(32) / 8);
    let style = ("sans-serif", 15).into_font().color(&RGBColor(150, 40, 20));
    let line_height_px = 22;
    let top_px = height_px as i32 / 2 - line_height_px * lines.len() as i32 / 2;
    for (line_idx, line) in lines.iter().enumerate() {
        area.draw(&Text::new(
            line.clone(),
            (16, top_px + line_height_px * line_idx as i32),
            style.clone(),
        ))
        .map_err(|error| error.to_string())?;
    }
    area.present().map_err(|error| error.to_string())
}

/// Splits text into lines of at most `max_chars` characters at spaces (a longer word
/// gets a line of its own).
fn wrap_words(text: &str, max_chars: usize) -> Vec<String> {
    let max_chars = max_chars.max(10);
    let mut lines: Vec<String> = Vec::new();
    let mut current = String::new();
    for word in text.split_whitespace() {
        if !current.is_empty() && current.chars().count() + 1 + word.chars().count() > max_chars {
            lines.push(std::mem::take(&mut current));
        }
        if !current.is_empty() {
            current.push(' ');
        }
        current.push_str(word);
    }
    if !current.is_empty() {
        lines.push(current);
    }
    lines
}

/// The size a canvas is laid out for, in CSS pixels: its `width` and `height` as the
/// page wrote them (kept in `data-width` and `data-height` the first time, since the
/// backing store is then resized).
pub fn logical_size(canvas: &HtmlCanvasElement) -> (u32, u32) {
    let read = |name: &str, current: u32| match canvas
        .get_attribute(name)
        .and_then(|value| value.parse::<u32>().ok())
    {
        Some(value) => value,
        None => {
            let _ = canvas.set_attribute(name, &current.to_string());
            current
        }
    };
    (
        read("data-width", canvas.width()),
        read("data-height", canvas.height()),
    )
}

/// A canvas backend whose backing store has `devicePixelRatio` pixels per CSS pixel (so
/// plots are sharp on high-density screens) while the plots lay themselves out in CSS
/// pixels: the size it reports is the logical one, and the 2D context is scaled.
pub struct HiDpi {
    inner: CanvasBackend,
    logical: (u32, u32),
}

impl HiDpi {
    fn of(canvas: &HtmlCanvasElement) -> Result<HiDpi, String> {
        let logical = logical_size(canvas);
        let ratio = web_sys::window()
            .map_or(1.0, |window| window.device_pixel_ratio())
            .clamp(1.0, 4.0);
        let physical = (
            (f64::from(logical.0) * ratio).round() as u32,
            (f64::from(logical.1) * ratio).round() as u32,
        );
        if (canvas.width(), canvas.height()) != physical {
            canvas.set_width(physical.0);
            canvas.set_height(physical.1);
        }
        let inner = CanvasBackend::with_canvas_object(canvas.clone())
            .ok_or("the canvas has no 2D context")?;
        let context = canvas
            .get_context("2d")
            .ok()
            .flatten()
            .and_then(|context| context.dyn_into::<web_sys::CanvasRenderingContext2d>().ok())
            .ok_or("the canvas has no 2D context")?;
        context
            .set_transform(ratio, 0.0, 0.0, ratio, 0.0, 0.0)
            .map_err(|_| "the canvas could not be scaled".to_string())?;
        Ok(HiDpi { inner, logical })
    }
}

type CanvasErrorKind = DrawingErrorKind<<CanvasBackend as DrawingBackend>::ErrorType>;

impl DrawingBackend for HiDpi {
    type ErrorType = <CanvasBackend as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.logical
    }

    fn ensure_prepared(&mut self) -> Result<(), CanvasErrorKind> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), CanvasErrorKind> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.fill_polygon(vert, style)
    }

    fn draw_text<TStyle: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &TStyle,
        pos: BackendCoord,
    ) -> Result<(), CanvasErrorKind> {
        self.inner.draw_text(text, style, pos)
    }

    fn estimate_text_size<TStyle: BackendTextStyle>(
        &self,
        text: &str,
        style: &TStyle,
    ) -> Result<(u32, u32), CanvasErrorKind> {
        self.inner.estimate_text_size(text, style)
    }
}
