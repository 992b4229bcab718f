//! The answer first: what a person should know of one log's analysis before any detail,
//! in a headline with its figure, a grade, the method chosen and why, a few key figures
//! and what to do next. The page puts it on the first screen and the HTML report at its
//! top; both take it from here, so they say the same.
//!
//! Three kinds of log get three kinds of answer:
//! - **a reference heading** (a column, GPS course, the autopilot's heading, legs): the
//!   heading error before and after, in degrees, on the part kept back to check;
//! - **no reference** (a board turned in the hand): how much the field's magnitude varies
//!   before and after the correction, the coverage of the sphere of directions and the
//!   fitted field against the World Magnetic Model, graded by the live panel's own
//!   conditions ([`crate::fit::quality::field_verdict`]), so a file and a live session are judged
//!   alike;
//! - **an autopilot log** with compasses fitted and written back: its first compass,
//!   written or kept, by the vector error against the Earth's field and the heading
//!   against the autopilot's, in force and as written (never the raw field, whose
//!   calibration was undone), and every compass's sentence as a figure.
//!
//! It warns when the calibration to be exported makes |B| vary more than the raw field
//! does, and does not count a vehicle's "steps" as steps ([`is_walk`]).
//!
//! Pure: it takes the analyses and returns values.

use nalgebra::Vector3;
use serde::Serialize;

use crate::analysis::calibration::autopilot::{describe, AutopilotCalibration, CompassResult};
use crate::analysis::calibration::row_key::RowKey;
use crate::analysis::calibration::selection::Basis;
use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::headings::HeadingReport;
use crate::base::stats::{spread_pct, HeadingErrorStats};
use crate::base::words::{duration_text, plural};
use crate::fit::coverage::{sphere_coverage, SphereCoverage};
use crate::fit::quality::field_verdict;
use crate::io::thousands;
use crate::pdr::PdrReport;

/// A heading error (RMS, degrees) within this reads as good: a hand-bearing compass's
/// accuracy, and under 3.5 % cross-track drift for dead reckoning.
pub const GOOD_HEADING_RMS_DEG: f64 = 2.0;
/// Within this, usable with care (about 9 % cross-track drift at 5°); above it, poor.
pub const FAIR_HEADING_RMS_DEG: f64 = 5.0;

/// How good the answer is, for the words and the colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grade {
    Good,
    Fair,
    Poor,
}

impl Grade {
    pub fn key(self) -> &'static str {
        match self {
            Grade::Good => "good",
            Grade::Fair => "fair",
            Grade::Poor => "poor",
        }
    }

    pub fn word(self) -> &'static str {
        match self {
            Grade::Good => "Good",
            Grade::Fair => "Usable with care",
            Grade::Poor => "Poor",
        }
    }

    fn of_heading_rms(rms_deg: f64) -> Grade {
        if rms_deg <= GOOD_HEADING_RMS_DEG {
            Grade::Good
        } else if rms_deg <= FAIR_HEADING_RMS_DEG {
            Grade::Fair
        } else {
            Grade::Poor
        }
    }
}

/// Which answer the log allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VerdictKind {
    Heading,
    FieldOnly,
    Autopilot,
}

impl VerdictKind {
    pub fn key(self) -> &'static str {
        match self {
            VerdictKind::Heading => "heading",
            VerdictKind::FieldOnly => "field_only",
            VerdictKind::Autopilot => "autopilot",
        }
    }
}

/// One key figure: a short label and its value with the unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Figure {
    pub label: String,
    pub value: String,
}

fn figure(label: &str, value: String) -> Figure {
    Figure {
        label: label.to_string(),
        value,
    }
}

/// The answer to one log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    pub kind: VerdictKind,
    pub grade: Grade,
    /// One sentence with the figure that matters.
    pub headline: String,
    /// What was read: format, samples, duration, reference.
    pub read: String,
    /// The method chosen and why.
    pub method: String,
    pub figures: Vec<Figure>,
    /// What to do to get a better answer; empty when there is nothing to do.
    pub to_do: Vec<String>,
    /// For a log without a reference (a board turned in the hand): where the corrected
    /// field's directions fell on MotionCal's 100 regions, the figure that says which
    /// directions to turn the board through again.
    pub coverage: Option<SphereCoverage>,
    /// For a walk (not a vehicle's log, not an autopilot's): its steps as a status line
    /// says them ("35 steps dead-reckoned over 19 m."), so that the page's status and
    /// this summary count steps for the same logs.
    pub steps: Option<String>,
    /// The picture that goes with the answer ([`Picture`]).
    pub picture: Picture,
}

/// The answer's picture: what the page draws beside the headline, chosen by what the
/// log is, each drawn by the same plotting code as the folded details' figures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Picture {
    /// A walk on a map (GNSS fixes, or reference positions): the dead-reckoned track
    /// with its σ, the fixes and the reference positions.
    Track,
    /// A log with a reference heading: the heading error before and after over time.
    HeadingError,
    /// A board turned in the hand: the sphere of directions with its gaps.
    Coverage,
    /// An autopilot's log: each compass's error against the Earth's field, with the
    /// parameters in force and as written.
    CompassErrors,
    /// A log with neither reference nor calibration: |B| over time, before and after.
    FieldMagnitude,
}

impl Picture {
    pub fn key(self) -> &'static str {
        match self {
            Picture::Track => "track",
            Picture::HeadingError => "heading_error",
            Picture::Coverage => "coverage",
            Picture::CompassErrors => "compass_errors",
            Picture::FieldMagnitude => "field_magnitude",
        }
    }

    /// What the picture shows, in a sentence under it.
    pub fn caption(self) -> &'static str {
        match self {
            Picture::Track => {
                "The walk as dead-reckoned from its steps (solid line, thicker where it had no \
                 GNSS), with rings of its position's 1σ (thin, grey), and the GNSS fixes (dots) \
                 and the reference positions (thin line, crosses) where the log has them."
            }
            Picture::HeadingError => {
                "The heading's error against the log's reference over time: before calibration \
                 (rings) and with the heading the answer chose (dots); a grey line marks where \
                 the part kept back to check begins."
            }
            Picture::Coverage => {
                "The directions the board was turned through (MotionCal's 100 regions of the \
                 sphere): filled where samples fell, pale with an edge where none did. To cover \
                 them, turn the board so that its axes point that way."
            }
            Picture::CompassErrors => {
                "Each compass's error against the Earth's field over the whole log: with the \
                 parameters in force (outlined) and with the new ones (filled)."
            }
            Picture::FieldMagnitude => {
                "The field's magnitude |B| over time, before and after the correction: a good \
                 calibration makes it a flat line."
            }
        }
    }
}

/// The answer to one log: from the calibration, the heading comparison (its choice of
/// method) and the dead reckoning, where there is one.
pub fn verdict(
    analysis: &CalibrationAnalysis,
    heading: &HeadingReport,
    pdr: Option<&PdrReport>,
) -> Verdict {
    let read = read_line(analysis, heading);
    let method = format!("Method: {}.", heading.choice.sentence());
    let field = FieldFigures::of(analysis);
    // An autopilot log whose compasses were assessed: its first compass leads, written
    // or kept (the raw field's error would say nothing of the vehicle's heading).
    let autopilot = analysis
        .report
        .autopilot
        .as_ref()
        .and_then(|autopilot| Some((autopilot, autopilot.compasses.get(autopilot.primary)?)));
    let mut verdict = match (autopilot, &heading.choice.basis) {
        (Some((autopilot, primary)), _) => autopilot_verdict(autopilot, primary, read),
        (
            _,
            &Basis::ReferenceRms {
                rms_deg,
                raw_rms_deg,
                on_train,
            },
        ) => heading_verdict(
            heading,
            Scores {
                rms_deg,
                raw_rms_deg,
                on_train,
            },
            &field,
            (read, method),
        ),
        (_, basis) => field_only_verdict(analysis, &field, (read, method), basis),
    };
    // A vehicle does not walk: its log gets no step count.
    if let Some(pdr) = pdr.filter(|_| verdict.kind != VerdictKind::Autopilot) {
        verdict.figures.push(dead_reckoning_figure(pdr));
        let autopilot_log = analysis.report.autopilot.is_some();
        verdict.steps = (is_walk(pdr) && !autopilot_log).then(|| {
            format!(
                "{} {} dead-reckoned over {:.0} m.",
                pdr.n_steps,
                plural(pdr.n_steps, "step", "steps"),
                pdr.pdr_distance_m
            )
        });
        // A walk on a map (GNSS fixes taken, or reference positions to score it
        // against) is pictured by its track; a walk with neither keeps its answer's.
        let fixes = &pdr.fixes;
        let on_map = fixes.used + fixes.used_after_reset + fixes.down_weighted > 0
            || pdr.position_error.is_some();
        if verdict.steps.is_some() && on_map {
            verdict.picture = Picture::Track;
        }
    }
    // What is written back to the device follows one rule: where it refuses, the answer
    // says why (an autopilot's compasses say it in their own sentences).
    let refused = match (&analysis.report.autopilot, analysis.device_calibration()) {
        (None, Some(_)) => crate::analysis::calibration::selection::device_write_back(analysis)
            .err()
            .map(|refused| refused.to_string()),
        _ => None,
    };
    match (refused, field.worse_warning()) {
        (Some(why), _) => verdict
            .to_do
            .insert(0, format!("Nothing is written to the device: {why}.")),
        (None, Some(warning)) => verdict.to_do.insert(0, warning),
        (None, None) => {}
    }
    verdict
}

/// A walk's steps and distance; a log whose "steps" are metres apart is not a walk
/// (a car, a bicycle), and says so instead of giving a step count.
fn dead_reckoning_figure(pdr: &PdrReport) -> Figure {
    if !is_walk(pdr) {
        return figure(
            "Dead reckoning",
            format!(
                "not a walk: {:.1} km in {} with {} step-like {}, so no step statistics",
                pdr.pdr_distance_m / 1000.0,
                duration_text(pdr.duration_s),
                thousands(pdr.n_steps),
                plural(pdr.n_steps, "motion", "motions")
            ),
        );
    }
    figure(
        "Dead reckoning",
        format!(
            "{} {} over {:.0} m{}",
            thousands(pdr.n_steps),
            plural(pdr.n_steps, "step", "steps"),
            pdr.pdr_distance_m,
            pdr.position_error
                .as_ref()
                .map_or(String::new(), |error| format!(
                    ", {:.1} m RMS from the reference positions",
                    error.rms_m
                ))
        ),
    )
}

/// Whether the dead-reckoned log is a walk: its detected steps are at most
/// 2.5 m (`MAX_WALKING_STEP_M`) apart along the track.
pub fn is_walk(pdr: &PdrReport) -> bool {
    pdr.pdr_distance_m / pdr.n_steps.max(1) as f64 <= MAX_WALKING_STEP_M
}

/// For a log that is not a walk ([`is_walk`]), the sentence that says its step figures
/// mean nothing, for the lists of the dead reckoning (the page, the report, the CLI).
pub fn not_a_walk(pdr: &PdrReport) -> Option<String> {
    (!is_walk(pdr)).then(|| {
        format!(
            "Not a walk: the {} \"steps\" are {:.0} m apart on average (a vehicle's log), so they \
             are step-like motions, not steps, and the step figures mean nothing.",
            pdr.n_steps,
            pdr.pdr_distance_m / pdr.n_steps.max(1) as f64
        )
    })
}

/// A stride longer than this per detected step is not walking (a fast runner's step is
/// under 2 m).
const MAX_WALKING_STEP_M: f64 = 2.5;

fn read_line(analysis: &CalibrationAnalysis, heading: &HeadingReport) -> String {
    let report = &analysis.report;
    let duration_s = match (analysis.t_s.first(), analysis.t_s.last()) {
        (Some(first), Some(last)) => last - first,
        _ => 0.0,
    };
    let reference = heading
        .reference
        .as_ref()
        .map_or("no reference heading".to_string(), |source| {
            format!("reference: {}", source.label())
        });
    format!(
        "{}: {}, {} magnetometer {} over {}; {reference}.",
        report.file_name,
        report.format,
        thousands(report.n_mag_samples),
        plural(report.n_mag_samples, "sample", "samples"),
        duration_text(duration_s)
    )
}

/// The field's figures under the calibration to be exported.
struct FieldFigures {
    /// Spread of |B|, raw and corrected, percent.
    raw_spread_pct: Option<f64>,
    corrected_spread_pct: Option<f64>,
    /// The method the device calibration comes from.
    method_label: Option<&'static str>,
    /// Corrected directions: MotionCal's 100 regions.
    coverage: SphereCoverage,
    /// The fitted field in µT (when the unit is known) and the model's.
    field_ut: Option<f64>,
    expected_ut: Option<f64>,
    n_samples: usize,
}

impl FieldFigures {
    fn of(analysis: &CalibrationAnalysis) -> FieldFigures {
        let raw_spread_pct = spread_pct(analysis.mag_ut.iter().map(Vector3::norm));
        let device = analysis.device_calibration();
        let corrected: Vec<Vector3<f64>> = device
            .as_ref()
            .map(|(_, calibration)| {
                analysis
                    .mag_ut
                    .iter()
                    .map(|raw| calibration.apply(*raw))
                    .collect()
            })
            .unwrap_or_default();
        let coverage = sphere_coverage(corrected.iter().copied());
        let unit_known = analysis
            .report
            .mag_frame
            .as_ref()
            .is_none_or(|frame| frame.unit.ut_per_unit.is_some());
        FieldFigures {
            raw_spread_pct,
            corrected_spread_pct: spread_pct(corrected.iter().map(Vector3::norm)),
            method_label: device.as_ref().map(|(method, _)| method.label()),
            coverage,
            field_ut: device
                .as_ref()
                .map(|(_, calibration)| calibration.field_ut)
                .filter(|_| unit_known),
            expected_ut: analysis
                .report
                .expected_field
                .as_ref()
                .map(|expected| expected.total_ut)
                .filter(|_| unit_known),
            n_samples: analysis.mag_ut.len(),
        }
    }

    fn spread_text(&self) -> Option<String> {
        let corrected = self.corrected_spread_pct?;
        Some(match self.raw_spread_pct {
            Some(raw) => format!("{raw:.1} % → {corrected:.1} %"),
            None => format!("{corrected:.1} %"),
        })
    }

    /// When the calibration to be exported makes |B| vary more than the raw field does:
    /// a warning not to write it.
    fn worse_warning(&self) -> Option<String> {
        let (raw, corrected) = (self.raw_spread_pct?, self.corrected_spread_pct?);
        (corrected > raw).then(|| {
            format!(
                "The {} calibration makes |B| vary more than the raw field does ({raw:.1} % → {corrected:.1} %): \
                 do not write it to the device; record again turning through every orientation, away from iron.",
                self.method_label.unwrap_or("exported")
            )
        })
    }

    fn figures(&self) -> Vec<Figure> {
        let mut figures = Vec::new();
        match (self.spread_text(), self.raw_spread_pct) {
            (Some(spread), _) => figures.push(figure("|B| varies (std / mean)", spread)),
            (None, Some(raw)) => figures.push(figure(
                "|B| varies (std / mean)",
                format!("{raw:.1} % raw (no 3D calibration)"),
            )),
            (None, None) => {}
        }
        if self.method_label.is_some() {
            figures.push(figure(
                "Directions covered",
                format!(
                    "{} of 100 regions ({:.0} % of the sphere missing)",
                    self.coverage.n_covered, self.coverage.gap_pct
                ),
            ));
        }
        match (self.field_ut, self.expected_ut) {
            (Some(field), Some(expected)) => figures.push(figure(
                "Fitted field",
                format!(
                    "{field:.1} µT ({:+.0} % from the World Magnetic Model's {expected:.1} µT)",
                    100.0 * (field - expected) / expected
                ),
            )),
            (Some(field), None) => figures.push(figure(
                "Fitted field",
                format!("{field:.1} µT (no position and date for the World Magnetic Model)"),
            )),
            _ => {}
        }
        figures
    }
}

fn row_rms(stats: Option<HeadingErrorStats>) -> Option<f64> {
    stats.map(|stats| stats.rms_deg)
}

/// The chosen heading's score against the reference (from [`Basis::ReferenceRms`]).
#[derive(Debug, Clone, Copy)]
struct Scores {
    rms_deg: f64,
    raw_rms_deg: Option<f64>,
    on_train: bool,
}

fn heading_verdict(
    heading: &HeadingReport,
    scores: Scores,
    field: &FieldFigures,
    (read, method): (String, String),
) -> Verdict {
    let Scores {
        rms_deg,
        raw_rms_deg,
        on_train,
    } = scores;
    let part = if on_train {
        "on the part it was fitted to (no part was kept back)"
    } else {
        "on the part kept back to check"
    };
    let reference = heading
        .reference
        .as_ref()
        .map_or("the reference", |source| source.label());
    let headline = match raw_rms_deg {
        Some(raw) if heading.choice.key != RowKey::RAW => format!(
            "Heading error {raw:.1}° → {rms_deg:.1}° RMS with {}, against the {reference} {part}.",
            heading.choice.label
        ),
        _ => format!(
            "Heading error {rms_deg:.1}° RMS uncalibrated against the {reference} {part}; no calibration improved on it."
        ),
    };
    let chosen = heading.row(heading.choice.key);
    let mut figures = vec![figure("Heading error after", format!("{rms_deg:.1}° RMS"))];
    if let Some(raw) =
        raw_rms_deg.or_else(|| heading.row(RowKey::RAW).and_then(|row| row_rms(row.check)))
    {
        figures.insert(0, figure("Heading error before", format!("{raw:.1}° RMS")));
    }
    if let Some(stats) = chosen.and_then(|row| if on_train { row.train } else { row.check }) {
        figures.push(figure(
            "Within ±5°",
            format!("{:.0} % of the time", stats.within_5_deg_pct),
        ));
        figures.push(figure(
            "95 % of errors within",
            format!("{:.1}°", stats.p95_abs_deg),
        ));
    }
    figures.extend(field.figures());
    let grade = Grade::of_heading_rms(rms_deg);
    let mut to_do = Vec::new();
    if on_train {
        to_do.push(
            "The error was measured on the part the methods were fitted to, so it flatters them: record a longer log, \
             so that a part can be kept back to check."
                .to_string(),
        );
    }
    if grade != Grade::Good {
        to_do.push(
            "Turn through every heading, tilted too, away from iron, so that the fits see the whole circle; \
             then drop the new log."
                .to_string(),
        );
    }
    Verdict {
        kind: VerdictKind::Heading,
        grade,
        headline,
        read,
        method,
        figures,
        to_do,
        coverage: None,
        steps: None,
        picture: Picture::HeadingError,
    }
}

fn field_only_verdict(
    analysis: &CalibrationAnalysis,
    field: &FieldFigures,
    (read, method): (String, String),
    basis: &Basis,
) -> Verdict {
    let Some(corrected_spread) = field.corrected_spread_pct else {
        return Verdict {
            kind: VerdictKind::FieldOnly,
            grade: Grade::Poor,
            headline: match analysis.report.methods.iter().find_map(|method| method.error.as_deref().filter(|_| method.method == crate::analysis::calibration::Method::Ellipsoid)) {
                Some(error) => format!("No 3D calibration could be fitted: {error}"),
                None => "No 3D calibration could be fitted, and the log has no reference heading to score one against.".to_string(),
            },
            read,
            method,
            figures: field.figures(),
            to_do: analysis
                .report
                .methods
                .iter()
                .filter_map(|method| method.error.as_ref().map(|error| format!("{}: {error}", method.label)))
                .collect(),
            coverage: None,
            steps: None,
            picture: Picture::FieldMagnitude,
        };
    };
    let label = field.method_label.unwrap_or("the calibration");
    let headline = match field.raw_spread_pct {
        Some(raw) => format!(
            "|B| varies {raw:.1} % before and {corrected_spread:.1} % after the {label} calibration; {} of 100 directions covered.",
            field.coverage.n_covered
        ),
        None => format!(
            "|B| varies {corrected_spread:.1} % after the {label} calibration; {} of 100 directions covered.",
            field.coverage.n_covered
        ),
    };
    let judged = field_verdict(
        field.n_samples,
        &field.coverage,
        corrected_spread,
        field.expected_ut,
        field.field_ut.unwrap_or(f64::NAN),
    );
    let grade = if judged.good_enough {
        Grade::Good
    } else if judged.far_off {
        Grade::Poor
    } else {
        Grade::Fair
    };
    let mut figures = field.figures();
    if let Some(std_deg) = heading_std_deg(analysis) {
        figures.push(figure(
            "Heading uncertainty from the fit",
            format!("±{std_deg:.1}° (1σ)"),
        ));
    }
    let mut to_do = judged.reasons;
    to_do.push(if matches!(basis, Basis::ReferenceTooFar { .. }) {
        "To measure the heading error itself, record with a reference heading that can judge it: \
         GPS while walking or driving straight outdoors (this log's course is too far from every \
         heading, as indoors), a ref_heading_deg column, or an autopilot's attitude."
    } else {
        "To measure the heading error itself, record with a reference heading (a ref_heading_deg column, \
         GPS while walking or driving straight, or an autopilot's attitude)."
    }
    .to_string());
    Verdict {
        kind: VerdictKind::FieldOnly,
        grade,
        headline,
        read,
        method,
        figures,
        to_do,
        coverage: Some(field.coverage.clone()),
        steps: None,
        picture: Picture::Coverage,
    }
}

/// The ellipsoid fit's own heading uncertainty, when it is the calibration exported.
fn heading_std_deg(analysis: &CalibrationAnalysis) -> Option<f64> {
    use crate::analysis::calibration::{Method, MethodParameters};
    let (method, _) = analysis.device_calibration()?;
    match analysis.report.method(method)?.parameters.as_ref()? {
        MethodParameters::Ellipsoid(fit) if method == Method::Ellipsoid => {
            Some(fit.heading_std_deg)
        }
        _ => None,
    }
}

/// An autopilot log's answer: its first compass, written or kept, by the vector error
/// against the Earth's field and the heading against the autopilot's; every compass's
/// sentence as a figure.
fn autopilot_verdict(
    autopilot: &AutopilotCalibration,
    primary: &CompassResult,
    read: String,
) -> Verdict {
    let label = primary.label();
    let (before, after) = (primary.whole.in_force, primary.whole.new);
    let headline = match (&primary.kept_because, before, after) {
        (None, Some(before), Some(after)) => format!(
            "{label}: new parameters written: vector error {:.0} → {:.0} mG against the Earth's \
             field{}.",
            before.vector_rms_mg,
            after.vector_rms_mg,
            match (before.heading_rms_deg, after.heading_rms_deg) {
                (Some(b), Some(a)) => format!(", heading {b:.1}° → {a:.1}° from the autopilot's"),
                _ => String::new(),
            }
        ),
        (None, _, Some(after)) => format!("{label}: new parameters written: {}.", describe(&after)),
        (Some(_), Some(before), _) => format!(
            "{label}: parameters in force kept: {:.0} mG from the Earth's field{}.",
            before.vector_rms_mg,
            before.heading_rms_deg.map_or_else(String::new, |h| format!(
                ", {h:.1}° from the autopilot's heading"
            ))
        ),
        _ => format!("{label}: parameters in force kept."),
    };
    // The grade is of what the vehicle will fly with.
    let flown = if primary.is_written() { after } else { before };
    let grade = flown
        .and_then(|score| score.heading_rms_deg)
        .map_or(Grade::Fair, Grade::of_heading_rms);
    let figures = autopilot
        .compasses
        .iter()
        .map(|compass| Figure {
            label: compass.label(),
            value: compass
                .sentence
                .strip_prefix(&format!("{}: ", compass.label()))
                .map_or_else(|| compass.sentence.clone(), str::to_string),
        })
        .collect();
    let written: Vec<String> = autopilot.written().map(CompassResult::label).collect();
    // Short, for a phone's first screen: the details list says the rest.
    let method = format!(
        "Method: fitted on the log's first half against {} through the autopilot's attitude; \
         written only where better than the {} parameters in force on the second half and \
         within the autopilot's limits: {}.",
        autopilot.earth.short(),
        autopilot.autopilot,
        if written.is_empty() {
            "none here".to_string()
        } else {
            crate::base::words::list(&written)
        }
    );
    // What to record, once, for the compasses the log could not calibrate.
    let to_record: Vec<String> = autopilot
        .compasses
        .iter()
        .filter(|compass| {
            compass
                .kept_because
                .as_deref()
                .is_some_and(|why| why.contains("Record a flight"))
        })
        .map(CompassResult::label)
        .collect();
    let mut to_do = autopilot.notes.clone();
    if !to_record.is_empty() {
        to_do.insert(
            0,
            format!(
                "To calibrate {}: record a flight (or a walk with the vehicle in hand) that turns \
                 through full circles with some tilt, for a minute or more.",
                to_record.join(" and ")
            ),
        );
    }
    Verdict {
        kind: VerdictKind::Autopilot,
        grade,
        headline,
        read,
        method,
        figures,
        to_do,
        coverage: None,
        steps: None,
        picture: Picture::CompassErrors,
    }
}
