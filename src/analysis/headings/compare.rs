//! The comparison of every heading method on one train/check split: each base heading
//! (uncalibrated, an autopilot's with its parameters in force, each field-domain
//! calibration, and the attitude filter's, row `ahrs`) alone, with the PDR paper's
//! Fourier model (Eq. 12) on top, with the 2007 paper's network on top (on the raw
//! heading and on the best-fitting calibration), the online adaptation of the featured
//! Fourier model, and the one choice of "best" by
//! [`crate::analysis::calibration::selection`]'s rule.

use crate::analysis::calibration::row_key::{OnTop, RowKey};
use crate::analysis::calibration::selection::{choose_by_reference, settle, Choice, Scored};
use crate::analysis::calibration::{CalibrationAnalysis, CalibrationReport};
use crate::base::stats::HeadingErrorStats;

use crate::analysis::headings::{
    featured, steady_mean, train_bins, FourierReport, HeadingAnalysis, HeadingOptions,
    HeadingReport, HeadingRow, OnlineReport, ONLINE_SNAPSHOT_SPACING_S, ONLINE_UPDATE_SPACING_S,
};
use crate::deviation::fourier::{self, fit_fourier};
use crate::deviation::neural;
use crate::deviation::rls::adapt_online;

/// A base heading: raw or one field-domain method, in radians per sample, with its
/// degrees and its scores as the calibration gave them (on the same split).
struct Base<'a> {
    key: RowKey,
    label: String,
    heading_rad: Vec<f64>,
    heading_deg: &'a [f64],
    scores: Scores,
}

/// A row's statistics on the train part and on the check part.
type Scores = (Option<HeadingErrorStats>, Option<HeadingErrorStats>);

/// What every row is scored on: the reference at each sample, and the analysis's one
/// train/check split ([`Split`](crate::analysis::calibration::Split)).
struct Scoring<'a> {
    reference_rad: Vec<Option<f64>>,
    is_train: &'a [bool],
}

impl<'a> Scoring<'a> {
    fn of(calibration: &'a CalibrationAnalysis) -> Scoring<'a> {
        Scoring {
            reference_rad: calibration
                .ref_heading_deg
                .iter()
                .map(|reference| reference.map(f64::to_radians))
                .collect(),
            is_train: &calibration.split.is_train,
        }
    }

    /// Samples with a reference on the train part (`true`) or the check part.
    fn n_referenced(&self, want_train: bool) -> usize {
        self.reference_rad
            .iter()
            .zip(self.is_train)
            .filter(|(reference, &train)| reference.is_some() && train == want_train)
            .count()
    }

    /// The heading error statistics on the train part and on the check part.
    fn both_stats(
        &self,
        headings_rad: &[f64],
    ) -> (Option<HeadingErrorStats>, Option<HeadingErrorStats>) {
        HeadingErrorStats::on_both_parts(headings_rad, &self.reference_rad, self.is_train)
    }
}

/// The rows of the comparison, each scored row's heading per sample, and the notes.
#[derive(Default)]
struct Table {
    rows: Vec<HeadingRow>,
    series: Vec<(RowKey, Vec<f64>)>,
    notes: Vec<String>,
}

impl Table {
    fn push_scored(&mut self, key: RowKey, label: String, headings_rad: &[f64], scoring: &Scoring) {
        self.push_row(
            key,
            label,
            scoring.both_stats(headings_rad),
            to_degrees(headings_rad),
        );
    }

    fn push_row(
        &mut self,
        key: RowKey,
        label: String,
        (train, check): Scores,
        series_deg: Vec<f64>,
    ) {
        self.rows.push(HeadingRow {
            key,
            label,
            train,
            check,
            error: None,
        });
        self.series.push((key, series_deg));
    }

    fn push_error(&mut self, key: RowKey, label: String, error: String) {
        self.rows.push(HeadingRow {
            key,
            label,
            train: None,
            check: None,
            error: Some(error),
        });
    }
}

/// Learns the deviation models on every base heading of a calibration analysis and
/// compares everything on its split ([`crate::pipeline::headings`] runs the calibration
/// then this, and writes the choice back into the calibration's report).
pub fn compare(calibration: &CalibrationAnalysis, options: &HeadingOptions) -> HeadingAnalysis {
    let calibration_report = calibration.report.clone();
    let scoring = Scoring::of(calibration);
    let bases = bases_of(calibration, &scoring);
    let mut table = Table::default();
    // The bases as the calibration scored them (its split is this one).
    for base in &bases {
        table.push_row(
            base.key,
            base.label.clone(),
            base.scores,
            base.heading_deg.to_vec(),
        );
    }
    // Field-domain methods that could not be fitted are listed with their reason.
    for method_report in &calibration_report.methods {
        if let Some(error) = &method_report.error {
            let (key, label) = (RowKey::method(method_report.method), method_report.label);
            table.push_error(key, label.to_string(), error.clone());
        }
    }
    let bins = train_bins(
        &calibration.t_s,
        scoring.is_train,
        &scoring.reference_rad,
        &calibration.gyro_heading_deg,
    );
    let fourier_reports = fourier_stacks(&bases, &bins, &scoring, &mut table);
    let neural_reports = if options.neural {
        neural_stacks(calibration, &bases, &bins, &scoring, &mut table)
    } else {
        Vec::new()
    };
    let online = online_adaptation(
        &calibration.t_s,
        &bases,
        &fourier_reports,
        &scoring,
        options,
    );
    let choice = choose(&table.rows, &calibration_report);
    if calibration_report.reference.is_none() {
        table.notes.push(
            "the log has no reference heading (a reference column, GPS course, reference positions, or a closed \
             loop for the gyro), so no deviation model could be learned"
                .to_string(),
        );
    }
    HeadingAnalysis {
        report: HeadingReport {
            file_name: calibration_report.file_name.clone(),
            reference: calibration_report.reference,
            reference_description: calibration_report.reference.map(|source| source.describe()),
            train_until_s: calibration_report.train_until_s,
            n_train_referenced: scoring.n_referenced(true),
            n_check_referenced: scoring.n_referenced(false),
            rows: table.rows,
            fourier: fourier_reports,
            neural: neural_reports,
            online,
            choice,
            notes: table.notes,
            calibration: calibration_report,
        },
        t_s: calibration.t_s.clone(),
        reference_deg: calibration.ref_heading_deg.clone(),
        headings_deg: table.series,
    }
}

/// The uncalibrated heading, an autopilot's with its calibration in force, each fitted
/// field-domain method's, then the attitude filter's (the last two scored here: the
/// calibration does not score them).
fn bases_of<'a>(calibration: &'a CalibrationAnalysis, scoring: &Scoring) -> Vec<Base<'a>> {
    let radians = |headings_deg: &[f64]| headings_deg.iter().map(|deg| deg.to_radians()).collect();
    let report = &calibration.report;
    let mut bases = vec![Base {
        key: RowKey::RAW,
        label: "uncalibrated".to_string(),
        heading_rad: radians(&calibration.raw_heading_deg),
        heading_deg: &calibration.raw_heading_deg,
        scores: (
            report.raw_heading_error_train,
            report.raw_heading_error_check,
        ),
    }];
    // A base the calibration does not score, scored here on the same split.
    let scored_here = |key: RowKey, label: String, heading_deg: &'a [f64]| {
        let heading_rad: Vec<f64> = radians(heading_deg);
        let scores = scoring.both_stats(&heading_rad);
        Base {
            key,
            label,
            heading_rad,
            heading_deg,
            scores,
        }
    };
    if let Some((autopilot, headings_deg)) = &calibration.in_force_heading_deg {
        let label = format!("{autopilot}'s parameters in force");
        bases.push(scored_here(RowKey::IN_FORCE, label, headings_deg));
    }
    for (method, headings_deg) in &calibration.headings_deg {
        let scores = report.method(*method).map_or((None, None), |method| {
            (method.heading_error_train, method.heading_error_check)
        });
        bases.push(Base {
            key: RowKey::method(*method),
            label: method.label().to_string(),
            heading_rad: radians(headings_deg),
            heading_deg: headings_deg,
            scores,
        });
    }
    if let Some(attitude) = &calibration.attitude_heading {
        let label = "attitude filter (gyro + acc + field)".to_string();
        bases.push(scored_here(RowKey::ATTITUDE, label, &attitude.heading_deg));
    }
    bases
}

/// A Fourier model (Eq. 12) on each base, trained on the train part's steady bins.
fn fourier_stacks(
    bases: &[Base],
    bins: &[Vec<usize>],
    scoring: &Scoring,
    table: &mut Table,
) -> Vec<FourierReport> {
    let reference_values: Vec<f64> = scoring
        .reference_rad
        .iter()
        .map(|reference| reference.unwrap_or(f64::NAN))
        .collect();
    // The reference's mean over each bin, the same for every base.
    let reference_means: Vec<Option<f64>> = bins
        .iter()
        .map(|bin| steady_mean(&reference_values, bin))
        .collect();
    let mut reports = Vec::new();
    for base in bases {
        let key = base.key.with(OnTop::Fourier);
        let label = if base.key == RowKey::RAW {
            "Fourier deviation model (Eq. 12)".to_string()
        } else {
            format!("{} + Fourier", base.label)
        };
        let (raw, reference): (Vec<f64>, Vec<f64>) = bins
            .iter()
            .zip(&reference_means)
            .filter_map(|(bin, &reference)| {
                Some((steady_mean(&base.heading_rad, bin)?, reference?))
            })
            .unzip();
        match fit_fourier(&raw, &reference) {
            Ok(fit) => {
                let corrected = crate::base::par::map(&base.heading_rad, |_, &heading| {
                    fit.model.correct_rad(heading)
                });
                table.push_scored(key, label, &corrected, scoring);
                if fit.terms != fourier::FourierTerms::Full {
                    table.notes.push(format!(
                        "{}: the train headings cover too little of the circle for all five terms, so only {} were \
                         fitted; turn through every heading while the reference is good",
                        base.label,
                        match fit.terms {
                            fourier::FourierTerms::FirstHarmonic => "A, B and C",
                            _ => "the constant A",
                        }
                    ));
                }
                reports.push(FourierReport {
                    base_key: base.key,
                    base_label: base.label.clone(),
                    fit,
                });
            }
            Err(error) => table.push_error(key, label, error.to_string()),
        }
    }
    if !reports.is_empty() {
        table.notes.push(
            "the Fourier model's constant A absorbs the misalignment between the device and the direction of travel \
             (β), the declination (λ) and any constant offset of the reference, so A is not a calibration of the \
             sensor alone"
                .to_string(),
        );
    }
    reports
}

/// The neural network on the raw heading (the paper's) and on the field-domain method
/// that fits its train part best.
fn neural_stacks(
    calibration: &CalibrationAnalysis,
    bases: &[Base],
    bins: &[Vec<usize>],
    scoring: &Scoring,
    table: &mut Table,
) -> Vec<neural::NeuralReport> {
    let horizontal_ut: Vec<f64> = calibration
        .level_raw_ut
        .iter()
        .map(nalgebra::Matrix::norm)
        .collect();
    let dip_deg: Vec<f64> = horizontal_ut
        .iter()
        .zip(&calibration.field_raw_ut)
        .map(|(&horizontal, &total)| {
            (horizontal / total.max(f64::MIN_POSITIVE))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        })
        .collect();
    // The paper's "gyro heading" is the gyroscope's heading; the attitude filter's is
    // that heading with its drift held by gravity and the field (issue 18), so it is the
    // input where the log has one, else the gyroscope integrated from its start.
    let filter_heading_deg: Option<Vec<Option<f64>>> =
        calibration.attitude_heading.as_ref().map(|attitude| {
            attitude
                .heading_deg
                .iter()
                .map(|&deg| deg.is_finite().then_some(deg))
                .collect()
        });
    let (gyro_heading_deg, gyro_heading_source) = match &filter_heading_deg {
        Some(headings) => (
            headings.as_slice(),
            neural::GyroHeadingSource::AttitudeFilter,
        ),
        None => (
            calibration.gyro_heading_deg.as_slice(),
            neural::GyroHeadingSource::IntegratedGyroscope,
        ),
    };
    let conditions = neural::Conditions {
        horizontal_ut: &horizontal_ut,
        dip_deg: &dip_deg,
        gyro_heading_deg,
        gyro_heading_source,
        temp_c: &calibration.temp_c,
    };
    let best_field_base = bases
        .iter()
        .skip(1)
        .filter(|base| base.key != RowKey::ATTITUDE)
        .filter_map(|base| Some((base, base.scores.0?.rms_deg)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(base, _)| base);
    let mut reports = Vec::new();
    for base in bases.iter().take(1).chain(best_field_base) {
        let key = base.key.with(OnTop::Network);
        let label = if base.key == RowKey::RAW {
            "MLP (the 2007 paper's inputs)".to_string()
        } else {
            format!("{} + MLP", base.label)
        };
        let trained = neural::train_correction(
            &base.key.text(),
            &base.label,
            &base.heading_rad,
            &scoring.reference_rad,
            &conditions,
            bins,
            1,
        );
        match trained {
            Ok(correction) => {
                let corrected = correction.correct_all_rad(&base.heading_rad, &conditions);
                table.push_scored(key, label, &corrected, scoring);
                if !correction.report.missing_inputs.is_empty() {
                    table.notes.push(format!(
                        "{}: the log has no {}, so the network learned from {}",
                        base.label,
                        correction.report.missing_inputs.join(" and "),
                        correction.report.inputs.join(", ")
                    ));
                }
                reports.push(correction.report);
            }
            Err(reason) => table.push_error(key, label, reason.to_string()),
        }
    }
    reports
}

/// Online adaptation over every referenced sample in time order, on the base whose
/// batch model is featured (the raw heading when nothing was fitted).
fn online_adaptation(
    t_s: &[f64],
    bases: &[Base],
    fourier_reports: &[FourierReport],
    scoring: &Scoring,
    options: &HeadingOptions,
) -> Option<OnlineReport> {
    let base = featured(fourier_reports)
        .and_then(|report| bases.iter().find(|base| base.key == report.base_key))
        .or(bases.first())?;
    let forgetting = (-ONLINE_UPDATE_SPACING_S / options.online_memory_s.max(1.0)).exp();
    let mut last_t_s = f64::NEG_INFINITY;
    let samples: Vec<(f64, f64, f64)> = t_s
        .iter()
        .zip(&base.heading_rad)
        .zip(&scoring.reference_rad)
        .filter_map(|((&t_s, &raw_rad), &reference_rad)| {
            let reference_rad = reference_rad?;
            (t_s - last_t_s >= ONLINE_UPDATE_SPACING_S).then(|| {
                last_t_s = t_s;
                (t_s, raw_rad, reference_rad)
            })
        })
        .collect();
    if samples.len() < 10 {
        return None;
    }
    let n_updates = samples.len();
    let (model, snapshots) = adapt_online(samples, forgetting, ONLINE_SNAPSHOT_SPACING_S);
    Some(OnlineReport {
        base_key: base.key,
        base_label: base.label.clone(),
        memory_s: options.online_memory_s,
        forgetting_per_update: forgetting,
        n_updates,
        model,
        snapshots,
    })
}

/// The one rule of `selection`: the lowest check RMS, never worse than uncalibrated;
/// without a reference, the field calibration the fits' own figures recommend.
fn choose(rows: &[HeadingRow], calibration_report: &CalibrationReport) -> Choice {
    let scored: Vec<Scored> = rows
        .iter()
        .map(|row| Scored {
            key: row.key,
            label: &row.label,
            train_rms_deg: row.train.map(|stats| stats.rms_deg),
            check_rms_deg: row.check.map(|stats| stats.rms_deg),
        })
        .collect();
    settle(choose_by_reference(&scored), calibration_report)
}

fn to_degrees(headings_rad: &[f64]) -> Vec<f64> {
    headings_rad.iter().map(|rad| rad.to_degrees()).collect()
}
