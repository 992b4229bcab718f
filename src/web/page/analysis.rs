//! The analysis the page runs on an import, with no DOM: the pipeline's three stages
//! ([`crate::pipeline`]) with the controls' options, and the dead reckoning's failure
//! worded for the page, one step at a time ([`Steps`]). It runs on the analysis worker
//! where the page has one (`web::worker`, the threaded module), else on the page's own
//! thread, a step per task ([`Page::analyse_here`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::{yield_to_browser, Page, Results};
use crate::analysis::AnalysisError;
use crate::calibration::CalibrationAnalysis;
use crate::heading::HeadingAnalysis;
use crate::io::ImportReport;
use crate::pdr::{PdrAnalysis, PdrError, PdrOptions};
use crate::pipeline::{self, Stage};

/// What the page asks to be analysed: a new import (every stage), or the kept one
/// again from `stage` with new settings (`previous`: the results it re-uses).
pub(crate) struct Request {
    pub import: Arc<ImportReport>,
    pub stage: Stage,
    pub previous: Option<Results>,
    pub options: PdrOptions,
}

/// The stages a request runs, in order, for the status line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Step {
    Calibrating,
    LearningHeadings,
    DeadReckoning,
}

impl Step {
    /// What the status line says while this step runs.
    pub(crate) fn status(self, file_name: &str) -> String {
        match self {
            Step::Calibrating => format!("Calibrating {file_name}…"),
            Step::LearningHeadings => {
                format!("Calibrated {file_name}; learning the heading models…")
            }
            Step::DeadReckoning => format!("Calibrated {file_name}; dead-reckoning the walk…"),
        }
    }
}

/// A request's analysis, one step at a time: whoever runs it (the worker, or the page
/// between its turns to the browser) calls [`Steps::next`] for the step to come and
/// [`Steps::advance`] to run it, until [`Steps::finish`].
pub(crate) struct Steps {
    import: Arc<ImportReport>,
    options: PdrOptions,
    state: State,
}

// One per request, moved once a step: its size is not worth a box per variant.
#[allow(clippy::large_enum_variant)]
enum State {
    Start,
    Calibrated(CalibrationAnalysis),
    HeadingsLearnt(CalibrationAnalysis, HeadingAnalysis),
    Done(Result<Results, AnalysisError>),
}

impl Steps {
    pub(crate) fn new(request: Request) -> Steps {
        let Request {
            import,
            stage,
            previous,
            options,
        } = request;
        let state = match (stage, previous) {
            // The dead reckoning alone re-uses the calibration and the heading models.
            (Stage::DeadReckoning, Some(results)) => {
                State::HeadingsLearnt(results.calibration, results.heading)
            }
            _ => State::Start,
        };
        Steps {
            import,
            options,
            state,
        }
    }

    /// The import analysed.
    pub(crate) fn import(&self) -> &Arc<ImportReport> {
        &self.import
    }

    /// The calibration, between the calibration step and the heading models.
    pub(crate) fn calibrated(&self) -> Option<&CalibrationAnalysis> {
        match &self.state {
            State::Calibrated(calibration) => Some(calibration),
            _ => None,
        }
    }

    /// The step [`Steps::advance`] runs next; `None` when done.
    pub(crate) fn next(&self) -> Option<Step> {
        match self.state {
            State::Start => Some(Step::Calibrating),
            State::Calibrated(_) => Some(Step::LearningHeadings),
            State::HeadingsLearnt(..) => Some(Step::DeadReckoning),
            State::Done(_) => None,
        }
    }

    /// Runs the next step.
    pub(crate) fn advance(&mut self) {
        let (import, options) = (&self.import, &self.options);
        let state = std::mem::replace(&mut self.state, State::Start);
        self.state = match state {
            State::Start => match pipeline::calibration(import, &options.heading_options) {
                Ok(calibration) => State::Calibrated(calibration),
                Err(error) => State::Done(Err(error)),
            },
            State::Calibrated(mut calibration) => {
                let heading = pipeline::heading_models(&mut calibration, &options.heading_options);
                State::HeadingsLearnt(calibration, heading)
            }
            State::HeadingsLearnt(calibration, heading) => {
                let pdr = dead_reckoning(import, (&calibration, &heading), options);
                State::Done(Ok(Results {
                    calibration,
                    heading,
                    pdr,
                }))
            }
            done @ State::Done(_) => done,
        };
    }

    /// The analysis, once [`Steps::next`] is `None`; before that, runs the steps left.
    pub(crate) fn finish(mut self) -> Result<Results, AnalysisError> {
        loop {
            if let State::Done(result) = self.state {
                return result;
            }
            self.advance();
        }
    }
}

/// The dead reckoning of `import` (steps, step model, the EKF), or why there is none,
/// as a sentence's end.
pub(crate) fn dead_reckoning(
    import: &ImportReport,
    stages: (&CalibrationAnalysis, &HeadingAnalysis),
    options: &PdrOptions,
) -> Result<PdrAnalysis, String> {
    crate::pdr::dead_reckon(import, stages, options).map_err(|error| match error {
        PdrError::NoAccelerometer { .. } => {
            "the log has no accelerometer, so no steps can be detected".to_string()
        }
        PdrError::Analysis(error) => error.to_string(),
        other => other.to_string(),
    })
}

impl Page {
    /// The request's [`Steps`] on the page's own thread, the browser getting a turn (to
    /// paint the status, to answer input) before each: where there is no analysis
    /// worker. `None` when `cancel` was set meanwhile.
    pub(super) async fn analyse_here(
        &self,
        request: Request,
        cancel: &AtomicBool,
    ) -> Option<Result<Results, AnalysisError>> {
        let mut steps = Steps::new(request);
        while let Some(step) = steps.next() {
            self.set_state("loading", &step.status(&steps.import().file_name));
            yield_to_browser().await;
            if cancel.load(Ordering::Acquire) {
                return None;
            }
            steps.advance();
            // The calibration's figures while the heading models wait, as the worker's
            // page shows them.
            if let Some(calibration) = steps.calibrated() {
                self.show_calibrated(steps.import(), calibration, cancel)
                    .await;
            }
        }
        Some(steps.finish())
    }
}
