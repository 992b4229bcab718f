//! An autopilot's compasses against the Earth's field: for each compass, the RMS of the
//! vector error `|corrected − Rᵀ·B|` (mG) over the whole log with the parameters in
//! force and with the new parameters as their written lines give them
//! ([`crate::analysis::calibration::autopilot`]). Readable without colour: the
//! parameters in force are an outlined bar, the new ones a filled bar, and each bar
//! carries its figure and what it is.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::PlotError;
use crate::analysis::calibration::autopilot::{AutopilotCalibration, CompassResult};

const IN_FORCE_COLOR: RGBColor = RGBColor(90, 90, 90);
const NEW_COLOR: RGBColor = RGBColor(30, 100, 200);
/// Half a compass's group of two bars, in compass widths.
const BAR_WIDTH: f64 = 0.32;
const BAR_GAP: f64 = 0.03;

/// Draws each compass's error against the Earth's field, in force and new.
pub fn draw_compass_errors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    autopilot: &AutopilotCalibration,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("compass errors");
    let compasses = &autopilot.compasses;
    let n = compasses.len().max(1);
    let largest_mg = compasses
        .iter()
        .flat_map(|compass| [compass.whole.in_force, compass.whole.new])
        .flatten()
        .map(|score| score.vector_rms_mg)
        .filter(|value| value.is_finite())
        .fold(1.0, f64::max);
    let x_range = -0.6..n as f64 - 0.4;
    let y_range = 0.0..largest_mg * 1.3;
    let labels: Vec<String> = compasses.iter().map(CompassResult::label).collect();
    let label_of = |x: &f64| {
        let idx = x.round();
        if (x - idx).abs() < 1e-6 && idx >= 0.0 {
            labels.get(idx as usize).cloned().unwrap_or_default()
        } else {
            String::new()
        }
    };
    let mut chart = ChartBuilder::on(area)
        .caption("Each compass against the Earth's field", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(52)
        .build_cartesian_2d(x_range, y_range)
        .map_err(&error)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n * 2 + 1)
        .x_label_formatter(&label_of)
        .y_desc("vector error RMS (mG)")
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(&error)?;
    for (idx, compass) in compasses.iter().enumerate() {
        let centre = idx as f64;
        let bars = [
            (compass.whole.in_force, -1.0, "in force", false),
            (
                compass.whole.new,
                1.0,
                if compass.is_written() {
                    "written"
                } else {
                    "fitted, kept out"
                },
                true,
            ),
        ];
        for (score, side, what, filled) in bars {
            let Some(value) = score
                .map(|score| score.vector_rms_mg)
                .filter(|v| v.is_finite())
            else {
                continue;
            };
            let (near, far) = (
                centre + side * BAR_GAP,
                centre + side * (BAR_GAP + BAR_WIDTH),
            );
            let (left, right) = (near.min(far), near.max(far));
            let style = if filled {
                NEW_COLOR.filled()
            } else {
                IN_FORCE_COLOR.stroke_width(2)
            };
            chart
                .draw_series([Rectangle::new([(left, 0.0), (right, value)], style)])
                .map_err(&error)?;
            chart
                .draw_series([Text::new(
                    format!("{what}: {value:.0}"),
                    (left, value + largest_mg * 0.12),
                    ("sans-serif", 12).into_font().color(&BLACK),
                )])
                .map_err(&error)?;
        }
    }
    Ok(())
}
