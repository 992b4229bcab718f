//! The answer's picture ([`crate::present::verdict::Picture`]): one of the plots, chosen
//! by the answer, drawn on any backend: the page's canvas beside its summary, the
//! report's SVG under its verdict.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::zoom::Zoom;
use super::PlotError;
use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::headings::HeadingAnalysis;
use crate::pdr::PdrAnalysis;
use crate::present::verdict::{Picture, Verdict};

/// Draws `verdict`'s picture from the analyses it was made of; a track without a dead
/// reckoning, or compasses without an autopilot's assessment, is an error that says so.
/// The heading error is the heading comparison's chosen row, the one the headline
/// names (the attitude filter, a gyro-aided or a Fourier-corrected heading as much as a
/// field calibration); without the comparison, the best field calibration's. Returns
/// the label of the heading drawn as "after" when the picture is the heading error from
/// the comparison (the page shows it beside the figure; its tests hold it to the
/// headline).
pub fn draw_answer_picture<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    verdict: &Verdict,
    (calibration, heading): (&CalibrationAnalysis, Option<&HeadingAnalysis>),
    pdr: Option<&PdrAnalysis>,
) -> Result<Option<String>, PlotError> {
    let missing = |reason: &str| PlotError {
        plot: "answer",
        reason: reason.to_string(),
    };
    let drawn = match verdict.picture {
        Picture::Track => match pdr {
            Some(pdr) => super::pdr::draw_trajectory(area, pdr, Zoom::WHOLE).map(|_| ()),
            None => Err(missing("the log has no dead reckoning")),
        },
        Picture::HeadingError => match heading.filter(|heading| shows_choice(heading)) {
            Some(heading) => return super::deviation::draw_heading_errors(area, heading).map(Some),
            None => super::draw_heading_error(area, calibration, Zoom::WHOLE).map(|_| ()),
        },
        Picture::Coverage => super::live_panel::draw_coverage_map(area, verdict.coverage.as_ref()),
        Picture::CompassErrors => match &calibration.report.autopilot {
            Some(autopilot) => super::compass_errors::draw_compass_errors(area, autopilot),
            None => Err(missing("the log's compasses were not assessed")),
        },
        Picture::FieldMagnitude => {
            super::draw_field_magnitude_of(area, calibration, Zoom::WHOLE).map(|_| ())
        }
    };
    drawn.map(|()| None)
}

/// Whether `heading` holds the series of the row it chose, against a reference.
fn shows_choice(heading: &HeadingAnalysis) -> bool {
    let key = heading.report.choice.key;
    heading.reference_deg.iter().any(Option::is_some)
        && heading
            .headings_deg
            .iter()
            .any(|(series_key, headings_deg)| *series_key == key && !headings_deg.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::headings::HeadingOptions;
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, WalkConfig};

    /// The heading-error picture draws the heading the headline names: the comparison's
    /// choice, whichever row it is, not the best field calibration's. The analyses are
    /// the pipeline's, as the page and the report get them.
    #[test]
    fn the_heading_error_picture_shows_the_heading_the_headline_names() {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(5, 120.0)));
        let report = import("sim.csv", text.as_bytes()).expect("readable");
        let (calibration, heading) =
            crate::pipeline::headings(&report, &HeadingOptions::default()).expect("analysable");
        let verdict = crate::present::verdict::verdict(&calibration, &heading.report, None);
        assert_eq!(
            verdict.picture,
            Picture::HeadingError,
            "{}",
            verdict.headline
        );
        let mut svg = String::new();
        let shown = {
            let root = SVGBackend::with_string(&mut svg, (900, 500)).into_drawing_area();
            draw_answer_picture(&root, &verdict, (&calibration, Some(&heading)), None)
                .expect("drawable")
        };
        let label = shown.expect("the comparison's heading is drawn");
        // On this walk the choice is the attitude filter, not a field calibration: the
        // picture drew the best field calibration's heading before (the car drive's
        // headline named the filter's 5.0° beside a min/max curve).
        let choice = &heading.report.choice;
        assert_eq!(choice.key.text(), "ahrs");
        assert_eq!(label, choice.label);
        assert!(
            verdict.headline.contains(&label),
            "{} / {label}",
            verdict.headline
        );
        assert!(svg.contains(&label), "the legend names it");
        assert!(
            svg.contains("before calibration"),
            "the raw heading beside it"
        );
    }
}
