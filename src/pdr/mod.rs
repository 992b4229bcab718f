//! Pedestrian dead reckoning: steps, step lengths, headings and the EKF that bridges
//! GNSS outages (Chen et al., *A unified heading error model and step length
//! estimation for PDR*, Sections III, V and VI; Fig. 2).
//!
//! ## Layout
//!
//! - `steps.rs`: step detection (sliding window, zero crossing and peak detection on
//!   `|f|`) with SF, SV, Amax and Amin per step.
//! - `step_length.rs`: the linear (Eq. 2), Weinberg (Eq. 3) and neural step-length
//!   models, fitted to per-step references or to a known distance.
//! - `ekf.rs`: the `[E, N, l, a]` filter of Eq. 13 with GNSS position updates ("how to
//!   fuse").
//! - `fusion.rs`: GNSS/PDR switching: outages, accuracy and χ² gates, recovery ("when
//!   to fuse").
//! - `metrics.rs`: the paper's accuracy figures (Tables I, III, IV) and loop closure.
//! - this file: [`run`], the pipeline from an imported recording to a [`PdrAnalysis`].
//!
//! ## The pipeline
//!
//! 1. GNSS fixes inside the outages are set aside; the heading models of
//!    [`crate::deviation`] then train on the GNSS course that is left (Fig. 2: "the
//!    speed and heading from GPS are utilized to train the step length model and
//!    calibrate the compass"), never on a reference-heading column, which in a test log
//!    is the truth.
//! 2. Steps are detected; each gets the heading of the chosen model (circular mean over
//!    the step) and a length from the step model.
//! 3. The step model trains on, in this order: a known distance (a loop of known
//!    length); the reference positions, when asked to; the GNSS speed over each step
//!    while GNSS is good; the distance between GNSS fixes on straight stretches (logs
//!    without speed); else a K given from an earlier walk, else Weinberg's default.
//! 4. One filter runs through the steps and the admissible fixes.
//! 5. Reference positions (a truth track, surveyed waypoints) score the track; a
//!    reference-heading column scores the headings.

pub mod ekf;
pub mod export;
pub mod fusion;
pub mod metrics;
pub mod step_length;
pub mod steps;

use serde::Serialize;

use crate::analysis::AnalysisError;
use crate::calibration::{calibrate, CalibrationOptions, Method};
use crate::deviation::{compare, HeadingOptions};
use crate::geo::{Geodetic, LocalFrame};
use crate::io::ImportReport;
use crate::recording::{Recording, Stream};
use crate::reference::gyro::gyro_heading;
use crate::reference::{ReferenceChoice, ReferenceOptions};

use ekf::EkfNoise;
use fusion::{fuse, FixInput, FixUse, GnssPolicy, Outage, StepInput, TrackPoint};
use metrics::{LoopClosure, MeanStd, PositionErrors};
use step_length::{SegmentReference, StepLengthModel, StepModelKind, StepReference};
use steps::{detect_steps, Step, StepOptions};

/// Where each step's heading comes from: a base heading, optionally carried by the gyro.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeadingChoice {
    pub base: HeadingBase,
    /// The integrated gyro, aligned (offset and drift) to the base heading over the whole
    /// walk: smooth and turn-true like a gyro, absolute like the base.
    pub gyro_aligned: bool,
}

/// The absolute heading a walk's steps take.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "key")]
pub enum HeadingBase {
    /// The heading model with the lowest check error against GNSS course (field-domain
    /// calibrations and Fourier models; the networks only when asked for by key), else
    /// the best field-domain calibration.
    Auto,
    /// A row of the heading comparison by key (`ellipse`, `ellipse+fourier`, `mlp`, ...).
    Model(String),
    /// The device's own fused yaw (Android's rotation vector, a compass module's HPR),
    /// magnetic, turned to true north by the declination.
    Device,
}

impl HeadingChoice {
    pub const AUTO: HeadingChoice = HeadingChoice {
        base: HeadingBase::Auto,
        gyro_aligned: false,
    };

    /// `auto`, a model key, `device`, or any of them after `gyro+` (`gyro` alone is
    /// `gyro+auto`).
    pub fn parse(text: &str) -> HeadingChoice {
        let text = text.trim();
        let (gyro_aligned, base) = match text.strip_prefix("gyro") {
            Some("") => (true, "auto"),
            Some(rest) if rest.starts_with('+') || rest.starts_with('-') => (true, &rest[1..]),
            _ => (false, text),
        };
        let base = match base {
            "auto" | "compass" => HeadingBase::Auto,
            "device" => HeadingBase::Device,
            key => HeadingBase::Model(key.replace('-', "+")),
        };
        HeadingChoice { base, gyro_aligned }
    }
}

/// Everything that changes the result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PdrOptions {
    pub steps: StepOptions,
    pub step_model: StepModelKind,
    pub heading: HeadingChoice,
    /// The heading comparison (declination, position, methods). Its reference choice is
    /// replaced by GNSS course.
    pub heading_options: HeadingOptions,
    /// A distance the walk is known to cover (m): fits Weinberg's K.
    pub known_distance_m: Option<f64>,
    /// Weinberg's K from an earlier walk (`compass-pdr pdr` prints the K it fitted), used
    /// when nothing in this log trains the step model.
    pub weinberg_k: Option<f64>,
    /// Train the step model on the log's reference positions (the distance between
    /// consecutive ones on straight stretches). Off by default: the reference positions
    /// then only score the track.
    pub train_on_reference_positions: bool,
    /// The walk ends where it started: report the loop-closure error.
    pub closed_loop: bool,
    pub gnss: GnssPolicy,
    pub noise: EkfNoise,
    /// The network's initial weights.
    pub seed: u64,
}

impl Default for PdrOptions {
    fn default() -> Self {
        PdrOptions {
            steps: StepOptions::default(),
            step_model: StepModelKind::Weinberg,
            heading: HeadingChoice::AUTO,
            heading_options: HeadingOptions::default(),
            known_distance_m: None,
            weinberg_k: None,
            train_on_reference_positions: false,
            closed_loop: false,
            gnss: GnssPolicy::default(),
            noise: EkfNoise::default(),
            seed: 1,
        }
    }
}

/// How the step model was trained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepModelReport {
    pub requested: StepModelKind,
    pub model: StepLengthModel,
    /// `known_distance`, `reference_positions`, `gnss_speed`, `gnss_positions`,
    /// `given_k` or `default`.
    pub trained_on: &'static str,
    pub n_references: usize,
    /// RMS of the model against its own references (m).
    pub train_rms_m: Option<f64>,
}

impl StepModelReport {
    /// The model and how it was trained, in words (`Weinberg, SL = 0.481·(Amax −
    /// Amin)^¼, fitted to the known distance`), as the CLI and the page show it.
    pub fn describe(&self) -> String {
        let model = match &self.model {
            StepLengthModel::Linear {
                a_m,
                b_m_per_hz,
                c_m_per_var,
            } => format!("linear, SL = {a_m:.3} + {b_m_per_hz:.3}·SF + {c_m_per_var:.4}·SV"),
            StepLengthModel::Weinberg { k } => format!("Weinberg, SL = {k:.4}·(Amax − Amin)^¼"),
            StepLengthModel::Neural { .. } => "neural network, 16 tanh neurons".to_string(),
        };
        let n = self.n_references;
        let rms = self
            .train_rms_m
            .map_or(String::new(), |rms| format!(", RMS {rms:.3} m"));
        let trained = match self.trained_on {
            "known_distance" => "fitted to the known distance".to_string(),
            "reference_positions" => {
                format!("trained on {n} straight stretches between reference positions{rms}")
            }
            "gnss_speed" => format!("trained on the GNSS speed of {n} steps{rms}"),
            "gnss_positions" => {
                format!("trained on {n} straight stretches between GNSS fixes{rms}")
            }
            "given_k" => "K given from an earlier walk".to_string(),
            _ => "not trained (no usable GNSS and no known distance: the default K)".to_string(),
        };
        format!("{model}, {trained}")
    }
}

/// What became of the GNSS fixes.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct FixCounts {
    pub used: usize,
    pub used_after_reset: usize,
    pub in_outage: usize,
    pub poor_accuracy: usize,
    pub rejected: usize,
    /// Before the first step or after the last.
    pub outside_walk: usize,
}

impl FixCounts {
    /// "N used, … rejected by the gate", or `None` when the log had no fix to judge.
    pub fn describe(&self) -> Option<String> {
        (self.used + self.used_after_reset + self.in_outage + self.poor_accuracy + self.rejected > 0)
            .then(|| {
                format!(
                    "{} used, {} after a reset, {} in outages, {} too inaccurate, {} rejected by the gate",
                    self.used, self.used_after_reset, self.in_outage, self.poor_accuracy, self.rejected
                )
            })
    }
}

/// What `compass-pdr pdr --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PdrReport {
    pub file_name: String,
    pub n_steps: usize,
    pub n_bouts: usize,
    pub mean_step_frequency_hz: Option<f64>,
    pub pdr_distance_m: f64,
    pub duration_s: f64,
    pub step_model: StepModelReport,
    /// The heading used: its key and label, and the heading comparison's best row.
    pub heading_key: String,
    pub heading_label: String,
    pub frame_origin_lat_lon_deg: Option<[f64; 2]>,
    pub outages: Vec<Outage>,
    pub fixes: FixCounts,
    /// Against reference positions over the whole walk, and over each outage.
    pub position_error: Option<PositionErrors>,
    pub outage_position_errors: Vec<PositionErrors>,
    /// Spans of the walk in which the log itself has no GNSS fix (a tunnel, a roof):
    /// what the dead reckoning bridged, with its error there where there is a reference.
    pub gnss_gaps: Vec<GnssGap>,
    /// Model step length minus the reference step length (m).
    pub step_length_error_m: Option<MeanStd>,
    /// Filtered step heading minus the reference heading (deg).
    pub heading_error_deg: Option<MeanStd>,
    pub loop_closure: Option<LoopClosure>,
    pub notes: Vec<String>,
}

/// A span of the walk without any GNSS fix in the log, longer than
/// `min_gap_s` of its fix interval: the dead reckoning alone carried the track.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GnssGap {
    /// The last fix before and the first after (or the walk's end).
    pub start_s: f64,
    pub end_s: f64,
    /// The track's length across the gap.
    pub pdr_distance_m: f64,
    /// Against the reference positions, where the log has them.
    pub position_error: Option<PositionErrors>,
}

/// The shortest span without fixes that counts as a gap: five fix intervals (the
/// median interval of the log's fixes), and at least 5 s.
fn min_gap_s(fix_times_s: &[f64]) -> f64 {
    let mut intervals: Vec<f64> = fix_times_s
        .windows(2)
        .filter_map(|pair| match pair {
            [before, after] if after > before => Some(after - before),
            _ => None,
        })
        .collect();
    intervals.sort_by(f64::total_cmp);
    let median = intervals.get(intervals.len() / 2).copied().unwrap_or(1.0);
    (5.0 * median).max(5.0)
}

/// The gaps between the log's fixes (sorted times) within the walk.
fn gnss_gaps(
    fix_times_s: &[f64],
    walk_start_s: f64,
    walk_end_s: f64,
    track: &[TrackPoint],
    reference_en_m: &[(f64, [f64; 2])],
) -> Vec<GnssGap> {
    if fix_times_s.is_empty() {
        return Vec::new();
    }
    let min_gap_s = min_gap_s(fix_times_s);
    let inside: Vec<f64> = fix_times_s
        .iter()
        .copied()
        .filter(|t_s| (walk_start_s..=walk_end_s).contains(t_s))
        .collect();
    let bounds = std::iter::once(walk_start_s)
        .chain(inside.iter().copied())
        .chain(std::iter::once(walk_end_s));
    let bounds: Vec<f64> = bounds.collect();
    bounds
        .windows(2)
        .filter_map(|pair| match pair {
            [start_s, end_s] if end_s - start_s > min_gap_s => Some((*start_s, *end_s)),
            _ => None,
        })
        .map(|(start_s, end_s)| GnssGap {
            start_s,
            end_s,
            pdr_distance_m: metrics::track_distance_m(track, start_s, end_s),
            position_error: metrics::position_errors(track, reference_en_m, start_s, end_s),
        })
        .collect()
}

/// The report with the series the plots and exports draw.
#[derive(Debug, Clone, PartialEq)]
pub struct PdrAnalysis {
    pub report: PdrReport,
    pub steps: Vec<Step>,
    /// The model's length and the chosen heading of each step.
    pub step_lengths_m: Vec<f64>,
    pub step_headings_rad: Vec<f64>,
    /// The reference length of each step, where there is one.
    pub step_references_m: Vec<Option<f64>>,
    pub track: Vec<TrackPoint>,
    /// GNSS fixes in the local frame and what became of each.
    pub fixes: Vec<(FixInput, FixUse)>,
    /// Reference positions in the local frame.
    pub reference_en_m: Vec<(f64, [f64; 2])>,
    pub frame: Option<LocalFrame>,
}

/// Why PDR could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PdrError {
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    #[error("{file_name} has no accelerometer samples, so no steps can be detected. PDR needs acc_x_mps2, acc_y_mps2, acc_z_mps2 (or the format's accelerometer).")]
    NoAccelerometer { file_name: String },
    #[error("{file_name}: no steps were detected in {duration_s:.0} s of accelerometer data. Check that the log is of walking, sampled at 25 Hz or more.")]
    NoSteps { file_name: String, duration_s: f64 },
}

/// Dead-reckons an imported recording.
pub fn run(report: ImportReport, options: &PdrOptions) -> Result<PdrAnalysis, PdrError> {
    let file_name = report.file_name.clone();
    let recording = report.recording.clone();
    let acc = &recording.acc_in_body_mps2;
    if acc.is_empty() {
        return Err(PdrError::NoAccelerometer { file_name });
    }
    let mut notes = Vec::new();

    // 1. Headings, trained on the GNSS course outside the outages.
    let mut for_headings = report;
    for_headings.recording.gnss = without_outages(&recording.gnss, &options.gnss.outages);
    let heading_options = HeadingOptions {
        calibration: CalibrationOptions {
            reference: ReferenceOptions {
                choice: ReferenceChoice::Gps,
                ..options.heading_options.calibration.reference
            },
            ..options.heading_options.calibration.clone()
        },
        // The networks train only when one is asked for: they would dominate the time
        // of the whole pipeline.
        neural: matches!(&options.heading.base, HeadingBase::Model(key) if key.contains("mlp")),
        ..options.heading_options.clone()
    };
    let refit_report = for_headings.clone();
    let calibration = calibrate(for_headings, &heading_options.calibration)?;
    let selection = compare(&calibration, &heading_options);
    let has_reference = selection.report.reference.is_some();
    let compass_key = match (&options.heading.base, &selection.report.best) {
        (HeadingBase::Model(key), _) => key.clone(),
        (_, Some(best)) if has_reference => best.clone(),
        _ => crate::selection::choose_without_reference(&selection.report.calibration).key,
    };
    // The split chose the model; the dead reckoning uses it trained on every sample
    // GNSS referenced (Fig. 2: the model trains while GNSS is good).
    // Only the chosen model's field-domain method is fitted again (with the 3D fits a
    // reference least squares over a few headings stands on).
    let base_method = Method::ALL
        .into_iter()
        .find(|method| compass_key.split('+').next() == Some(method.key()));
    let methods = match base_method.unwrap_or(Method::MinMax) {
        Method::RefLs => vec![Method::Ellipse, Method::Ellipsoid, Method::RefLs],
        method => vec![method],
    };
    let headings = if has_reference && heading_options.calibration.train_until_s.is_none() {
        let everything = HeadingOptions {
            calibration: CalibrationOptions {
                train_until_s: Some(f64::INFINITY),
                methods,
                ..heading_options.calibration.clone()
            },
            ..heading_options.clone()
        };
        match calibrate(refit_report, &everything.calibration) {
            Ok(refit) => compare(&refit, &everything),
            // The split's own fit stands when every sample together does not fit.
            Err(error) => {
                notes.push(format!(
                    "The heading model was not refitted on every GNSS-referenced sample ({error}); the one fitted \
                     on the train part was used."
                ));
                selection
            }
        }
    } else {
        selection
    };
    let compass_series = headings
        .headings_deg
        .iter()
        .find(|(key, _)| *key == compass_key)
        .or_else(|| headings.headings_deg.iter().find(|(key, _)| key == "raw"));
    let Some((compass_key, compass_deg)) = compass_series else {
        return Err(PdrError::NoSteps {
            file_name,
            duration_s: acc.duration_s(),
        });
    };
    if let HeadingBase::Model(requested) = &options.heading.base {
        if requested != compass_key {
            notes.push(format!("There is no heading model '{requested}' for this log; the {compass_key} heading was used. The models are: {}.", model_keys(&headings.headings_deg)));
        }
    }
    let compass = Stream {
        t_s: headings.t_s.clone(),
        values: compass_deg.iter().map(|deg| deg.to_radians()).collect(),
    };
    let compass_label = label_of(&headings.report, compass_key);
    let (base_stream, base_key, base_label) = match options.heading.base {
        HeadingBase::Device => {
            let declination_rad = headings
                .report
                .calibration
                .declination
                .declination_deg
                .to_radians();
            let mut device = Stream::default();
            for (&t_s, attitude) in recording
                .attitude
                .t_s
                .iter()
                .zip(&recording.attitude.values)
            {
                if let Some(yaw_rad) = attitude.yaw_rad.filter(|yaw| yaw.is_finite()) {
                    device.push(t_s, crate::angle::wrap_to_2pi(yaw_rad + declination_rad));
                }
            }
            if device.is_empty() {
                notes.push(
                    "The log has no device yaw (rotation vector): the compass heading was used."
                        .to_string(),
                );
                (compass, compass_key.clone(), compass_label)
            } else {
                (
                    device,
                    "device".to_string(),
                    "the device's own yaw (rotation vector) with the declination".to_string(),
                )
            }
        }
        _ => (compass, compass_key.clone(), compass_label),
    };
    let gyro = options
        .heading
        .gyro_aligned
        .then(|| {
            gyro_heading(
                &recording,
                heading_options.calibration.gravity_window_s,
                Some(&base_stream),
                false,
            )
        })
        .flatten();
    if options.heading.gyro_aligned && gyro.is_none() {
        notes.push(format!(
            "The log has no gyroscope: the {base_key} heading was used without it."
        ));
    }
    let (heading_stream, heading_key, heading_label) = match gyro {
        Some(gyro) => (
            gyro.heading_rad,
            format!("gyro+{base_key}"),
            format!("the gyro aligned to {base_label}"),
        ),
        None => (base_stream, base_key, base_label),
    };

    // 2. Steps and their headings.
    let detection = detect_steps(acc, &options.steps);
    notes.extend(detection.notes.iter().cloned());
    let steps = detection.steps.clone();
    if steps.is_empty() {
        return Err(PdrError::NoSteps {
            file_name,
            duration_s: acc.duration_s(),
        });
    }
    let step_headings_rad: Vec<f64> = steps
        .iter()
        .map(|step| mean_heading(&heading_stream, step.t_start_s, step.t_end_s))
        .collect();
    let n_without_heading = step_headings_rad.iter().filter(|h| !h.is_finite()).count();
    if n_without_heading > 0 {
        notes.push(format!("{n_without_heading} steps had no heading sample within a second and kept the previous step's heading."));
    }
    let step_headings_rad = fill_forward(step_headings_rad);

    // 3. The local frame, the fixes and the reference positions.
    let frame = first_good_fix(&recording, &options.gnss).map(LocalFrame::at);
    let fixes: Vec<FixInput> = frame
        .map(|frame| {
            recording
                .gnss
                .t_s
                .iter()
                .zip(&recording.gnss.values)
                .filter_map(|(&t_s, fix)| {
                    let en = frame.en_of(fix.lat_deg?, fix.lon_deg?);
                    Some(FixInput {
                        t_s,
                        en_m: [en.x, en.y],
                        hacc_m: fix.hacc_m,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    let reference_en_m = reference_positions(
        &recording,
        frame.as_ref(),
        &fixes,
        &options.gnss,
        &mut notes,
    );

    // 4. Step lengths.
    let gnss_references = gnss_step_references(&recording, &steps, &options.gnss);
    let admissible_fixes: Vec<(f64, [f64; 2])> = fixes
        .iter()
        .filter(|fix| options.gnss.admissible(fix).is_ok())
        .map(|fix| (fix.t_s, fix.en_m))
        .collect();
    let sets = ReferenceSets {
        known_distance: options.known_distance_m.map(|distance_m| {
            vec![SegmentReference {
                steps: 0..steps.len(),
                distance_m,
            }]
        }),
        reference_positions: options
            .train_on_reference_positions
            .then(|| straight_segments(&reference_en_m, &steps, &step_headings_rad, 3.0, 5.0)),
        gnss_speed: &gnss_references,
        gnss_positions: straight_segments(
            &admissible_fixes,
            &steps,
            &step_headings_rad,
            20.0,
            15.0,
        ),
    };
    let step_model = train_step_model(&steps, &sets, options, &mut notes);
    let step_lengths_m: Vec<f64> = steps
        .iter()
        .map(|step| step_model.model.length_m(step))
        .collect();

    // 5. The filter.
    let first_step = &steps[0];
    let (start_en_m, start_sigma_m) =
        start_position(first_step, &fixes, &reference_en_m, &options.gnss);
    let inputs: Vec<StepInput> = steps
        .iter()
        .zip(&step_lengths_m)
        .zip(&step_headings_rad)
        .map(|((step, &length_m), &heading_rad)| StepInput {
            t_start_s: step.t_start_s,
            t_s: step.t_end_s,
            length_m,
            heading_rad,
        })
        .collect();
    let fused = fuse(
        &inputs,
        &fixes,
        start_en_m,
        start_sigma_m,
        options.noise,
        &options.gnss,
    );
    let mut fix_counts = FixCounts::default();
    for decision in &fused.fix_use {
        let counter = match decision {
            FixUse::Used => &mut fix_counts.used,
            FixUse::UsedAfterReset => &mut fix_counts.used_after_reset,
            FixUse::InOutage => &mut fix_counts.in_outage,
            FixUse::PoorAccuracy => &mut fix_counts.poor_accuracy,
            FixUse::Rejected => &mut fix_counts.rejected,
            FixUse::BeforeWalk | FixUse::AfterWalk => &mut fix_counts.outside_walk,
        };
        *counter += 1;
    }
    if frame.is_none() {
        // No fix was good enough to anchor a frame: all were refused for accuracy.
        fix_counts.poor_accuracy = recording
            .gnss
            .values
            .iter()
            .filter(|fix| fix.lat_deg.is_some() && fix.lon_deg.is_some())
            .count();
        if fix_counts.poor_accuracy > 0 {
            notes.push(format!(
                "None of the {} GNSS fixes reported an accuracy within {} m: the track is dead-reckoned throughout.",
                fix_counts.poor_accuracy, options.gnss.max_hacc_m
            ));
        }
    }
    if !fixes.is_empty() && fix_counts.used + fix_counts.used_after_reset == 0 {
        notes.push(format!(
            "None of the {} GNSS fixes was used (accuracy worse than {} m, or in outages): the track is dead-reckoned throughout.",
            fixes.len(),
            options.gnss.max_hacc_m
        ));
    }

    // 6. Scores.
    let track = fused.track;
    let (walk_start_s, walk_end_s) = (
        track.first().map_or(0.0, |point| point.t_s),
        track.last().map_or(0.0, |point| point.t_s),
    );
    let position_error =
        metrics::position_errors(&track, &reference_en_m, walk_start_s, walk_end_s);
    let outage_position_errors = options
        .gnss
        .outages
        .iter()
        .filter_map(|outage| {
            metrics::position_errors(&track, &reference_en_m, outage.start_s, outage.end_s)
        })
        .collect();
    let mut fix_times_s: Vec<f64> = fixes.iter().map(|fix| fix.t_s).collect();
    fix_times_s.sort_by(f64::total_cmp);
    let gnss_gaps = gnss_gaps(
        &fix_times_s,
        walk_start_s,
        walk_end_s,
        &track,
        &reference_en_m,
    );
    let step_references_m = step_reference_lengths(&steps, &reference_en_m, &gnss_references);
    let step_length_error_m = MeanStd::of(
        step_lengths_m
            .iter()
            .zip(&step_references_m)
            .filter_map(|(length, reference)| reference.map(|reference| length - reference)),
    );
    let heading_error_deg =
        metrics::heading_error_deg(steps.iter().zip(&track[1..]).filter_map(|(step, point)| {
            let reference = recording
                .ref_heading_rad
                .interpolate_angle_at(step.mid_s(), 0.5)?;
            Some((point.heading_rad, reference))
        }));
    let loop_closure = options
        .closed_loop
        .then(|| {
            let length_m = options
                .known_distance_m
                .unwrap_or_else(|| metrics::track_distance_m(&track, walk_start_s, walk_end_s));
            metrics::loop_closure(&track, length_m)
        })
        .flatten();
    let pdr_distance_m = metrics::track_distance_m(&track, walk_start_s, walk_end_s);
    let report = PdrReport {
        file_name,
        n_steps: steps.len(),
        n_bouts: detection.n_bouts,
        mean_step_frequency_hz: detection.mean_frequency_hz(),
        pdr_distance_m,
        duration_s: walk_end_s - walk_start_s,
        step_model,
        heading_key,
        heading_label,
        frame_origin_lat_lon_deg: frame
            .map(|frame| [frame.origin().lat_deg, frame.origin().lon_deg]),
        outages: options.gnss.outages.clone(),
        fixes: fix_counts,
        position_error,
        outage_position_errors,
        gnss_gaps,
        step_length_error_m,
        heading_error_deg,
        loop_closure,
        notes,
    };
    Ok(PdrAnalysis {
        report,
        steps,
        step_lengths_m,
        step_headings_rad,
        step_references_m,
        track,
        fixes: fixes.into_iter().zip(fused.fix_use).collect(),
        reference_en_m,
        frame,
    })
}

fn without_outages(
    gnss: &Stream<crate::recording::GnssFix>,
    outages: &[Outage],
) -> Stream<crate::recording::GnssFix> {
    let mut kept = Stream::default();
    for (&t_s, fix) in gnss.t_s.iter().zip(&gnss.values) {
        if !outages.iter().any(|outage| outage.contains(t_s)) {
            kept.push(t_s, *fix);
        }
    }
    kept
}

/// The field-domain method to use without a reference: the 3D fit, else the ellipse,
/// else min/max, else the raw heading.
fn label_of(report: &crate::deviation::HeadingReport, key: &str) -> String {
    report
        .rows
        .iter()
        .find(|row| row.key == key)
        .map_or_else(|| key.to_string(), |row| row.label.clone())
}

fn model_keys(series: &[(String, Vec<f64>)]) -> String {
    series
        .iter()
        .map(|(key, _)| key.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The circular mean of the heading samples within a step, else the heading
/// interpolated at its middle (within a second); NaN when there is none.
fn mean_heading(heading: &Stream<f64>, start_s: f64, end_s: f64) -> f64 {
    let first = heading.t_s.partition_point(|&t| t < start_s);
    let last = heading.t_s.partition_point(|&t| t < end_s);
    let (mut sin_sum, mut cos_sum) = (0.0, 0.0);
    for value in heading.values.get(first..last).unwrap_or(&[]) {
        sin_sum += value.sin();
        cos_sum += value.cos();
    }
    if sin_sum != 0.0 || cos_sum != 0.0 {
        return crate::angle::wrap_to_2pi(sin_sum.atan2(cos_sum));
    }
    heading
        .interpolate_angle_at(0.5 * (start_s + end_s), 1.0)
        .unwrap_or(f64::NAN)
}

fn fill_forward(values: Vec<f64>) -> Vec<f64> {
    let first_finite = values
        .iter()
        .copied()
        .find(|v| v.is_finite())
        .unwrap_or(0.0);
    let mut last = first_finite;
    values
        .into_iter()
        .map(|value| {
            if value.is_finite() {
                last = value;
            }
            last
        })
        .collect()
}

/// The first fix with a position that the policy would take (its accuracy), where the
/// local frame is anchored.
fn first_good_fix(recording: &Recording, policy: &GnssPolicy) -> Option<Geodetic> {
    recording
        .gnss
        .t_s
        .iter()
        .zip(&recording.gnss.values)
        .find_map(|(&t_s, fix)| {
            policy.admits(t_s, fix.hacc_m).ok()?;
            Some(Geodetic {
                lat_deg: fix.lat_deg?,
                lon_deg: fix.lon_deg?,
                alt_m: fix.alt_m.unwrap_or(0.0),
            })
        })
}

/// Reference positions in the filter's frame. Latitude/longitude references go through
/// the frame; metric references are used as they are without GNSS, and with GNSS are
/// shifted by their mean offset from the fixes that are used (both frames point east
/// and north, so a shift ties them).
fn reference_positions(
    recording: &Recording,
    frame: Option<&LocalFrame>,
    fixes: &[FixInput],
    policy: &GnssPolicy,
    notes: &mut Vec<String>,
) -> Vec<(f64, [f64; 2])> {
    let mut out: Vec<(f64, [f64; 2])> = Vec::new();
    if let Some(frame) = frame {
        let lat_lon = &recording.ref_position_lat_lon_deg;
        out.extend(
            lat_lon
                .t_s
                .iter()
                .zip(&lat_lon.values)
                .map(|(&t_s, value)| {
                    let en = frame.en_of(value.x, value.y);
                    (t_s, [en.x, en.y])
                }),
        );
    }
    let metric = &recording.ref_position_en_m;
    if metric.is_empty() {
        return out;
    }
    let mut shift = [0.0, 0.0];
    if frame.is_some() {
        let mut n = 0usize;
        for fix in fixes.iter().filter(|fix| policy.admissible(fix).is_ok()) {
            if let Some(reference) = metric.interpolate_at(fix.t_s, 1.0) {
                shift[0] += fix.en_m[0] - reference.x;
                shift[1] += fix.en_m[1] - reference.y;
                n += 1;
            }
        }
        if n == 0 {
            notes.push("The reference positions do not overlap the GNSS fixes in time, so they cannot be placed in the GNSS frame and score nothing.".to_string());
            return out;
        }
        shift = [shift[0] / n as f64, shift[1] / n as f64];
        notes.push(format!(
            "The reference positions were tied to the GNSS frame by their mean offset from {n} fixes ({:.1} m east, {:.1} m north).",
            shift[0], shift[1]
        ));
    }
    out.extend(
        metric
            .t_s
            .iter()
            .zip(&metric.values)
            .map(|(&t_s, value)| (t_s, [value.x + shift[0], value.y + shift[1]])),
    );
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// Per-step references from the GNSS speed while GNSS is good: the speed at the middle
/// of the step (interpolated across at most 1.5 s) times its duration. The last step of
/// a bout, whose end is a guess, has none.
fn gnss_step_references(
    recording: &Recording,
    steps: &[Step],
    policy: &GnssPolicy,
) -> Vec<StepReference> {
    let mut speed = Stream::default();
    for (&t_s, fix) in recording.gnss.t_s.iter().zip(&recording.gnss.values) {
        if let (Some(speed_mps), Ok(_)) = (fix.speed_mps, policy.admits(t_s, fix.hacc_m)) {
            if speed_mps.is_finite() && speed_mps >= 0.0 {
                speed.push(t_s, speed_mps);
            }
        }
    }
    steps
        .iter()
        .enumerate()
        .filter(|(_, step)| !step.ends_bout)
        .filter_map(|(step_idx, step)| {
            let speed_mps = speed.interpolate_at(step.mid_s(), 1.5)?;
            Some(StepReference {
                step_idx,
                length_m: speed_mps * step.duration_s(),
            })
        })
        .collect()
}

/// Where the step model's references come from, in the order they are tried.
struct ReferenceSets<'a> {
    known_distance: Option<Vec<SegmentReference>>,
    reference_positions: Option<Vec<SegmentReference>>,
    gnss_speed: &'a [StepReference],
    gnss_positions: Vec<SegmentReference>,
}

fn train_step_model(
    steps: &[Step],
    sets: &ReferenceSets<'_>,
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> StepModelReport {
    let requested = options.step_model;
    let rms_on = |model: &StepLengthModel, segments: &[SegmentReference]| {
        let squares: Vec<f64> = segments
            .iter()
            .filter_map(|segment| {
                let run = steps.get(segment.steps.clone())?;
                let modelled: f64 = run.iter().map(|step| model.length_m(step)).sum();
                Some(((modelled - segment.distance_m) / run.len().max(1) as f64).powi(2))
            })
            .collect();
        (!squares.is_empty()).then(|| (squares.iter().sum::<f64>() / squares.len() as f64).sqrt())
    };
    let per_step: Vec<SegmentReference> = sets
        .gnss_speed
        .iter()
        .map(|reference| SegmentReference {
            steps: reference.step_idx..reference.step_idx + 1,
            distance_m: reference.length_m,
        })
        .collect();
    let candidates: [(&'static str, Option<&[SegmentReference]>); 4] = [
        ("known_distance", sets.known_distance.as_deref()),
        ("reference_positions", sets.reference_positions.as_deref()),
        (
            "gnss_speed",
            (!per_step.is_empty()).then_some(per_step.as_slice()),
        ),
        (
            "gnss_positions",
            (!sets.gnss_positions.is_empty()).then_some(sets.gnss_positions.as_slice()),
        ),
    ];
    for (source, segments) in candidates {
        let Some(segments) = segments else { continue };
        // Runs of several steps fit the network only through a Weinberg model.
        let kind = if requested == StepModelKind::Neural
            && segments.iter().any(|s| s.steps.len() != 1)
        {
            notes.push(format!(
                "The {source} references are distances over several steps, which train only the Weinberg and linear models; Weinberg's was fitted."
            ));
            StepModelKind::Weinberg
        } else {
            requested
        };
        match step_length::fit_segments(kind, steps, segments, options.seed) {
            Ok(model) => {
                let train_rms_m = rms_on(&model, segments);
                return StepModelReport {
                    requested,
                    model,
                    trained_on: source,
                    n_references: segments.len(),
                    train_rms_m,
                };
            }
            Err(error) => notes.push(format!(
                "The {source} references did not train the step model: {error}."
            )),
        }
    }
    if let Some(k) = options.weinberg_k.filter(|k| k.is_finite() && *k > 0.0) {
        if requested != StepModelKind::Weinberg {
            notes.push(format!(
                "Nothing in the log trains the {} model; the given Weinberg K was used.",
                requested.key()
            ));
        }
        return StepModelReport {
            requested,
            model: StepLengthModel::Weinberg { k },
            trained_on: "given_k",
            n_references: 0,
            train_rms_m: None,
        };
    }
    notes.push(format!(
        "Nothing trained the step model (no GNSS while GNSS was good, no known distance): Weinberg's K = {} was used. Give --known-distance for a walk of known length, or --weinberg-k from an earlier walk.",
        step_length::DEFAULT_WEINBERG_K
    ));
    StepModelReport {
        requested,
        model: StepLengthModel::Weinberg {
            k: step_length::DEFAULT_WEINBERG_K,
        },
        trained_on: "default",
        n_references: 0,
        train_rms_m: None,
    }
}

/// The steps whose middle lies between two times.
fn steps_between(steps: &[Step], start_s: f64, end_s: f64) -> std::ops::Range<usize> {
    let first = steps.partition_point(|step| step.mid_s() < start_s);
    let last = steps.partition_point(|step| step.mid_s() <= end_s);
    first..last.max(first)
}

/// The speed (m/s) of the least-squares line through timed positions.
fn line_speed_mps(positions: &[(f64, [f64; 2])]) -> Option<f64> {
    let n = positions.len() as f64;
    let mean_t = positions.iter().map(|(t, _)| t).sum::<f64>() / n;
    let mean_e = positions.iter().map(|(_, p)| p[0]).sum::<f64>() / n;
    let mean_n = positions.iter().map(|(_, p)| p[1]).sum::<f64>() / n;
    let (mut stt, mut ste, mut stn) = (0.0, 0.0, 0.0);
    for (t, p) in positions {
        let dt = t - mean_t;
        stt += dt * dt;
        ste += dt * (p[0] - mean_e);
        stn += dt * (p[1] - mean_n);
    }
    (stt > 0.0).then(|| (ste * ste + stn * stn).sqrt() / stt)
}

/// The circular spread (rad) of the headings of a run of steps.
fn heading_spread_rad(headings: &[f64]) -> f64 {
    let n = headings.len().max(1) as f64;
    let (sin, cos) = headings
        .iter()
        .fold((0.0, 0.0), |(s, c), h| (s + h.sin(), c + h.cos()));
    let resultant = ((sin / n).powi(2) + (cos / n).powi(2)).sqrt().min(1.0);
    (-2.0 * resultant.max(1e-12).ln()).sqrt()
}

/// Segments between positions (GNSS fixes or reference positions) on straight
/// stretches: from each position, the first one at least `span_s` later; kept when the
/// steps between them hold their heading (spread under 8°), so that the path is a line.
/// Its length is the speed of a least-squares line through all the positions of the
/// span times the span: over 20 fixes of 3 m noise that is good to about 2.3 m, where
/// the chord between the two end fixes would be good to 4.2 m. The
/// end is chosen by time, not by distance: choosing the first fix far enough away
/// would prefer fixes whose noise lengthens the chord. The next segment starts where
/// this one ended.
fn straight_segments(
    positions: &[(f64, [f64; 2])],
    steps: &[Step],
    step_headings_rad: &[f64],
    span_s: f64,
    min_chord_m: f64,
) -> Vec<SegmentReference> {
    let mut segments = Vec::new();
    let mut start = 0usize;
    while start < positions.len() {
        let (t_a, _) = positions[start];
        let Some(offset) = positions[start + 1..]
            .iter()
            .position(|(t_b, _)| t_b - t_a >= span_s)
        else {
            break;
        };
        let end = start + 1 + offset;
        let (t_b, _) = positions[end];
        let span = positions.get(start..=end).unwrap_or(&[]);
        let chord_m = line_speed_mps(span).map_or(0.0, |speed| speed * (t_b - t_a));
        if span.len() < 3 || t_b - t_a > 2.0 * span_s || chord_m < min_chord_m {
            start += 1;
            continue;
        }
        let run = steps_between(steps, t_a, t_b);
        let straight = step_headings_rad.get(run.clone()).is_some_and(|headings| {
            !headings.is_empty() && heading_spread_rad(headings) < 8f64.to_radians()
        });
        let walking = steps
            .get(run.clone())
            .is_some_and(|run| !run.iter().any(|step| step.ends_bout));
        if straight && walking && run.len() >= 5 {
            segments.push(SegmentReference {
                steps: run,
                distance_m: chord_m,
            });
            start = end;
        } else {
            start += 1;
        }
    }
    segments
}

/// The filter's start: the first admissible fix within 5 s of the first step (σ its
/// accuracy), else the first reference position (a surveyed start, σ 0.5 m), else the
/// origin (σ 0).
fn start_position(
    first_step: &Step,
    fixes: &[FixInput],
    reference_en_m: &[(f64, [f64; 2])],
    policy: &GnssPolicy,
) -> ([f64; 2], f64) {
    let near_start = fixes
        .iter()
        .filter(|fix| (fix.t_s - first_step.t_start_s).abs() <= 5.0)
        .find_map(|fix| {
            policy
                .admissible(fix)
                .ok()
                .map(|sigma_m| (fix.en_m, sigma_m))
        });
    if let Some(found) = near_start {
        return found;
    }
    if let Some((_, first)) = reference_en_m.first() {
        return (*first, 0.5);
    }
    ([0.0, 0.0], 0.0)
}

/// Each step's reference length: from dense reference positions (5 Hz or more: the
/// distance between the positions at its start and end), else its GNSS reference.
fn step_reference_lengths(
    steps: &[Step],
    reference_en_m: &[(f64, [f64; 2])],
    gnss_references: &[StepReference],
) -> Vec<Option<f64>> {
    let dense = reference_en_m.len() >= 2 && {
        let span_s = reference_en_m.last().map_or(0.0, |r| r.0) - reference_en_m[0].0;
        span_s > 0.0 && reference_en_m.len() as f64 / span_s >= 5.0
    };
    if dense {
        let stream = Stream {
            t_s: reference_en_m.iter().map(|(t, _)| *t).collect(),
            values: reference_en_m
                .iter()
                .map(|(_, en)| nalgebra::Vector2::new(en[0], en[1]))
                .collect(),
        };
        return steps
            .iter()
            .map(|step| {
                if step.ends_bout {
                    return None;
                }
                let a = stream.interpolate_at(step.t_start_s, 0.5)?;
                let b = stream.interpolate_at(step.t_end_s, 0.5)?;
                Some((b - a).norm())
            })
            .collect();
    }
    let mut out = vec![None; steps.len()];
    for reference in gnss_references {
        if let Some(slot) = out.get_mut(reference.step_idx) {
            *slot = Some(reference.length_m);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, GnssSim, WalkConfig};

    fn sim_report(config: &WalkConfig) -> ImportReport {
        let text = canonical_csv::write(&simulate(config));
        import("sim.csv", text.as_bytes()).expect("readable")
    }

    fn with_gnss(seed: u64, duration_s: f64) -> WalkConfig {
        WalkConfig {
            gnss: Some(GnssSim {
                position_noise_m: 3.0,
                hacc_m: 3.0,
                ..GnssSim::default()
            }),
            ..WalkConfig::from_seed(seed, duration_s)
        }
    }

    fn weinberg_k(analysis: &PdrAnalysis) -> f64 {
        match analysis.report.step_model.model {
            StepLengthModel::Weinberg { k } => k,
            _ => f64::NAN,
        }
    }

    /// Issue 6's simulator check: a 15-minute walk (varied gait, Weinberg-sized
    /// bounces, the unified heading error of up to ~18°, 3 m GNSS) with GNSS ignored from
    /// 4 to 14 minutes. The outage's RMS position error must stay under 1 % of the
    /// distance walked in it, and the step count within 1 % of the truth's.
    #[test]
    fn a_ten_minute_outage_is_bridged_within_one_percent_of_the_distance() {
        for (seed, rate_hz, model) in [
            (1, 50.0, StepModelKind::Weinberg),
            (2, 100.0, StepModelKind::Linear),
            (3, 50.0, StepModelKind::Neural),
        ] {
            let config = WalkConfig::pdr_walk(seed, 900.0, rate_hz);
            let (rows, truth) = crate::sim::walk::simulate_with_truth(&config);
            let text = canonical_csv::write(&rows);
            let report = import("walk.csv", text.as_bytes()).expect("readable");
            let options = PdrOptions {
                step_model: model,
                gnss: GnssPolicy {
                    outages: vec![Outage {
                        start_s: 240.0,
                        end_s: 840.0,
                    }],
                    ..GnssPolicy::default()
                },
                ..PdrOptions::default()
            };
            let analysis = run(report, &options).expect("dead-reckons");
            let report = &analysis.report;
            let outage = report.outage_position_errors.first().expect("scored");
            let step_error_pct = 100.0 * (report.n_steps as f64 / truth.steps.len() as f64 - 1.0);
            eprintln!(
                "seed {seed}, {rate_hz} Hz, {model:?}: {} steps (truth {}), outage RMS {:.2} m = {:.3} % of {:.0} m, max {:.2} m, heading {}",
                report.n_steps,
                truth.steps.len(),
                outage.rms_m,
                outage.rms_pct,
                outage.distance_m,
                outage.max_m,
                report.heading_key
            );
            assert!(outage.rms_pct < 1.0, "{outage:?}");
            assert!(outage.distance_m > 500.0, "{outage:?}");
            assert!(step_error_pct.abs() < 1.0, "{step_error_pct} %");
            assert_eq!(report.step_model.trained_on, "gnss_speed");
            assert_eq!(report.step_model.model.kind(), model);
            assert_eq!(report.fixes.in_outage, 601, "{:?}", report.fixes);
        }
    }

    #[test]
    fn gnss_positions_train_the_step_model_when_the_log_has_no_speed() {
        // 20 minutes: each 20-s stretch knows its length to about 2.3 m (3 m fixes), so
        // about 50 stretches give K to about 1.3 %.
        let config = with_gnss(21, 1200.0);
        let with_speed = run(sim_report(&config), &PdrOptions::default()).expect("runs");
        assert_eq!(with_speed.report.step_model.trained_on, "gnss_speed");
        let mut report = sim_report(&config);
        for fix in &mut report.recording.gnss.values {
            fix.speed_mps = None;
        }
        let without_speed = run(report, &PdrOptions::default()).expect("runs");
        let summary = &without_speed.report.step_model;
        assert_eq!(
            summary.trained_on, "gnss_positions",
            "{:?}",
            without_speed.report.notes
        );
        assert!(summary.n_references >= 10, "{summary:?}");
        let (k_speed, k_positions) = (weinberg_k(&with_speed), weinberg_k(&without_speed));
        assert!(
            (k_positions / k_speed - 1.0).abs() < 0.04,
            "{k_speed} from speed, {k_positions} from positions"
        );
    }

    #[test]
    fn straight_segments_follow_straight_runs_of_steps_only() {
        let step = |k: usize| Step {
            t_start_s: 0.5 * k as f64,
            t_end_s: 0.5 * (k + 1) as f64,
            t_peak_s: 0.5 * k as f64 + 0.1,
            frequency_hz: 2.0,
            variance_mps2_sq: 1.0,
            a_max_mps2: 11.0,
            a_min_mps2: 8.5,
            ends_bout: false,
        };
        let steps: Vec<Step> = (0..200).map(step).collect();
        // North for 50 s, then turning 9° a step.
        let headings: Vec<f64> = (0..200)
            .map(|k| {
                if k < 100 {
                    0.0
                } else {
                    (k - 100) as f64 * 9f64.to_radians()
                }
            })
            .collect();
        let positions: Vec<(f64, [f64; 2])> = (0..100)
            .map(|t| (t as f64, [0.0, 1.4 * t as f64]))
            .collect();
        let segments = straight_segments(&positions, &steps, &headings, 20.0, 15.0);
        assert!(!segments.is_empty());
        for segment in &segments {
            assert!(segment.steps.end <= 100, "{segment:?}");
            assert!(segment.distance_m >= 15.0);
        }
    }
}
