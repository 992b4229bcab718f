//! What dead reckoning reports: the step model's training, what became of the fixes,
//! the accuracy figures (the PDR paper's Tables I, III, IV), the spans without any fix,
//! and the series the plots and exports draw.

use serde::Serialize;

use crate::analysis::levelled::AnalysisError;
use crate::base::geodesy::LocalFrame;

use super::fusion::{FixInput, FixUse, Outage, TrackPoint};
use super::metrics::{self, LoopClosure, PositionErrors};
use super::step_length::{StepLengthModel, StepModelKind};
use super::steps::Step;
use crate::base::stats::MeanStd;

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
            _ => "the default K (nothing in the log proves a step length)".to_string(),
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
    /// Taken with less weight: beyond the smoother's χ² gate.
    pub down_weighted: usize,
    /// Before the first step or after the last.
    pub outside_walk: usize,
}

impl FixCounts {
    /// "N used, … rejected by the gate", or `None` when the log had no fix to judge.
    pub fn describe(&self) -> Option<String> {
        let parts: Vec<String> = [
            (self.used, "used"),
            (self.down_weighted, "down-weighted beyond the gate"),
            (self.used_after_reset, "after a reset"),
            (self.in_outage, "in outages"),
            (self.poor_accuracy, "too inaccurate"),
            (self.rejected, "rejected by the gate"),
        ]
        .iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
        (!parts.is_empty()).then(|| parts.join(", "))
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
pub(super) fn gnss_gaps(
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
