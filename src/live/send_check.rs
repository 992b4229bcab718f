//! Whether a calibration may be sent to the board: the project's rule for every
//! write-back (issue 41). A device gets new parameters only if they are better than the
//! ones in force on a held-back part of the same data, and inside the device's
//! acceptance bounds; otherwise nothing is sent and the page says why.
//!
//! **Held back.** The session's magnetometer samples are cut into blocks of
//! [`BLOCK_LEN`] consecutive samples: even blocks train, odd blocks check (blocks rather
//! than every other sample, because neighbouring samples see nearly the same direction
//! and noise, and a check on them would flatter the fit). `Blocks` keeps a second
//! ellipsoid accumulator fed with the train blocks only, and an evenly thinned copy of
//! the check blocks' samples. At each refit the train-only accumulator is solved with
//! the model of the full fit, and the train-only fit, the full fit and the calibration
//! **in force** ([`InForce`]: the one the board last confirmed, else the one sent last,
//! else the raw readings) are applied to the check samples.
//!
//! **Better** ([`compare`]): the |B| spread (standard deviation over mean) on the check
//! samples at least [`MIN_RELATIVE_IMPROVEMENT`] lower than the calibration in force's,
//! and lower by more than twice the difference's standard error over the check blocks
//! (the blocks as independent units: the difference is outside the noise). Both the
//! train-only fit (which has never seen the check samples) and the full fit (the one
//! sent) must be better.
//!
//! **Bounds** ([`acceptance_reasons`], in [`crate::fit::quality`]): every number finite,
//! the soft iron positive definite with its axes within 3:1, the field strength the
//! Earth's (0.35-1.65 × the World Magnetic Model's, else 10-150 µT).

use nalgebra::{Matrix3, Vector3};
use serde::{Serialize, Serializer};

use crate::fit::model::FieldCalibration;
use crate::fit::streaming_ellipsoid::{EllipsoidAccumulator, EllipsoidError};

use crate::fit::quality::acceptance_reasons;
use crate::fit::quality::FieldVerdict;

/// Consecutive samples per block of the train/check split. At the 10-1,000 lines/s of
/// serial boards a block is 0.06-6 s of turning: long enough that the check samples are
/// not the train samples' neighbours, short enough that a 300-sample session has two
/// check blocks and train and check both see every part of the turn.
pub const BLOCK_LEN: usize = 64;

/// At most this many check samples are kept (evenly thinned, as the session's kept
/// samples are): the check costs the same after ten minutes as after ten seconds.
pub const MAX_CHECK_SAMPLES: usize = 8_192;

/// The fewest check blocks a comparison is made on: the standard error of the
/// difference needs two.
pub const MIN_CHECK_BLOCKS: usize = 2;

/// A new calibration must leave |B| varying at least this much less (relative) than the
/// calibration in force. Two fits of one session differ by less in their spread on the
/// check samples: the train-only and the full fit by 0.2 % on the simulated board of the
/// tests and by 1.3 % on the real HMC5883L of `hmc5883l-sphere` streamed live, a refit
/// after another sweep of the simulated board by 0.02 % from the one it sent. 5 % is
/// about four times what refitting alone gives, so a board is not rewritten for nothing.
pub const MIN_RELATIVE_IMPROVEMENT: f64 = 0.05;

/// The improvement must exceed this many standard errors of the paired difference of
/// the squared spreads over the check blocks (one-sided, about 98 % that it is real).
pub const NOISE_STANDARD_ERRORS: f64 = 2.0;

/// The session's samples split into train and check blocks.
#[derive(Debug, Clone)]
pub(super) struct Blocks {
    /// The power sums of the train blocks' samples.
    train: EllipsoidAccumulator,
    /// The check blocks' samples (sensor axes, µT), evenly thinned, each with its block.
    check_ut: Vec<Vector3<f64>>,
    check_block: Vec<usize>,
    check_stride: usize,
    n_check_seen: usize,
    n_seen: usize,
}

impl Blocks {
    pub(super) fn new() -> Self {
        Blocks {
            train: EllipsoidAccumulator::new(),
            check_ut: Vec::new(),
            check_block: Vec::new(),
            check_stride: 1,
            n_check_seen: 0,
            n_seen: 0,
        }
    }

    /// Takes the next magnetometer sample (sensor axes, µT).
    pub(super) fn add(&mut self, sample_ut: Vector3<f64>) {
        let block = self.n_seen / BLOCK_LEN;
        self.n_seen += 1;
        if block.is_multiple_of(2) {
            self.train.add(sample_ut);
            return;
        }
        if self.n_check_seen.is_multiple_of(self.check_stride) {
            self.check_ut.push(sample_ut);
            self.check_block.push(block);
            if self.check_ut.len() >= MAX_CHECK_SAMPLES {
                // Every second one; later ones at the doubled stride.
                let mut idx = 0usize;
                self.check_ut.retain(|_| {
                    idx += 1;
                    idx % 2 == 1
                });
                let mut idx = 0usize;
                self.check_block.retain(|_| {
                    idx += 1;
                    idx % 2 == 1
                });
                self.check_stride *= 2;
            }
        }
        self.n_check_seen += 1;
    }

    pub(super) fn train(&self) -> &EllipsoidAccumulator {
        &self.train
    }

    /// Check blocks begun so far (the odd ones).
    fn n_check_blocks(&self) -> usize {
        self.n_seen.div_ceil(BLOCK_LEN) / 2
    }
}

/// Where the calibration in force comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum InForceSource {
    /// Nothing sent in this session: the board's raw readings.
    Raw,
    /// Sent, and not (yet) echoed back by the board.
    Sent,
    /// Echoed back by the board (`Cal1:`/`Cal2:`).
    Confirmed,
}

/// The calibration in force on the board, as far as the session knows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InForce {
    pub source: InForceSource,
    /// Identity soft iron and no hard iron for the raw readings.
    pub calibration: FieldCalibration,
}

impl InForce {
    pub fn raw() -> Self {
        InForce {
            source: InForceSource::Raw,
            calibration: FieldCalibration {
                hard_iron_ut: Vector3::zeros(),
                soft_iron: Matrix3::identity(),
                field_ut: 0.0,
            },
        }
    }

    /// What it is, for the sentences.
    pub fn describe(&self) -> &'static str {
        match self.source {
            InForceSource::Raw => "the raw readings (nothing sent yet)",
            InForceSource::Sent => "the calibration sent last (not confirmed by the board)",
            InForceSource::Confirmed => "the calibration the board confirmed",
        }
    }

    fn short(&self) -> &'static str {
        match self.source {
            InForceSource::Raw => "raw",
            InForceSource::Sent => "sent",
            InForceSource::Confirmed => "confirmed",
        }
    }
}

/// A calibration on the check samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OnCheck {
    /// Standard deviation of `|corrected|` over its mean (percent).
    pub spread_pct: f64,
    /// RMS of `|corrected|` − the World Magnetic Model's field (µT), when known.
    pub rms_to_expected_ut: Option<f64>,
}

/// A calibration on the check samples beside the calibration in force.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Compared {
    pub on_check: OnCheck,
    /// Twice the standard error of the spread's difference with the calibration in
    /// force, over the check blocks (percentage points).
    pub noise_pct: f64,
    /// At least [`MIN_RELATIVE_IMPROVEMENT`] lower spread, and outside the noise.
    pub better: bool,
}

/// The held-back check of a calibration against the one in force.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldBack {
    pub n_train_samples: usize,
    /// Check samples received (before thinning), and their blocks.
    pub n_check_samples: usize,
    pub n_check_blocks: usize,
    /// The fit of the train blocks alone, with the full fit's model (`None` for a saved
    /// calibration, which was fitted on other data).
    pub train_calibration: Option<FieldCalibration>,
    /// Why there is no train-only fit, when it failed (serialized as its message).
    #[serde(serialize_with = "serialize_message")]
    pub train_error: Option<EllipsoidError>,
    pub train: Option<Compared>,
    /// The calibration to send (the full fit, which has seen the check samples, or a
    /// saved one).
    pub candidate: Compared,
    pub in_force: InForce,
    pub in_force_on_check: OnCheck,
}

/// An optional error as its message, as the held-back check's JSON shows it.
fn serialize_message<S: Serializer>(
    error: &Option<EllipsoidError>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    error
        .as_ref()
        .map(ToString::to_string)
        .serialize(serializer)
}

impl HeldBack {
    /// The check of `candidate` (and of `train`, the train-only fit or why it failed)
    /// against `in_force` on the split's check samples.
    pub(super) fn assess(
        blocks: &Blocks,
        candidate: &FieldCalibration,
        train: Option<Result<FieldCalibration, EllipsoidError>>,
        in_force: InForce,
        expected_field_ut: Option<f64>,
    ) -> HeldBack {
        let check = Check::of(blocks, expected_field_ut);
        let in_force_on_check = check.on_check(&in_force.calibration);
        let (train_calibration, train_error) = match train {
            Some(Ok(calibration)) => (Some(calibration), None),
            Some(Err(error)) => (None, Some(error)),
            None => (None, None),
        };
        HeldBack {
            n_train_samples: blocks.train.n_samples(),
            n_check_samples: blocks.n_check_seen,
            n_check_blocks: blocks.n_check_blocks(),
            train: train_calibration.map(|train| check.compare(&train, &in_force.calibration)),
            train_calibration,
            train_error,
            candidate: check.compare(candidate, &in_force.calibration),
            in_force,
            in_force_on_check,
        }
    }

    /// The figures for the fit line: "held back: |B| spread 1.1 % (in force 24 %)".
    pub fn summary(&self) -> String {
        let train = self.train.map_or(String::new(), |train| {
            format!(", {:.2} % fitted without them", train.on_check.spread_pct)
        });
        let field = match (
            self.candidate.on_check.rms_to_expected_ut,
            self.in_force_on_check.rms_to_expected_ut,
        ) {
            (Some(new_ut), Some(in_force_ut)) => {
                format!("; |B| − WMM RMS {new_ut:.1} µT (in force {in_force_ut:.1} µT)")
            }
            _ => String::new(),
        };
        format!(
            "held back ({} samples): |B| spread {:.2} %{train} (in force, {}: {:.2} %){field}",
            self.n_check_samples,
            self.candidate.on_check.spread_pct,
            self.in_force.short(),
            self.in_force_on_check.spread_pct
        )
    }

    /// Why the calibration is not better than the one in force on the held-back
    /// samples (each says what to do); empty when it is.
    pub fn reasons(&self) -> Vec<String> {
        if self.n_check_blocks < MIN_CHECK_BLOCKS {
            return vec![format!(
                "only {} samples are held back to compare the calibration to send with the \
                 one in force (at least {MIN_CHECK_BLOCKS} blocks of {BLOCK_LEN} are needed): \
                 keep turning the device",
                self.n_check_samples
            )];
        }
        if let Some(error) = &self.train_error {
            return vec![format!(
                "fitted without the held-back samples, no calibration could be made \
                 ({error}): keep turning the device through every direction"
            )];
        }
        let train_ok = self.train.is_none_or(|train| train.better);
        if self.candidate.better && train_ok {
            return Vec::new();
        }
        let train = self.train.map_or(String::new(), |train| {
            format!(" ({:.2} % fitted without them)", train.on_check.spread_pct)
        });
        let noise_pct = self.train.map_or(self.candidate.noise_pct, |train| {
            train.noise_pct.max(self.candidate.noise_pct)
        });
        let noise = if noise_pct >= 0.01 {
            format!("±{noise_pct:.2} %")
        } else {
            "under ±0.01 %".to_string()
        };
        vec![format!(
            "on the held-back samples the calibration to send leaves |B| varying by \
             {:.2} %{train}, not clearly less than the {:.2} % of {} (at least {:.0} % less, and \
             more than the noise of {noise}, is needed). Keep turning the device slowly, away \
             from metal, to improve on it",
            self.candidate.on_check.spread_pct,
            self.in_force_on_check.spread_pct,
            self.in_force.describe(),
            100.0 * MIN_RELATIVE_IMPROVEMENT
        )]
    }
}

/// Send it, or why not.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SendDecision {
    pub sendable: bool,
    /// Each failed condition, saying what to do: the verdict's, the held-back check's,
    /// then the bounds'.
    pub reasons: Vec<String>,
}

impl SendDecision {
    /// Good enough, better than the calibration in force on the held-back samples, and
    /// inside the bounds.
    pub fn of(
        verdict: &FieldVerdict,
        held_back: &HeldBack,
        calibration: &FieldCalibration,
        expected_field_ut: Option<f64>,
    ) -> SendDecision {
        let reasons: Vec<String> = verdict
            .reasons
            .iter()
            .cloned()
            .chain(held_back.reasons())
            .chain(acceptance_reasons(calibration, expected_field_ut))
            .collect();
        SendDecision {
            sendable: reasons.is_empty(),
            reasons,
        }
    }
}

/// The check samples, ready to measure calibrations on.
struct Check<'a> {
    samples_ut: &'a [Vector3<f64>],
    blocks: &'a [usize],
    expected_field_ut: Option<f64>,
}

impl<'a> Check<'a> {
    fn of(blocks: &'a Blocks, expected_field_ut: Option<f64>) -> Self {
        Check {
            samples_ut: &blocks.check_ut,
            blocks: &blocks.check_block,
            expected_field_ut,
        }
    }

    fn magnitudes(&self, calibration: &FieldCalibration) -> Vec<f64> {
        self.samples_ut
            .iter()
            .map(|&raw_ut| calibration.apply(raw_ut).norm())
            .collect()
    }

    fn on_check(&self, calibration: &FieldCalibration) -> OnCheck {
        let magnitudes = self.magnitudes(calibration);
        OnCheck {
            spread_pct: crate::base::stats::spread_pct(magnitudes.iter().copied())
                .unwrap_or(f64::NAN),
            rms_to_expected_ut: self.expected_field_ut.and_then(|expected_ut| {
                let squares: Vec<f64> = magnitudes
                    .iter()
                    .map(|magnitude| (magnitude - expected_ut).powi(2))
                    .filter(|square| square.is_finite())
                    .collect();
                (!squares.is_empty())
                    .then(|| (squares.iter().sum::<f64>() / squares.len() as f64).sqrt())
            }),
        }
    }

    /// `candidate` beside `in_force`: see [`compare`].
    fn compare(&self, candidate: &FieldCalibration, in_force: &FieldCalibration) -> Compared {
        let on_check = self.on_check(candidate);
        let (better, noise_pct) = compare(
            &self.magnitudes(candidate),
            &self.magnitudes(in_force),
            self.blocks,
        );
        Compared {
            on_check,
            noise_pct,
            better,
        }
    }
}

/// Whether the magnitudes `new` vary clearly less than `in_force` (the same samples,
/// in the same order, from the blocks `blocks`), and the noise on the difference of
/// their spreads (percentage points).
///
/// With `r = |c| / mean − 1` for each calibration, the squared spread is the mean of
/// `r²`; the paired difference `d = r_new² − r_in_force²` is summed per block, and its
/// mean's standard error taken over the blocks (a cluster estimate: samples of one
/// block are not independent, blocks nearly are). Since `s_new² − s_in_force² =
/// (s_new − s_in_force)(s_new + s_in_force)`, the standard error of the spreads'
/// difference is that of `d` over `s_new + s_in_force`. Better: `s_new ≤ (1 −`
/// [`MIN_RELATIVE_IMPROVEMENT`]`) s_in_force`, and `s_in_force − s_new` more than
/// [`NOISE_STANDARD_ERRORS`] of those.
pub fn compare(new: &[f64], in_force: &[f64], blocks: &[usize]) -> (bool, f64) {
    let normalised = |magnitudes: &[f64]| -> Option<Vec<f64>> {
        let mean = magnitudes.iter().sum::<f64>() / magnitudes.len() as f64;
        (mean.is_finite() && mean > 0.0).then(|| {
            magnitudes
                .iter()
                .map(|magnitude| (magnitude / mean - 1.0).powi(2))
                .collect()
        })
    };
    let (Some(new_sq), Some(in_force_sq)) = (normalised(new), normalised(in_force)) else {
        return (false, f64::NAN);
    };
    // Per block: the sum of d and the number of samples.
    let mut sums: Vec<(f64, f64)> = Vec::new();
    let mut previous_block = None;
    for ((new_sq, in_force_sq), &block) in new_sq.iter().zip(&in_force_sq).zip(blocks) {
        if previous_block != Some(block) {
            sums.push((0.0, 0.0));
            previous_block = Some(block);
        }
        if let Some(last) = sums.last_mut() {
            last.0 += new_sq - in_force_sq;
            last.1 += 1.0;
        }
    }
    let n_blocks = sums.len();
    let n_samples: f64 = sums.iter().map(|(_, n)| n).sum();
    if n_blocks < MIN_CHECK_BLOCKS || n_samples == 0.0 {
        return (false, f64::NAN);
    }
    let mean_d = sums.iter().map(|(sum, _)| sum).sum::<f64>() / n_samples;
    let variance = sums
        .iter()
        .map(|(sum, n)| (sum - n * mean_d).powi(2))
        .sum::<f64>()
        / (n_samples * n_samples)
        * n_blocks as f64
        / (n_blocks - 1) as f64;
    let s_new = (new_sq.iter().sum::<f64>() / new_sq.len() as f64).sqrt();
    let s_in_force = (in_force_sq.iter().sum::<f64>() / in_force_sq.len() as f64).sqrt();
    let noise = if s_new + s_in_force > 0.0 {
        NOISE_STANDARD_ERRORS * variance.sqrt() / (s_new + s_in_force)
    } else {
        0.0
    };
    let better =
        s_new <= (1.0 - MIN_RELATIVE_IMPROVEMENT) * s_in_force && s_in_force - s_new > noise;
    (better, 100.0 * noise)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_improvement_within_the_noise_or_the_margin_is_not_better() {
        // Four blocks of 100 samples; the new magnitudes vary 1 %, the ones in force 2 %.
        let blocks: Vec<usize> = (0..400).map(|idx| 2 * (idx / 100) + 1).collect();
        let wave = |amplitude: f64| -> Vec<f64> {
            (0..400)
                .map(|idx| 50.0 * (1.0 + amplitude * (idx as f64 * 0.7).sin()))
                .collect()
        };
        let (better, noise_pct) = compare(&wave(0.01), &wave(0.02), &blocks);
        assert!(better && noise_pct < 0.1, "{noise_pct}");
        // 3 % lower: inside the 5 % margin.
        assert!(!compare(&wave(0.0194), &wave(0.02), &blocks).0);
        // Better in two blocks, worse in the two others: the noise covers it.
        let mixed: Vec<f64> = wave(0.01)[..200]
            .iter()
            .chain(&wave(0.028)[200..])
            .copied()
            .collect();
        let (better, noise_pct) = compare(&mixed, &wave(0.02), &blocks);
        assert!(!better && noise_pct > 0.2, "{noise_pct}");
        // One block: no standard error, no comparison.
        assert!(!compare(&wave(0.01), &wave(0.02), &[1; 400]).0);
    }
}
