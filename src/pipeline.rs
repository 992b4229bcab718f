//! The one analysis pipeline: an imported recording → the field calibrations
//! ([`crate::calibration`]) → the heading models and the one choice of "best"
//! ([`crate::heading`], [`crate::calibration::selection`]) → dead reckoning ([`crate::pdr`]). The
//! CLI, the page and the report are thin callers of these functions, so they name the
//! same best method and export the same device calibration.
//!
//! Each stage is a function of its inputs and the options. A change re-runs the stage it
//! touches and those after it ([`Stage`]): a new declination, split or method list
//! re-runs everything; a new step model, outage, known distance or filter noise re-runs
//! only the dead reckoning, which fits the chosen model again without the outages' fixes
//! (so no fix inside an outage trains what bridges it) but does not choose again.

use crate::analysis::AnalysisError;
use crate::attitude::track::{attitude_of, FieldSource};
use crate::attitude::{AttitudeError, AttitudeOptions, AttitudeTrack};
use crate::calibration::selection::Choice;
use crate::calibration::CalibrationOptions;
use crate::calibration::{calibrate, CalibrationAnalysis, Method};
use crate::heading::{compare, HeadingAnalysis, HeadingOptions};
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
    let base = Method::ALL
        .into_iter()
        .find(|method| choice.key.split('+').next() == Some(method.key()));
    for report in [&mut calibration.report, &mut headings.report.calibration] {
        report.best = base;
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
/// accelerometer (else why not, in `pdr`).
pub fn analyse(import: &ImportReport, options: &PdrOptions) -> Result<Analysis, AnalysisError> {
    let (calibration, headings) = headings(import, &options.heading_options)?;
    let pdr = Some(dead_reckon(import, (&calibration, &headings), options));
    Ok(Analysis {
        calibration,
        headings,
        pdr,
    })
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
    )
}

/// [`attitude`] as CSV (see [`crate::attitude::track::attitude_csv`]): yaw from true
/// north where the analysis knows the declination.
pub fn attitude_csv(
    import: &ImportReport,
    calibration: &CalibrationAnalysis,
) -> Result<String, AttitudeError> {
    let (track, _) = attitude(import, calibration)?;
    let declination = &calibration.report.declination;
    let body_axes = calibration.report.mag_frame.as_ref().map_or_else(
        || "as logged (x forward, y right, z down)".to_string(),
        |frame| frame.describe(),
    );
    Ok(crate::attitude::track::attitude_csv(
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
