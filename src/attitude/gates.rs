//! When to trust the magnetometer and the accelerometer: the field's magnitude and dip
//! against the undisturbed field's, and the specific force's magnitude against
//! gravity's.
//!
//! ## The magnetic gate
//!
//! Iron near the sensor (a steel door, a radiator, a car) adds its own field. It
//! changes the field's direction, which is what the heading reads, and almost always
//! its magnitude and its angle below the horizontal (the dip) as well: those two are
//! measured without knowing the heading, so a disturbance shows in them before it bends
//! the heading (Michel et al. 2018, *On attitude estimation with smartphones*, §5.2,
//! who gate the magnetometer on both; Fusion AHRS gates on the heading's disagreement
//! instead). The undisturbed field is the calibrated sphere's radius (or the magnetic
//! model's intensity) and the model's inclination where the place is known, else the
//! median dip of the log's undisturbed samples; the tolerances are physical
//! ([`MAGNITUDE_TOLERANCE`], [`DIP_TOLERANCE_RAD`]), not the log's own spread: indoors
//! a disturbed field can be most of a log.
//!
//! A gate that reopens at the first clean sample lets the edges of a disturbance in, so
//! the field must stay clean for [`CLEAN_HOLD_S`] before it is used again.

use nalgebra::Vector3;
use serde::Serialize;

use crate::base::stats::median;
use crate::io::recording::Stream;

/// The field's magnitude may differ from the reference by this fraction before it
/// counts as disturbed: a calibration (the phone's own running one too) leaves a few
/// per cent, and a moving body's magnetometer lags its gyroscope. Chosen on the shared
/// attitude trials (8 % refused most samples of a phone walked in a pocket); the
/// direction's gate ([`QuasiStaticField`]) catches what this lets through.
pub const MAGNITUDE_TOLERANCE: f64 = 0.15;
/// Likewise for the dip (rad, 10°): it is measured with the filter's tilt, which is
/// good to a few degrees while a hand swings or a runner bounces.
pub const DIP_TOLERANCE_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// The field must stay undisturbed this long (s) before the heading is corrected again.
pub const CLEAN_HOLD_S: f64 = 0.5;

/// The undisturbed field the gate compares with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FieldReference {
    /// Magnitude of the calibrated field (µT).
    pub field_ut: f64,
    /// Angle below the horizontal (rad, positive down).
    pub dip_rad: f64,
    /// Fraction of `field_ut` beyond which the field is disturbed.
    pub magnitude_tolerance: f64,
    /// Dip difference (rad) beyond which the field is disturbed.
    pub dip_tolerance_rad: f64,
}

impl FieldReference {
    /// The reference from the log's own calibrated field: `field_ut` (the calibrated
    /// sphere's radius) or else the median magnitude, and the median dip of the samples
    /// whose magnitude is within [`MAGNITUDE_TOLERANCE`] of it (a disturbance changes
    /// both, so the undisturbed samples' dip is the field's), or `dip_rad` where known.
    /// `None` without a field sample that has a down direction beside it.
    pub fn of_log(
        field_in_body_ut: &Stream<Vector3<f64>>,
        down_in_body: &Stream<Vector3<f64>>,
        (field_ut, dip_rad): (Option<f64>, Option<f64>),
    ) -> Option<FieldReference> {
        let (magnitudes, dips) = magnitudes_and_dips(field_in_body_ut, down_in_body);
        FieldReference::of_samples(&magnitudes, &dips, (field_ut, dip_rad))
    }

    /// [`FieldReference::of_log`] from each field sample's magnitude (µT) and dip (rad),
    /// however they were paired with a down direction (a live session pairs each with
    /// the latest specific force).
    pub fn of_samples(
        magnitudes: &[f64],
        dips: &[f64],
        (field_ut, dip_rad): (Option<f64>, Option<f64>),
    ) -> Option<FieldReference> {
        let median_field_ut = median(&mut magnitudes.to_vec())?;
        let field_ut = field_ut
            .filter(|f| f.is_finite() && *f > 0.0)
            .unwrap_or(median_field_ut);
        let mut undisturbed_dips: Vec<f64> = magnitudes
            .iter()
            .zip(dips)
            .filter(|(magnitude, _)| (*magnitude / field_ut - 1.0).abs() <= MAGNITUDE_TOLERANCE)
            .map(|(_, dip)| *dip)
            .collect();
        let median_dip_rad =
            median(&mut undisturbed_dips).or_else(|| median(&mut dips.to_vec()))?;
        let dip_rad = dip_rad.filter(|d| d.is_finite()).unwrap_or(median_dip_rad);
        Some(FieldReference {
            field_ut,
            dip_rad,
            magnitude_tolerance: MAGNITUDE_TOLERANCE,
            dip_tolerance_rad: DIP_TOLERANCE_RAD,
        })
    }

    /// Whether a field of this magnitude and dip is the undisturbed one.
    pub fn holds(&self, field_ut: f64, dip_rad: f64) -> bool {
        (field_ut / self.field_ut - 1.0).abs() <= self.magnitude_tolerance
            && (dip_rad - self.dip_rad).abs() <= self.dip_tolerance_rad
    }
}

/// Each field sample's magnitude and dip, where a down direction is known beside it.
fn magnitudes_and_dips(
    field_in_body_ut: &Stream<Vector3<f64>>,
    down_in_body: &Stream<Vector3<f64>>,
) -> (Vec<f64>, Vec<f64>) {
    let mut magnitudes = Vec::with_capacity(field_in_body_ut.len());
    let mut dips = Vec::with_capacity(field_in_body_ut.len());
    for (&t_s, field) in field_in_body_ut.t_s.iter().zip(&field_in_body_ut.values) {
        let Some(down) = down_in_body.interpolate_at(t_s, 0.5) else {
            continue;
        };
        if let Some(dip) = dip_of(*field, down) {
            magnitudes.push(field.norm());
            dips.push(dip);
        }
    }
    (magnitudes, dips)
}

/// The field's angle below the horizontal, given the unit down direction in the same
/// axes; `None` for a zero field.
pub fn dip_of(field: Vector3<f64>, down: Vector3<f64>) -> Option<f64> {
    let norm = field.norm() * down.norm();
    (norm > 0.0 && norm.is_finite()).then(|| (field.dot(&down) / norm).clamp(-1.0, 1.0).asin())
}

/// The magnetic gate's state: open (the field is used) once the field has held for
/// [`CLEAN_HOLD_S`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagneticGate {
    reference: FieldReference,
    /// When the field last looked disturbed (s).
    last_disturbed_s: f64,
}

impl MagneticGate {
    pub fn new(reference: FieldReference) -> MagneticGate {
        MagneticGate {
            reference,
            last_disturbed_s: f64::NEG_INFINITY,
        }
    }

    pub fn reference(&self) -> &FieldReference {
        &self.reference
    }

    /// Compares with `reference` from now on (a live session's new fit), keeping when
    /// the field last looked disturbed.
    pub fn set_reference(&mut self, reference: FieldReference) {
        self.reference = reference;
    }

    /// Whether the field seen at `t_s` may correct the heading.
    pub fn open(&mut self, t_s: f64, field_ut: f64, dip_rad: f64) -> bool {
        if !self.reference.holds(field_ut, dip_rad) {
            self.last_disturbed_s = t_s;
            return false;
        }
        t_s - self.last_disturbed_s >= CLEAN_HOLD_S
    }
}

/// A quasi-static field (Afzal, Renaudin and Lachapelle 2011, *Use of Earth's magnetic
/// field for mitigating gyroscope errors regardless of magnetic perturbation*, Sensors
/// 11(12)): over a short time the gyroscope's attitude is good, so the field turned into
/// the navigation frame keeps its direction where the field is the Earth's alone. Iron
/// passed while walking turns it, although its magnitude and dip can stay within
/// tolerance; this gate closes then. The direction is averaged over blocks of
/// [`QUASI_STATIC_BLOCK_S`] (a swinging arm or a step turns the sample's direction back
/// and forth by the time between the magnetometer's and the gyroscope's samples; a
/// block averages that out) and the field is steady while the last
/// [`QUASI_STATIC_BLOCKS`] blocks agree within [`QUASI_STATIC_TOLERANCE_RAD`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct QuasiStaticField {
    /// The open block: its start and the sums of the direction's cosine and sine.
    block: Option<(f64, f64, f64)>,
    /// The mean directions of the last closed blocks, with their last samples' times.
    closed: std::collections::VecDeque<(f64, f64)>,
    steady: bool,
}

/// The block (s) over which the field's direction is averaged.
pub const QUASI_STATIC_BLOCK_S: f64 = 0.5;
/// How many successive blocks must agree.
pub const QUASI_STATIC_BLOCKS: usize = 3;
/// How far (rad, 6°) their directions may differ: a gyroscope drifts far less over a
/// second and a half, and a block's mean of an undisturbed field is good to a few
/// degrees while the body moves (3° refused almost every block of a swinging arm on the
/// shared attitude trials).
pub const QUASI_STATIC_TOLERANCE_RAD: f64 = 6.0 * std::f64::consts::PI / 180.0;

impl QuasiStaticField {
    /// Adds the direction seen at `t_s`; whether the last blocks agreed.
    pub fn steady(&mut self, t_s: f64, direction_rad: f64) -> bool {
        let (start_s, cos_sum, sin_sum) = self.block.get_or_insert((t_s, 0.0, 0.0));
        *cos_sum += direction_rad.cos();
        *sin_sum += direction_rad.sin();
        if t_s - *start_s >= QUASI_STATIC_BLOCK_S || t_s < *start_s {
            let (start_s, mean_rad) = (*start_s, sin_sum.atan2(*cos_sum));
            self.block = None;
            if self.closed.back().is_some_and(|&(end_s, _)| {
                !(start_s - end_s <= MAX_BLOCK_GAP_S && start_s >= end_s)
            }) {
                // A gap: the blocks before it say nothing of the field after it.
                self.closed.clear();
            }
            self.closed.push_back((t_s, mean_rad));
            while self.closed.len() > QUASI_STATIC_BLOCKS {
                self.closed.pop_front();
            }
            self.steady = self.closed.len() == QUASI_STATIC_BLOCKS
                && self.closed.iter().all(|&(_, block_rad)| {
                    crate::base::angle::wrap_to_pi(block_rad - mean_rad).abs()
                        <= QUASI_STATIC_TOLERANCE_RAD
                });
        }
        self.steady
    }
}

/// Successive blocks further apart than this (s, from one's last sample to the next's
/// first) are not compared: the field was not seen between them. A log of one sample a
/// second still makes contiguous blocks.
pub const MAX_BLOCK_GAP_S: f64 = 1.5;

/// How much the body's own acceleration corrupts the specific force's direction: the
/// spread of its magnitude about gravity's, smoothed over about [`ACCELERATION_TAU_S`].
pub const ACCELERATION_TAU_S: f64 = 0.5;

/// An exponential mean of `(|f| − g)²`, whose root is the acceleration's share of the
/// specific force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerationLevel {
    mean_square_mps2: f64,
    last_t_s: Option<f64>,
}

impl AccelerationLevel {
    pub fn new() -> AccelerationLevel {
        AccelerationLevel {
            mean_square_mps2: 0.0,
            last_t_s: None,
        }
    }

    /// Adds the sample at `t_s`; returns the RMS of the acceleration (m/s²).
    pub fn add(&mut self, t_s: f64, specific_force_mps2: f64, gravity_mps2: f64) -> f64 {
        let square = (specific_force_mps2 - gravity_mps2).powi(2);
        let weight = match self.last_t_s {
            Some(last_s) if t_s > last_s => 1.0 - (-(t_s - last_s) / ACCELERATION_TAU_S).exp(),
            Some(_) => 0.0,
            None => 1.0,
        };
        self.last_t_s = Some(t_s);
        self.mean_square_mps2 += weight * (square - self.mean_square_mps2);
        // The sample itself counts as well: a single jolt is not averaged away.
        self.mean_square_mps2.max(square).sqrt()
    }
}

impl Default for AccelerationLevel {
    fn default() -> Self {
        Self::new()
    }
}

/// How long (s) the heading's error from the field is remembered: about the time over
/// which the filter follows the field rather than the gyroscope (the heading noise
/// density over the gyroscope's, 0.05 rad·√s over 0.005 rad/√s).
pub const FIELD_ERROR_TAU_S: f64 = 10.0;
/// How long (s) the square of that error is averaged over: one window's mean tells its
/// size poorly (two of three components seen once), several windows' tell it well.
pub const FIELD_ERROR_MEMORY_S: f64 = 60.0;

/// The heading error the fused field carries, from what the gates can see of it.
///
/// A disturbance `δ` added to the Earth's field has three components: along the field
/// (it changes the magnitude), across it in the vertical plane (it changes the dip) and
/// across it horizontally (it turns the heading by `δ_h / B_h`, `B_h` the horizontal
/// field). The gates see the first two and let through whatever stays within their
/// tolerances; the third is what the heading takes. The filter follows the field over
/// about [`FIELD_ERROR_TAU_S`], so its yaw takes the disturbance's mean over that time,
/// not each sample's: the first two components are averaged (with their signs) over the
/// fused samples of that time, and with no direction preferred the third's square is
/// the mean of their squares, `(ΔB̄² + (B·Δdip)̄²) / 2`. One window shows that square
/// poorly (two of three components, seen once), so it is averaged in turn over
/// [`FIELD_ERROR_MEMORY_S`]. A calibration's residue shows in the same way (the
/// corrected magnitude varying with the orientation).
///
/// The filter's own yaw variance treats each field sample's error as independent of the
/// next, so it shrinks as samples come; a disturbance or a calibration's residue lasts
/// for seconds and does not average away. The stated yaw σ adds this in quadrature
/// (on the nine TYREX trials the filter's own σ alone covered 17-55 % of the errors
/// within 1σ and 29-80 % within 2σ; with this, 51-99 % and 94-100 %: `bench/attitude.sh`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FieldErrorLevel {
    /// The exponential sums of the magnitude's and of the dip's departure (µT) and of
    /// their weights: the mean is one over the other, so that the first samples are not
    /// taken as an average of zeros.
    along: ExponentialMean,
    across: ExponentialMean,
    /// The same of the heading component's square that their means give (µT²).
    square: ExponentialMean,
    last_t_s: Option<f64>,
}

/// An exponential mean `Σ wᵢ·xᵢ / Σ wᵢ` with each weight decaying over time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct ExponentialMean {
    weighted_sum: f64,
    total_weight: f64,
}

impl ExponentialMean {
    /// Adds `value` after the older ones decayed by `keep` (e^(−Δt/τ)).
    fn add(&mut self, value: f64, keep: f64) {
        self.weighted_sum = keep * self.weighted_sum + (1.0 - keep) * value;
        self.total_weight = keep * self.total_weight + (1.0 - keep);
    }

    fn mean(&self) -> f64 {
        if self.total_weight > 0.0 {
            self.weighted_sum / self.total_weight
        } else {
            0.0
        }
    }
}

impl FieldErrorLevel {
    /// Adds a fused sample of magnitude `field_ut` and dip `dip_rad`, against `reference`.
    pub fn add(&mut self, t_s: f64, field_ut: f64, dip_rad: f64, reference: &FieldReference) {
        let along_ut = field_ut - reference.field_ut;
        let across_ut = reference.field_ut * (dip_rad - reference.dip_rad);
        if !(along_ut.is_finite() && across_ut.is_finite()) {
            return;
        }
        // How much of the older samples' weight is kept. The first sample only starts
        // the clock (its weight would be its interval's, which is not known yet); one
        // out of time order is not counted.
        let Some(last_s) = self.last_t_s.filter(|&last_s| t_s > last_s) else {
            if self.last_t_s.is_none() {
                self.last_t_s = Some(t_s);
            }
            return;
        };
        let keep = |tau_s: f64| (-(t_s - last_s) / tau_s).exp();
        let (keep_fast, keep_slow) = (keep(FIELD_ERROR_TAU_S), keep(FIELD_ERROR_MEMORY_S));
        self.last_t_s = Some(t_s);
        self.along.add(along_ut, keep_fast);
        self.across.add(across_ut, keep_fast);
        let square = 0.5 * (self.along.mean().powi(2) + self.across.mean().powi(2));
        self.square.add(square, keep_slow);
    }

    /// The heading's 1σ (rad) from it, at `reference`'s horizontal field; at most π/2.
    pub fn heading_sigma_rad(&self, reference: &FieldReference) -> f64 {
        let horizontal_ut = reference.field_ut * reference.dip_rad.cos();
        let across_ut = self.square.mean().max(0.0).sqrt();
        if horizontal_ut > 0.0 {
            across_ut.atan2(horizontal_ut)
        } else {
            std::f64::consts::FRAC_PI_2
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> FieldReference {
        FieldReference {
            field_ut: 50.0,
            dip_rad: 1.0,
            magnitude_tolerance: 0.05,
            dip_tolerance_rad: 0.05,
        }
    }

    #[test]
    fn the_gate_closes_on_magnitude_or_dip_and_reopens_after_the_hold() {
        let mut gate = MagneticGate::new(reference());
        assert!(gate.open(0.0, 50.0, 1.0));
        assert!(!gate.open(1.0, 55.0, 1.0), "10 % stronger");
        assert!(!gate.open(1.1, 50.0, 1.1), "dip 0.1 rad off");
        assert!(!gate.open(1.2, 50.0, 1.0), "clean, but within the hold");
        assert!(gate.open(1.1 + CLEAN_HOLD_S, 50.0, 1.0));
    }

    #[test]
    fn the_reference_is_the_median_of_the_undisturbed_samples() {
        let mut field = Stream::default();
        let mut down = Stream::default();
        for idx in 0..1000 {
            let t_s = idx as f64 * 0.01;
            down.push(t_s, Vector3::new(0.0, 0.0, 1.0));
            // 45° dip, 40 µT, with one disturbed stretch of 10 %.
            let scale = if (400..500).contains(&idx) {
                2.0
            } else {
                1.0 + 0.001 * ((idx % 7) as f64 - 3.0)
            };
            field.push(t_s, Vector3::new(40.0, 0.0, 40.0) * scale / 2f64.sqrt());
        }
        let reference = FieldReference::of_log(&field, &down, (None, None)).expect("samples");
        assert!(
            (reference.field_ut - 40.0).abs() < 0.2,
            "{}",
            reference.field_ut
        );
        assert!((reference.dip_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
        assert!(!reference.holds(80.0, reference.dip_rad));
    }

    #[test]
    fn the_acceleration_level_follows_the_spread_about_gravity() {
        let mut level = AccelerationLevel::new();
        let mut last = 0.0;
        for idx in 0..400 {
            let sign = if idx % 2 == 0 { 1.0 } else { -1.0 };
            last = level.add(idx as f64 * 0.01, 9.81 + 2.0 * sign, 9.81);
        }
        assert!((last - 2.0).abs() < 1e-6, "{last}");
    }

    /// The level after `n` fused samples at 50 Hz of the reference's dip, sample `idx`
    /// of magnitude `magnitude_ut(idx)`.
    fn fed(
        reference: &FieldReference,
        n: usize,
        magnitude_ut: impl Fn(usize) -> f64,
    ) -> FieldErrorLevel {
        let mut level = FieldErrorLevel::default();
        for idx in 0..n {
            level.add(
                idx as f64 * 0.02,
                magnitude_ut(idx),
                reference.dip_rad,
                reference,
            );
        }
        level
    }

    #[test]
    fn a_field_that_keeps_its_magnitude_and_dip_carries_no_heading_error() {
        let reference = reference();
        let level = fed(&reference, 500, |_| reference.field_ut);
        assert_eq!(level.heading_sigma_rad(&reference), 0.0);
    }

    #[test]
    fn a_lasting_disturbance_counts_and_a_flickering_one_averages_away() {
        let reference = reference();
        // 5 µT along the field for two minutes: the heading takes as much across it,
        // (25 / 2)^½ µT over the horizontal field.
        let lasting = fed(&reference, 6000, |_| reference.field_ut + 5.0);
        let horizontal_ut = reference.field_ut * reference.dip_rad.cos();
        let expected_rad = (12.5f64.sqrt() / horizontal_ut).atan();
        assert!((lasting.heading_sigma_rad(&reference) - expected_rad).abs() < 1e-3 * expected_rad);
        // ±5 µT from one sample to the next: the filter averages it out, and so does this.
        let flickering = fed(&reference, 6000, |idx| {
            reference.field_ut + if idx % 2 == 0 { 5.0 } else { -5.0 }
        });
        assert!(flickering.heading_sigma_rad(&reference) < 0.05 * expected_rad);
    }
}
