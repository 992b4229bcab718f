//! The answer's picture ([`crate::present::verdict::Picture`]): one of the plots, chosen
//! by the answer, drawn on any backend: the page's canvas beside its summary, the
//! report's SVG under its verdict.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::zoom::Zoom;
use super::PlotError;
use crate::analysis::calibration::CalibrationAnalysis;
use crate::pdr::PdrAnalysis;
use crate::present::verdict::{Picture, Verdict};

/// Draws `verdict`'s picture from the analyses it was made of; a track without a dead
/// reckoning, or compasses without an autopilot's assessment, is an error that says so.
pub fn draw_answer_picture<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    verdict: &Verdict,
    calibration: &CalibrationAnalysis,
    pdr: Option<&PdrAnalysis>,
) -> Result<(), PlotError> {
    let missing = |reason: &str| PlotError {
        plot: "answer",
        reason: reason.to_string(),
    };
    match verdict.picture {
        Picture::Track => match pdr {
            Some(pdr) => super::pdr::draw_trajectory(area, pdr, Zoom::WHOLE).map(|_| ()),
            None => Err(missing("the log has no dead reckoning")),
        },
        Picture::HeadingError => {
            super::draw_heading_error(area, calibration, Zoom::WHOLE).map(|_| ())
        }
        Picture::Coverage => super::live_panel::draw_coverage_map(area, verdict.coverage.as_ref()),
        Picture::CompassErrors => match &calibration.report.autopilot {
            Some(autopilot) => super::compass_errors::draw_compass_errors(area, autopilot),
            None => Err(missing("the log's compasses were not assessed")),
        },
        Picture::FieldMagnitude => {
            super::draw_field_magnitude_of(area, calibration, Zoom::WHOLE).map(|_| ())
        }
    }
}
