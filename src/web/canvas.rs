//! Drawing the core's plots on canvas elements.

use plotters::prelude::*;
use plotters_canvas::CanvasBackend;
use web_sys::HtmlCanvasElement;

use crate::calibration::CalibrationAnalysis;
use crate::deviation::HeadingAnalysis;
use crate::pdr::PdrAnalysis;
use crate::plot::deviation::{
    draw_deviation_curve, draw_online_convergence, draw_residual_histogram,
};
use crate::plot::pdr::{draw_position_error, draw_step_lengths, draw_trajectory};
use crate::plot::{draw_circle_fit, draw_field_magnitude_of, draw_heading_error, PlotError};

/// Which plot goes on a canvas.
#[derive(Debug, Clone, Copy)]
pub enum Plot {
    CircleFit,
    HeadingError,
    FieldMagnitude,
}

pub fn draw(
    canvas: &HtmlCanvasElement,
    plot: Plot,
    analysis: &CalibrationAnalysis,
) -> Result<(), String> {
    draw_with(canvas, |area| match plot {
        Plot::CircleFit => draw_circle_fit(area, analysis),
        Plot::HeadingError => draw_heading_error(area, analysis),
        Plot::FieldMagnitude => draw_field_magnitude_of(area, analysis),
    })
}

/// Clears the canvas to white, draws one plot on it, and presents it.
fn draw_with(
    canvas: &HtmlCanvasElement,
    plot: impl FnOnce(&DrawingArea<CanvasBackend, plotters::coord::Shift>) -> Result<(), PlotError>,
) -> Result<(), String> {
    let backend =
        CanvasBackend::with_canvas_object(canvas.clone()).ok_or("the canvas has no 2D context")?;
    let area = backend.into_drawing_area();
    area.fill(&WHITE).map_err(|error| format!("{error:?}"))?;
    plot(&area).map_err(|error| error.to_string())?;
    area.present().map_err(|error| format!("{error:?}"))
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

pub fn draw_pdr(
    canvas: &HtmlCanvasElement,
    plot: PdrPlot,
    analysis: &PdrAnalysis,
) -> Result<(), String> {
    draw_with(canvas, |area| match plot {
        PdrPlot::Trajectory => draw_trajectory(area, analysis),
        PdrPlot::StepLengths => draw_step_lengths(area, analysis),
        PdrPlot::PositionError => draw_position_error(area, analysis),
    })
}

/// The live panel's point clouds (sensor axes, µT) with the latest fit.
pub fn draw_live_clouds(
    canvas: &HtmlCanvasElement,
    samples_ut: &[nalgebra::Vector3<f64>],
    quality: Option<&crate::live::LiveQuality>,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::plot::live::draw_live_clouds(area, samples_ut, quality)
    })
}

/// The live panel's coverage map.
pub fn draw_coverage(
    canvas: &HtmlCanvasElement,
    coverage: Option<&crate::calib::sphere_coverage::SphereCoverage>,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::plot::live::draw_coverage_map(area, coverage)
    })
}

/// The controls' timeline.
pub fn draw_timeline(
    canvas: &HtmlCanvasElement,
    timeline: &crate::plot::timeline::Timeline,
) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::plot::timeline::draw_timeline(area, timeline)
    })
}

/// The live panel's heading dial.
pub fn draw_dial(canvas: &HtmlCanvasElement, heading_rad: Option<f64>) -> Result<(), String> {
    draw_with(canvas, |area| {
        crate::plot::live::draw_heading_dial(area, heading_rad)
    })
}

/// Replaces a plot by a message, so that a failed analysis never leaves a blank or
/// stale canvas.
pub fn draw_message(canvas: &HtmlCanvasElement, message: &str) -> Result<(), String> {
    let backend =
        CanvasBackend::with_canvas_object(canvas.clone()).ok_or("the canvas has no 2D context")?;
    let area = backend.into_drawing_area();
    area.fill(&RGBColor(250, 246, 240))
        .map_err(|error| format!("{error:?}"))?;
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
        .map_err(|error| format!("{error:?}"))?;
    }
    area.present().map_err(|error| format!("{error:?}"))
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
