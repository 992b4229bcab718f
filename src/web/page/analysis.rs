//! The analysis the page runs on an import, with no DOM: the pipeline's steps
//! ([`crate::pipeline::Steps`]) with the controls' options, one at a time, their status
//! line, and the dead reckoning's failure worded for the page. It runs on the analysis
//! worker where the page has one (`web::worker`, the threaded module), else on the
//! page's own thread, a step per task ([`Page::analyse_here`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use super::{yield_to_browser, Page, Results};
use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::levelled::AnalysisError;
use crate::io::ImportReport;
use crate::pdr::{PdrError, PdrOptions};
use crate::pipeline::{self, Stage, Step};

/// What the page asks to be analysed: a new import (every stage), or the kept one
/// again from `stage` with new settings (`previous`: the results it re-uses).
pub(crate) struct Request {
    pub import: Arc<ImportReport>,
    pub stage: Stage,
    pub previous: Option<Results>,
    pub options: PdrOptions,
}

/// What the status line says while `step` runs.
pub(crate) fn status(step: Step, file_name: &str) -> String {
    match step {
        Step::Calibrating => format!("Calibrating {file_name}…"),
        Step::LearningHeadings => format!("Calibrated {file_name}; learning the heading models…"),
        Step::DeadReckoning => format!("Calibrated {file_name}; dead-reckoning the walk…"),
    }
}

/// A request's analysis, one step at a time: the pipeline's [`pipeline::Steps`] on the
/// request's import. Whoever runs it (the worker, or the page between its turns to the
/// browser) calls [`Steps::next`] for the step to come and [`Steps::advance`] to run
/// it, until [`Steps::finish`].
pub(crate) struct Steps {
    import: Arc<ImportReport>,
    steps: pipeline::Steps,
}

impl Steps {
    pub(crate) fn new(request: Request) -> Steps {
        let Request {
            import,
            stage,
            previous,
            options,
        } = request;
        let steps = match (stage, previous) {
            // The dead reckoning alone re-uses the calibration and the heading models.
            (Stage::DeadReckoning, Some(results)) => {
                pipeline::Steps::after_headings(options, results.calibration, results.heading)
            }
            _ => pipeline::Steps::new(options),
        };
        Steps { import, steps }
    }

    /// The import analysed.
    pub(crate) fn import(&self) -> &Arc<ImportReport> {
        &self.import
    }

    /// The calibration, between the calibration step and the heading models.
    pub(crate) fn calibrated(&self) -> Option<&CalibrationAnalysis> {
        self.steps.calibrated()
    }

    /// The step [`Steps::advance`] runs next; `None` when done.
    pub(crate) fn next(&self) -> Option<Step> {
        self.steps.next()
    }

    /// Runs the next step.
    pub(crate) fn advance(&mut self) {
        self.steps.advance(&self.import);
    }

    /// The analysis, once [`Steps::next`] is `None`; before that, runs the steps left.
    pub(crate) fn finish(self) -> Result<Results, AnalysisError> {
        let analysis = self.steps.finish(&self.import)?;
        Ok(Results {
            calibration: analysis.calibration,
            heading: analysis.headings,
            pdr: match analysis.pdr {
                Some(pdr) => pdr.map_err(worded),
                None => Err("the dead reckoning was not run".to_string()),
            },
        })
    }
}

/// Why there is no dead reckoning, as a sentence's end.
fn worded(error: PdrError) -> String {
    match error {
        PdrError::NoAccelerometer { .. } => {
            "the log has no accelerometer, so no steps can be detected".to_string()
        }
        PdrError::Analysis(error) => error.to_string(),
        other => other.to_string(),
    }
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
            self.set_state("loading", &status(step, &steps.import().file_name));
            yield_to_browser().await;
            if cancel.load(Ordering::Acquire) {
                return None;
            }
            steps.advance();
            // The calibration's figures while the heading models wait, as the worker's
            // page shows them.
            if let Some(calibration) = steps.calibrated() {
                // Nothing else runs meanwhile: the job is not finished before the
                // figures are drawn.
                let finished = AtomicBool::new(false);
                self.show_calibrated(steps.import(), calibration, (cancel, &finished))
                    .await;
            }
        }
        Some(steps.finish())
    }
}
