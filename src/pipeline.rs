//! The one analysis pipeline: an imported recording → the field calibrations
//! ([`crate::analysis::calibration`]) → the heading models and the one choice of "best"
//! ([`crate::analysis::headings`], [`crate::analysis::calibration::selection`], written
//! back into the calibration's report so that its device calibration follows it) →
//! dead reckoning ([`crate::pdr`]). The CLI, the page and the report are thin callers of
//! these functions, so they name the same best method and export the same device
//! calibration.
//!
//! Each stage is a function of its inputs and the options. A change re-runs the stage it
//! touches and those after it ([`Stage`]): a new declination, split or method list
//! re-runs everything; a new step model, outage, known distance or filter noise re-runs
//! only the dead reckoning, which fits the chosen model again without the outages' fixes
//! (so no fix inside an outage trains what bridges it, on the calibration's levelled
//! samples unless their down used fixes the outages hide) but does not choose again.
//!
//! [`analyse`] runs every stage; [`Steps`] is the same order one step at a time
//! (`next`, `advance`, `finish`; `after_headings` for the dead reckoning alone), for a
//! caller with other work between steps (the page's worker); [`dead_reckoning`] is the
//! whole for callers that want only the track; [`calibrate_file`] and
//! [`calibrate_files`] the calibration stage on bytes (tests and scripts); [`attitude`]
//! and [`attitude_csv`] the attitude filter with the analysis's device calibration.

use crate::analysis::attitude_track::{attitude_of, FieldSource};
use crate::analysis::calibration::selection::Choice;
use crate::analysis::calibration::CalibrationOptions;
use crate::analysis::calibration::{calibrate, CalibrationAnalysis};
use crate::analysis::headings::{compare, HeadingAnalysis, HeadingOptions};
use crate::analysis::levelled::AnalysisError;
use crate::attitude::{AttitudeError, AttitudeOptions, AttitudeTrack};
use crate::io::import::import_files;
use crate::io::ImportReport;
use crate::pdr::{dead_reckon, PdrAnalysis, PdrError, PdrOptions};

/// Where a re-run starts (the page's controls say which stage a change touches, and run
/// the stage functions from there).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// The calibration, the heading models and the dead reckoning.
    Calibration,
    /// The dead reckoning only.
    DeadReckoning,
}

/// Everything the pipeline found in one recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Analysis {
    /// The field calibrations. Its report's `best` and `choice` are the analysis's one
    /// choice (set by [`headings`]), so its device calibration follows it.
    pub calibration: CalibrationAnalysis,
    /// Every heading method and model on the same split, and the choice.
    pub headings: HeadingAnalysis,
    /// The dead reckoning, or why there is none; `None` when it was not asked for.
    pub pdr: Option<Result<PdrAnalysis, PdrError>>,
}

impl Analysis {
    /// The one best heading method, and why.
    pub fn best(&self) -> &Choice {
        &self.headings.report.choice
    }
}

/// The calibration stage: every field-domain method the options name.
pub fn calibration(
    import: &ImportReport,
    options: &HeadingOptions,
) -> Result<CalibrationAnalysis, AnalysisError> {
    calibrate(import.clone(), &options.calibration)
}

/// The heading stage: every heading model on top of the calibrations, on the same
/// split, and the one choice of "best", written back into the calibration's report (so
/// that its device calibration follows it).
pub fn heading_models(
    calibration: &mut CalibrationAnalysis,
    options: &HeadingOptions,
) -> HeadingAnalysis {
    let mut headings = compare(calibration, options);
    let choice = headings.report.choice.clone();
    for report in [&mut calibration.report, &mut headings.report.calibration] {
        report.choice = Some(choice.clone());
    }
    headings
}

/// The calibration and the heading stages.
pub fn headings(
    import: &ImportReport,
    options: &HeadingOptions,
) -> Result<(CalibrationAnalysis, HeadingAnalysis), AnalysisError> {
    let mut calibration = calibration(import, options)?;
    let headings = heading_models(&mut calibration, options);
    Ok((calibration, headings))
}

/// Every stage: [`headings`], then the dead reckoning when the log has an
/// accelerometer (else why not, in `pdr`). [`Steps`] run to the end.
pub fn analyse(import: &ImportReport, options: &PdrOptions) -> Result<Analysis, AnalysisError> {
    Steps::new(options.clone()).finish(import)
}

/// The steps of [`analyse`], in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    Calibrating,
    LearningHeadings,
    DeadReckoning,
}

/// [`analyse`] one step at a time, for a caller that has other work between them (the
/// page's worker says which step runs and shows the calibration's figures before the
/// heading models are done; without a worker, the page yields to the browser between
/// steps): [`Steps::next`] names the step to come, [`Steps::advance`] runs it, until
/// [`Steps::finish`]. The one order of the stages, whichever caller runs them.
pub struct Steps {
    options: PdrOptions,
    state: StepState,
}

// One per analysis, moved once a step: its size is not worth a box per variant.
#[allow(clippy::large_enum_variant)]
enum StepState {
    Start,
    Calibrated(CalibrationAnalysis),
    HeadingsLearnt(CalibrationAnalysis, HeadingAnalysis),
    Done(Result<Analysis, AnalysisError>),
}

impl Steps {
    /// Every stage, from the calibration.
    pub fn new(options: PdrOptions) -> Steps {
        Steps {
            options,
            state: StepState::Start,
        }
    }

    /// The dead reckoning alone ([`Stage::DeadReckoning`]), on the calibration and the
    /// heading models of an earlier run.
    pub fn after_headings(
        options: PdrOptions,
        calibration: CalibrationAnalysis,
        headings: HeadingAnalysis,
    ) -> Steps {
        Steps {
            options,
            state: StepState::HeadingsLearnt(calibration, headings),
        }
    }

    /// The step [`Steps::advance`] runs next; `None` when done.
    pub fn next(&self) -> Option<Step> {
        match self.state {
            StepState::Start => Some(Step::Calibrating),
            StepState::Calibrated(_) => Some(Step::LearningHeadings),
            StepState::HeadingsLearnt(..) => Some(Step::DeadReckoning),
            StepState::Done(_) => None,
        }
    }

    /// The calibration, between the calibration step and the heading models.
    pub fn calibrated(&self) -> Option<&CalibrationAnalysis> {
        match &self.state {
            StepState::Calibrated(calibration) => Some(calibration),
            _ => None,
        }
    }

    /// Runs the next step on `import` (the same import at every step).
    pub fn advance(&mut self, import: &ImportReport) {
        let options = &self.options;
        let state = std::mem::replace(&mut self.state, StepState::Start);
        self.state = match state {
            StepState::Start => match calibration(import, &options.heading_options) {
                Ok(calibration) => StepState::Calibrated(calibration),
                Err(error) => StepState::Done(Err(error)),
            },
            StepState::Calibrated(mut calibration) => {
                let headings = heading_models(&mut calibration, &options.heading_options);
                StepState::HeadingsLearnt(calibration, headings)
            }
            StepState::HeadingsLearnt(calibration, headings) => {
                let pdr = Some(dead_reckon(import, (&calibration, &headings), options));
                StepState::Done(Ok(Analysis {
                    calibration,
                    headings,
                    pdr,
                }))
            }
            done @ StepState::Done(_) => done,
        };
    }

    /// The analysis, running the steps left.
    pub fn finish(mut self, import: &ImportReport) -> Result<Analysis, AnalysisError> {
        loop {
            if let StepState::Done(result) = self.state {
                return result;
            }
            self.advance(import);
        }
    }
}

/// The dead reckoning of a recording, with the stages before it (for callers that
/// want only the track).
pub fn dead_reckoning(
    import: &ImportReport,
    options: &PdrOptions,
) -> Result<PdrAnalysis, PdrError> {
    let (calibration, headings) = headings(import, &options.heading_options)?;
    dead_reckon(import, (&calibration, &headings), options)
}

/// The attitude filter ([`crate::attitude`]) on the recording, its field corrected by
/// the analysis's device calibration (the one exported).
pub fn attitude(
    import: &ImportReport,
    calibration: &CalibrationAnalysis,
) -> Result<(AttitudeTrack, FieldSource), AttitudeError> {
    let device = calibration.device_calibration().map(|(_, field)| field);
    attitude_of(
        &import.recording,
        device.as_ref(),
        &AttitudeOptions::for_gyro(import.recording.gyro_bias),
        crate::attitude::smoother::Runs::BothWays,
    )
}

/// [`attitude`] as CSV (see [`crate::analysis::attitude_track::attitude_csv`]): yaw from true
/// north where the analysis knows the declination.
pub fn attitude_csv(
    import: &ImportReport,
    calibration: &CalibrationAnalysis,
) -> Result<String, AttitudeError> {
    let (track, _) = attitude(import, calibration)?;
    let declination = &calibration.report.declination;
    let body_axes = calibration.report.mag_frame.as_ref().map_or_else(
        || "as logged (x forward, y right, z down)".to_string(),
        crate::io::frame::SensorFrame::describe,
    );
    Ok(crate::analysis::attitude_track::attitude_csv(
        &track,
        declination
            .is_known()
            .then_some(declination.declination_deg),
        &body_axes,
        import.recording.start_unix_s,
    ))
}

/// The calibration stage on the bytes of one log (any format [`crate::io::import`]
/// knows), for tests and scripts (the page and the CLI read files in chunks).
pub fn calibrate_file(
    file_name: &str,
    bytes: &[u8],
    options: &CalibrationOptions,
) -> Result<CalibrationAnalysis, AnalysisError> {
    calibrate_files(&[(file_name, bytes)], options)
}

/// The calibration stage on the files of one recording, merged (phyphox writes one file
/// per sensor).
pub fn calibrate_files(
    files: &[(&str, &[u8])],
    options: &CalibrationOptions,
) -> Result<CalibrationAnalysis, AnalysisError> {
    calibrate(import_files(files)?, options)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, WalkConfig};

    /// Run one step at a time, the analysis is [`analyse`]'s, in the one order; the
    /// calibration is there between its step and the heading models'.
    #[test]
    fn the_steps_one_at_a_time_give_the_whole_analysis() {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(3, 60.0)));
        let import = import("walk.csv", text.as_bytes()).expect("readable");
        let mut options = PdrOptions::default();
        options.heading_options.neural = false;
        let mut steps = Steps::new(options.clone());
        let mut order = Vec::new();
        while let Some(step) = steps.next() {
            order.push(step);
            steps.advance(&import);
            assert_eq!(steps.calibrated().is_some(), step == Step::Calibrating);
        }
        assert_eq!(
            order,
            [
                Step::Calibrating,
                Step::LearningHeadings,
                Step::DeadReckoning
            ]
        );
        let analysis = steps.finish(&import).expect("analysable");
        // Compared as printed: the analyses hold NaN where a figure is undefined.
        let printed = |analysis: &Analysis| format!("{analysis:?}");
        let whole = analyse(&import, &options).expect("analysable");
        assert!(
            printed(&analysis) == printed(&whole),
            "the steps differ from analyse"
        );
        // The dead reckoning alone, on the same calibration and models, is the same.
        let again = Steps::after_headings(
            options,
            analysis.calibration.clone(),
            analysis.headings.clone(),
        );
        assert_eq!(again.next(), Some(Step::DeadReckoning));
        let again = again.finish(&import).expect("analysable");
        assert!(
            printed(&again) == printed(&analysis),
            "the dead reckoning alone differs"
        );
    }
}
