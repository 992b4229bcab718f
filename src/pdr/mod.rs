//! Pedestrian dead reckoning: steps, step lengths, headings and the EKF that bridges
//! GNSS outages (Chen et al., *A unified heading error model and step length
//! estimation for PDR*, Sections III, V and VI; Fig. 2).
//!
//! ## Layout
//!
//! - `steps.rs`: step detection (sliding window, zero crossing and peak detection on
//!   `|f|`) with SF, SV, Amax and Amin per step.
//! - `turning_over.rs`: the "steps" of a phone turned over in the hand (a compass
//!   calibration's figure eight) left out; `lone_steps.rs`: bouts of one or two steps
//!   (feet shifted while standing or turning about) left out.
//! - `step_length.rs`: the linear (Eq. 2), Weinberg (Eq. 3) and neural step-length
//!   models, fitted to per-step references or to a known distance; `references.rs`
//!   where those references (and the track's local frame and reference positions) come
//!   from.
//! - `step_heading.rs`: the heading each step takes: the analysis's one best model,
//!   fitted again on the GNSS course outside the outages, optionally carried by the
//!   gyro, with the attitude filter's yaw σ where the heading is the filter's.
//! - `ekf.rs`: the `[E, N, l, a]` filter of Eq. 13 with GNSS position updates ("how to
//!   fuse"; the heading's 1σ the step's own where it states one, else the noise
//!   model's).
//! - `fusion.rs`: GNSS/PDR switching: outages, accuracy and χ² gates, recovery ("when
//!   to fuse"), the paper's causal filter (`--filter paper`).
//! - `fix_accuracy.rs`: the accuracy a fix is taken at (no better than its
//!   neighbours' by more than a share).
//! - `smoother.rs`: the default for logs: every fix weighted by its accuracy and
//!   innovation, the step scale (never learnt from the fixes), the heading error and
//!   the GNSS's slow error as states, forward and then backward (Rauch-Tung-Striebel);
//!   `--filter causal` is its forward pass alone; `small_matrix.rs` its 7 × 7 algebra.
//! - `metrics.rs`: the paper's accuracy figures (Tables I, III, IV), the competitions'
//!   P75, the share of errors within 1 and 2 × the stated σ, and loop closure.
//! - `results.rs`: what it reports, with each gap without any fix in the log
//!   ([`GnssGap`], which the plots shade as they do the user's outages); `export.rs`
//!   the track as CSV, GeoJSON and GPX.
//! - this file: [`dead_reckon`], from an imported recording and its heading comparison
//!   to a [`PdrAnalysis`] ([`crate::pipeline`] runs the stages in order).
//!
//! ## The stage
//!
//! 1. The heading model is the comparison's choice
//!    ([`crate::analysis::calibration::selection`]); it is fitted again on the GNSS
//!    course left after the outages' fixes are set aside (Fig. 2: "the speed and
//!    heading from GPS are utilized to train the step length model and calibrate the
//!    compass"), never on a reference-heading column, which in a test log is the truth.
//! 2. Steps are detected, those of a phone turned over left out; each gets the heading
//!    of the chosen model (circular mean over the step) and a length from the step
//!    model.
//! 3. The step model trains on, in this order: a known distance (a loop of known
//!    length); the reference positions, when asked to; the GNSS speed over each step
//!    while GNSS is good; the distance between GNSS fixes on straight stretches (logs
//!    without speed); else a K given from an earlier walk, else Weinberg's default.
//! 4. One filter runs through the steps and the fixes: by default the smoother of
//!    `smoother.rs` over every fix, else the paper's switching EKF over the admissible
//!    ones.
//! 5. Reference positions (a truth track, surveyed waypoints) score the track; a
//!    reference-heading column scores the headings.

pub mod ekf;
pub mod export;
mod fix_accuracy;
pub mod fusion;
pub mod lone_steps;
pub mod metrics;
mod references;
mod results;
mod small_matrix;
pub mod smoother;
pub mod step_heading;
pub mod step_length;
pub mod steps;
pub mod turning_over;

pub use results::{FixCounts, GnssGap, PdrAnalysis, PdrError, PdrReport, StepModelReport};

use serde::Serialize;

use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::headings::{HeadingAnalysis, HeadingOptions};
use crate::base::geodesy::LocalFrame;
use crate::io::recording::{Recording, Stream};
use crate::io::ImportReport;

use crate::base::stats::MeanStd;
use ekf::EkfNoise;
use fusion::{fuse, FixInput, FixUse, Fused, GnssPolicy, StepInput, TrackPoint};
use lone_steps::gait_steps;
use metrics::{LoopClosure, PositionErrors};
use references::{
    first_good_fix, gnss_step_references, reference_positions, start_position,
    step_reference_lengths, train_step_model, ReferenceSets,
};
use results::gnss_gaps;
use smoother::{fuse_walk, WalkNoise, WalkPrior};
use step_heading::{fill_forward, mean_heading, step_heading, StepHeading};
use step_length::StepModelKind;
use steps::{detect_steps, Step, StepOptions};
use turning_over::walking_steps;

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

/// How the steps and the fixes are fused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterKind {
    /// Forward and backward over every fix ([`smoother`]): for logs, analysed after the
    /// fact.
    Smoother,
    /// The smoother's forward pass alone: each position from what came before it.
    Causal,
    /// The paper's `[E, N, l, a]` EKF with GNSS/PDR switching ([`fusion`]).
    Paper,
}

impl FilterKind {
    pub fn key(self) -> &'static str {
        match self {
            FilterKind::Smoother => "smoother",
            FilterKind::Causal => "causal",
            FilterKind::Paper => "paper",
        }
    }

    pub fn parse(text: &str) -> Option<FilterKind> {
        match text.trim() {
            "smoother" => Some(FilterKind::Smoother),
            "causal" => Some(FilterKind::Causal),
            "paper" => Some(FilterKind::Paper),
            _ => None,
        }
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
    pub filter: FilterKind,
    /// The paper filter's noise.
    pub noise: EkfNoise,
    /// The smoother's noise.
    pub walk_noise: WalkNoise,
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
            filter: FilterKind::Smoother,
            noise: EkfNoise::default(),
            walk_noise: WalkNoise::default(),
            seed: 1,
        }
    }
}

/// Dead-reckons an imported recording with the heading comparison made on it
/// ([`crate::pipeline`] runs the two in order). Its steps (the functions below marked
/// `#[inline(never)]`) run once per log and stay out of line (docs/ARCHITECTURE.md,
/// "Build").
pub fn dead_reckon(
    import: &ImportReport,
    (calibration, headings): (&CalibrationAnalysis, &HeadingAnalysis),
    options: &PdrOptions,
) -> Result<PdrAnalysis, PdrError> {
    let file_name = import.file_name.clone();
    let recording = &import.recording;
    if recording.acc_in_body_mps2.is_empty() {
        return Err(PdrError::NoAccelerometer { file_name });
    }
    let mut notes = Vec::new();

    // 1 and 2: the heading, the steps and their headings.
    let HeadedSteps {
        steps,
        headings_rad: step_headings_rad,
        heading_sigmas_rad: step_heading_sigmas_rad,
        heading_key,
        heading_label,
    } = headed_steps(import, (calibration, headings), options, &mut notes)?;
    let n_bouts = steps.iter().filter(|step| step.ends_bout).count();

    // 3. The local frame, the fixes and the reference positions.
    let placing = Placing::of(recording, options, &mut notes);
    let (fixes, reference_en_m) = (&placing.fixes, &placing.reference_en_m);

    // 4. Step lengths.
    let gnss_references = gnss_step_references(recording, &steps, &options.gnss);
    let sets = ReferenceSets::of(
        &steps,
        &step_headings_rad,
        fixes,
        reference_en_m,
        &gnss_references,
        options,
    );
    let (step_model, step_lengths_m) = step_model_and_lengths(&steps, &sets, options, &mut notes);

    // 5. The filter.
    let (fused, smoothed) = run_filter(
        &steps,
        &step_lengths_m,
        (&step_headings_rad, &step_heading_sigmas_rad),
        fixes,
        reference_en_m,
        (options, &step_model),
    );
    if let Some(smoothed) = smoothed {
        notes.push(smoothed.describe(options.filter, !fixes.is_empty()));
    }
    let fix_counts = count_fixes(&fused.fix_use, &placing, recording, &mut notes);

    // 6. Scores.
    let track = fused.track;
    let scores = track_scores(&track, reference_en_m, fixes, options);
    let step_references_m = step_reference_lengths(&steps, reference_en_m, &gnss_references);
    let step_length_error_m = step_length_error_m(&step_lengths_m, &step_references_m);
    let heading_error_deg = step_heading_error_deg(&steps, &track, recording);
    let report = PdrReport {
        file_name,
        n_steps: steps.len(),
        n_bouts,
        mean_step_frequency_hz: steps::mean_frequency_hz(&steps),
        pdr_distance_m: scores.pdr_distance_m,
        duration_s: scores.walk_end_s - scores.walk_start_s,
        step_model,
        heading_key,
        heading_label,
        frame_origin_lat_lon_deg: placing
            .frame
            .map(|frame| [frame.origin().lat_deg, frame.origin().lon_deg]),
        outages: options.gnss.outages.clone(),
        fixes: fix_counts,
        position_error: scores.position_error,
        outage_position_errors: scores.outage_position_errors,
        gnss_gaps: scores.gnss_gaps,
        step_length_error_m,
        heading_error_deg,
        loop_closure: scores.loop_closure,
        notes,
    };
    Ok(PdrAnalysis {
        report,
        steps,
        step_lengths_m,
        step_headings_rad,
        step_references_m,
        track,
        fixes: placing.fixes.into_iter().zip(fused.fix_use).collect(),
        reference_en_m: placing.reference_en_m,
        frame: placing.frame,
    })
}

/// The walk's steps, each with its heading and that heading's 1σ, and the heading model
/// they took.
struct HeadedSteps {
    steps: Vec<Step>,
    headings_rad: Vec<f64>,
    heading_sigmas_rad: Vec<Option<f64>>,
    heading_key: String,
    heading_label: String,
}

/// Stages 1 and 2: the heading (the comparison's choice, fitted again outside the
/// outages), the steps of walking, and each step's heading; fails without either.
#[inline(never)]
fn headed_steps(
    import: &ImportReport,
    (calibration, headings): (&CalibrationAnalysis, &HeadingAnalysis),
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> Result<HeadedSteps, PdrError> {
    let recording = &import.recording;
    let acc = &recording.acc_in_body_mps2;
    let no_steps = || PdrError::NoSteps {
        file_name: import.file_name.clone(),
        duration_s: acc.duration_s(),
    };

    // 1. The heading: the comparison's choice, fitted again outside the outages.
    let Some(StepHeading {
        heading_rad: heading_stream,
        sigma_rad: heading_sigma_stream,
        key: heading_key,
        label: heading_label,
    }) = step_heading(import, (calibration, headings), options, notes)
    else {
        return Err(no_steps());
    };

    // 2. Steps and their headings.
    let detection = detect_steps(acc, &options.steps);
    notes.extend(detection.notes.iter().cloned());
    let walking = walking_steps(&detection.steps, acc, &recording.gyro_in_body_radps);
    notes.extend(walking.note());
    let gait = gait_steps(&walking.steps);
    notes.extend(gait.note());
    let steps = gait.steps;
    if steps.is_empty() {
        return Err(no_steps());
    }
    let headings_rad = step_headings(&steps, &heading_stream, notes);
    // The heading's 1σ at each step's middle (the filter's changes slowly).
    let heading_sigmas_rad: Vec<Option<f64>> = steps
        .iter()
        .map(|step| {
            heading_sigma_stream
                .as_ref()
                .and_then(|sigma| sigma.interpolate_at(step.mid_s(), 1.0))
        })
        .collect();
    Ok(HeadedSteps {
        steps,
        headings_rad,
        heading_sigmas_rad,
        heading_key,
        heading_label,
    })
}

/// Stage 4: the step model trained on the reference sets (one trained on GNSS only where
/// its lengths are plausible) and each step's length (m) by it.
#[inline(never)]
fn step_model_and_lengths(
    steps: &[Step],
    sets: &ReferenceSets,
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> (StepModelReport, Vec<f64>) {
    let step_model = train_step_model(steps, sets, options, notes);
    let step_model = plausible_step_model(step_model, steps, options, notes);
    let step_lengths_m: Vec<f64> = steps
        .iter()
        .map(|step| step_model.model.length_m(step))
        .collect();
    (step_model, step_lengths_m)
}

/// The steps' length error (m) against the reference lengths, where a step has one.
#[inline(never)]
fn step_length_error_m(
    step_lengths_m: &[f64],
    step_references_m: &[Option<f64>],
) -> Option<MeanStd> {
    MeanStd::of(
        step_lengths_m
            .iter()
            .zip(step_references_m)
            .filter_map(|(length, reference)| reference.map(|reference| length - reference)),
    )
}

/// The track's heading error (deg) at each step against the log's reference heading.
#[inline(never)]
fn step_heading_error_deg(
    steps: &[Step],
    track: &[TrackPoint],
    recording: &Recording,
) -> Option<MeanStd> {
    metrics::heading_error_deg(steps.iter().zip(&track[1..]).filter_map(|(step, point)| {
        let reference = recording
            .ref_heading_rad
            .interpolate_angle_at(step.mid_s(), 0.5)?;
        Some((point.heading_rad, reference))
    }))
}

/// Each step's heading: the circular mean over the step, a step without any carrying
/// the previous one's (said in a note).
fn step_headings(steps: &[Step], heading: &Stream<f64>, notes: &mut Vec<String>) -> Vec<f64> {
    let step_headings_rad: Vec<f64> = steps
        .iter()
        .map(|step| mean_heading(heading, step.t_start_s, step.t_end_s))
        .collect();
    let n_without_heading = step_headings_rad.iter().filter(|h| !h.is_finite()).count();
    if n_without_heading > 0 {
        notes.push(format!("{n_without_heading} steps had no heading sample within a second and kept the previous step's heading."));
    }
    fill_forward(step_headings_rad)
}

impl PdrOptions {
    /// The policy the filter takes fixes by: the smoother weighs every fix by its
    /// accuracy and its innovation, so only an outage keeps one out; the paper's filter
    /// refuses the inaccurate ones.
    fn fix_policy(&self) -> GnssPolicy {
        match self.filter {
            FilterKind::Paper => self.gnss.clone(),
            FilterKind::Smoother | FilterKind::Causal => GnssPolicy {
                max_hacc_m: f64::INFINITY,
                ..self.gnss.clone()
            },
        }
    }
}

/// What the smoother learnt, for the notes.
struct Smoothed {
    trust: f64,
    scale: (f64, f64),
}

impl Smoothed {
    fn describe(&self, filter: FilterKind, has_fixes: bool) -> String {
        let how = match filter {
            FilterKind::Smoother => "smoothed forward and backward (Rauch-Tung-Striebel), so each position uses the fixes before and after it",
            _ => "filtered forward only (causal): each position uses what came before it",
        };
        let trust = if has_fixes {
            format!(
                "; every GNSS fix weighted by its reported accuracy × {:.2} (learnt from the fixes' innovations), those beyond the χ² gate down-weighted",
                self.trust
            )
        } else {
            String::new()
        };
        let lengths = if has_fixes {
            "the step model's lengths are taken as they are (a phone's fixes move less than its walker, so they do not teach a step length)".to_string()
        } else {
            format!(
                "the step model's lengths are taken as they are, their scale's σ ({:.1} % by the walk's end) carried into the track's σ",
                100.0 * self.scale.1
            )
        };
        format!("The track is {how}{trust}; {lengths}.")
    }
}

/// How well the step model's training proves it: the 1σ of its scale the filter starts
/// from.
/// The filter carries it but never learns it: a phone's GNSS moves less than the
/// walker (its fixes lag, stay put indoors and cut corners), so the fixes alone would
/// shrink a walk (`smoother.rs`).
fn scale_sigma(step_model: &StepModelReport) -> f64 {
    match step_model.trained_on {
        "known_distance" => 0.01,
        "reference_positions" => 0.02,
        "gnss_speed" | "gnss_positions" | "given_k" => 0.03,
        _ => 0.05,
    }
}

/// A step model trained on GNSS that makes this walk's steps shorter than 0.6 or
/// longer than 1.6 times Weinberg's default K would is not proved by its references
/// (indoor fixes report a speed near zero while the walker walks): the default K is
/// used instead.
fn plausible_step_model(
    step_model: StepModelReport,
    steps: &[Step],
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> StepModelReport {
    if !matches!(step_model.trained_on, "gnss_speed" | "gnss_positions") || steps.is_empty() {
        return step_model;
    }
    let default = step_length::StepLengthModel::Weinberg {
        k: step_length::DEFAULT_WEINBERG_K,
    };
    let trained_m: f64 = steps
        .iter()
        .map(|step| step_model.model.length_m(step))
        .sum();
    let default_m: f64 = steps.iter().map(|step| default.length_m(step)).sum();
    let ratio = trained_m / default_m;
    if default_m > 0.0 && (0.6..=1.6).contains(&ratio) {
        return step_model;
    }
    notes.push(format!(
        "The step model trained on {} made the steps {:.0} % of the usual length ({}): not believed. Weinberg's K = {} was used.",
        step_model.trained_on.replace('_', " "),
        100.0 * ratio,
        step_model.describe(),
        step_length::DEFAULT_WEINBERG_K
    ));
    StepModelReport {
        requested: options.step_model,
        model: default,
        trained_on: "default",
        n_references: 0,
        train_rms_m: None,
    }
}

/// The filter over the steps and the fixes, from the start position.
#[inline(never)]
fn run_filter(
    steps: &[Step],
    step_lengths_m: &[f64],
    (step_headings_rad, step_heading_sigmas_rad): (&[f64], &[Option<f64>]),
    fixes: &[FixInput],
    reference_en_m: &[(f64, [f64; 2])],
    (options, step_model): (&PdrOptions, &StepModelReport),
) -> (Fused, Option<Smoothed>) {
    let Some(first_step) = steps.first() else {
        return (
            fuse(&[], fixes, [0.0, 0.0], 0.0, options.noise, &options.gnss),
            None,
        );
    };
    let inputs: Vec<StepInput> = steps
        .iter()
        .zip(step_lengths_m)
        .zip(step_headings_rad.iter().zip(step_heading_sigmas_rad))
        .map(
            |((step, &length_m), (&heading_rad, &heading_sigma_rad))| StepInput {
                t_start_s: step.t_start_s,
                t_s: step.t_end_s,
                length_m,
                heading_rad,
                heading_sigma_rad,
            },
        )
        .collect();
    if options.filter == FilterKind::Paper {
        let (start_en_m, start_sigma_m) =
            start_position(first_step, fixes, reference_en_m, &options.gnss);
        let fused = fuse(
            &inputs,
            fixes,
            start_en_m,
            start_sigma_m,
            options.noise,
            &options.gnss,
        );
        return (fused, None);
    }
    // Where there are fixes they place the walk; else a surveyed start, else the origin.
    let start = fixes.is_empty().then(|| {
        reference_en_m
            .first()
            .map_or(([0.0, 0.0], 0.0), |(_, first)| (*first, 0.5))
    });
    let prior = WalkPrior {
        start,
        scale_sigma: scale_sigma(step_model),
    };
    let walk = fuse_walk(
        &inputs,
        fixes,
        prior,
        options.walk_noise,
        &options.gnss,
        options.filter == FilterKind::Smoother,
    );
    (
        Fused {
            track: walk.track,
            fix_use: walk.fix_use,
        },
        Some(Smoothed {
            trust: walk.trust,
            scale: walk.scale,
        }),
    )
}

/// What places the walk (stage 3): the local frame, the fixes in it, the reference
/// positions, and the policy the filter takes the fixes by.
struct Placing {
    fix_policy: GnssPolicy,
    frame: Option<LocalFrame>,
    fixes: Vec<FixInput>,
    reference_en_m: Vec<(f64, [f64; 2])>,
}

impl Placing {
    /// The frame, fixes and reference positions of `recording` under `options`' policy.
    #[inline(never)]
    fn of(recording: &Recording, options: &PdrOptions, notes: &mut Vec<String>) -> Placing {
        let fix_policy = options.fix_policy();
        let (frame, fixes) = local_fixes(recording, &fix_policy);
        let reference_en_m =
            reference_positions(recording, frame.as_ref(), &fixes, &fix_policy, notes);
        Placing {
            fix_policy,
            frame,
            fixes,
            reference_en_m,
        }
    }
}

/// The local frame (anchored at the first admissible fix) and every fix with a position
/// in it; none without such a fix.
fn local_fixes(recording: &Recording, policy: &GnssPolicy) -> (Option<LocalFrame>, Vec<FixInput>) {
    let frame = first_good_fix(recording, policy).map(LocalFrame::at);
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
    (frame, fixes)
}

/// What became of the fixes `placing` gave the filter, with a note when none was used.
#[inline(never)]
fn count_fixes(
    fix_use: &[FixUse],
    placing: &Placing,
    recording: &Recording,
    notes: &mut Vec<String>,
) -> FixCounts {
    let (has_frame, n_fixes) = (placing.frame.is_some(), placing.fixes.len());
    let policy = &placing.fix_policy;
    let mut fix_counts = FixCounts::default();
    for decision in fix_use {
        let counter = match decision {
            FixUse::Used => &mut fix_counts.used,
            FixUse::UsedAfterReset => &mut fix_counts.used_after_reset,
            FixUse::InOutage => &mut fix_counts.in_outage,
            FixUse::PoorAccuracy => &mut fix_counts.poor_accuracy,
            FixUse::Rejected => &mut fix_counts.rejected,
            FixUse::DownWeighted => &mut fix_counts.down_weighted,
            FixUse::BeforeWalk | FixUse::AfterWalk => &mut fix_counts.outside_walk,
        };
        *counter += 1;
    }
    if !has_frame {
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
                fix_counts.poor_accuracy, policy.max_hacc_m
            ));
        }
    }
    if n_fixes > 0 && fix_counts.used + fix_counts.used_after_reset + fix_counts.down_weighted == 0
    {
        let why = if policy.max_hacc_m.is_finite() {
            format!("accuracy worse than {} m, or in outages", policy.max_hacc_m)
        } else {
            "all in outages or outside the walk".to_string()
        };
        notes.push(format!(
            "None of the {n_fixes} GNSS fixes was used ({why}): the track is dead-reckoned throughout."
        ));
    }
    fix_counts
}

/// The track's accuracy figures: against the reference positions over the whole walk
/// and each outage, each span without a fix, the loop closure and the distance.
struct TrackScores {
    walk_start_s: f64,
    walk_end_s: f64,
    position_error: Option<PositionErrors>,
    outage_position_errors: Vec<PositionErrors>,
    gnss_gaps: Vec<GnssGap>,
    loop_closure: Option<LoopClosure>,
    pdr_distance_m: f64,
}

#[inline(never)]
fn track_scores(
    track: &[TrackPoint],
    reference_en_m: &[(f64, [f64; 2])],
    fixes: &[FixInput],
    options: &PdrOptions,
) -> TrackScores {
    let (walk_start_s, walk_end_s) = (
        track.first().map_or(0.0, |point| point.t_s),
        track.last().map_or(0.0, |point| point.t_s),
    );
    let position_error = metrics::position_errors(track, reference_en_m, walk_start_s, walk_end_s);
    let outage_position_errors = options
        .gnss
        .outages
        .iter()
        .filter_map(|outage| {
            metrics::position_errors(track, reference_en_m, outage.start_s, outage.end_s)
        })
        .collect();
    let mut fix_times_s: Vec<f64> = fixes.iter().map(|fix| fix.t_s).collect();
    fix_times_s.sort_by(f64::total_cmp);
    let gnss_gaps = gnss_gaps(
        &fix_times_s,
        walk_start_s,
        walk_end_s,
        track,
        reference_en_m,
    );
    let loop_closure = options
        .closed_loop
        .then(|| {
            let length_m = options
                .known_distance_m
                .unwrap_or_else(|| metrics::track_distance_m(track, walk_start_s, walk_end_s));
            metrics::loop_closure(track, length_m)
        })
        .flatten();
    let pdr_distance_m = metrics::track_distance_m(track, walk_start_s, walk_end_s);
    TrackScores {
        walk_start_s,
        walk_end_s,
        position_error,
        outage_position_errors,
        gnss_gaps,
        loop_closure,
        pdr_distance_m,
    }
}

#[cfg(test)]
mod tests;
