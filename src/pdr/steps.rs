//! Step detection on the magnitude of specific force.
//!
//! Chen et al., *A unified heading error model and step length estimation for PDR*,
//! Section III: "a combination of three methods: sliding window, peak detection and
//! zero-crossing, \[which\] can calculate the statistics of acceleration per step
//! simultaneously". Here, on samples at any rate (times, not sample counts, set every
//! window):
//!
//! 1. `|f|`, the magnitude of specific force, so that the phone's orientation (in hand,
//!    flat, in a pocket) does not matter;
//! 2. a zero-phase low-pass (a first-order filter run forwards and backwards), which
//!    merges the heel-strike and push-off peaks of one step;
//! 3. the **sliding window**: a centred moving mean over `detrend_window_s` is
//!    subtracted (gravity and its slow drift), and a centred moving RMS over
//!    `threshold_window_s` sets the hysteresis band `h = max(floor, fraction × RMS)`;
//! 4. **zero crossing**: a step starts where the detrended signal crosses zero upwards
//!    after it was below `−h` (the crossing time is interpolated between samples);
//! 5. **peak detection**: the bounce after the crossing must rise above `+h`, and its
//!    maximum is the step's peak.
//!
//! Each accepted bounce is one step, so a walk of n bounces gives n steps: a step ends
//! at the next step's start, or, for the last step of a bout (no start within
//! `max_step_s`), after the duration of the step before it. Per step it records what
//! the step-length models of Eq. 2-3 and the paper's neural network take: the step
//! frequency (SF), the variance of `|f|` (SV), and the largest and smallest `|f|` after
//! a gentler low-pass (Amax, Amin).

use nalgebra::Vector3;
use serde::Serialize;

use crate::io::recording::Stream;

/// Choices of the detector. The defaults hold for a phone in hand or flat, walking at
/// 1.2-2.5 steps per second, sampled at 25-200 Hz.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepOptions {
    /// Cut-off of the low-pass that detection runs on (Hz).
    pub lowpass_hz: f64,
    /// Cut-off of the gentler low-pass whose extremes are Amax and Amin (Hz): it takes
    /// the sensor noise off the peaks without flattening them.
    pub stats_lowpass_hz: f64,
    /// Window of the moving mean that is subtracted (s).
    pub detrend_window_s: f64,
    /// Window of the moving RMS that scales the hysteresis band (s).
    pub threshold_window_s: f64,
    /// The hysteresis band as a fraction of the moving RMS ...
    pub threshold_fraction: f64,
    /// ... and never below this (m/s²), so that a phone at rest counts no steps.
    pub threshold_floor_mps2: f64,
    /// Steps shorter than this are merged into the one before (s).
    pub min_step_s: f64,
    /// A gap longer than this between two step starts ends a bout of walking (s).
    pub max_step_s: f64,
}

impl Default for StepOptions {
    fn default() -> Self {
        StepOptions {
            lowpass_hz: 3.0,
            stats_lowpass_hz: 6.0,
            detrend_window_s: 4.0,
            threshold_window_s: 2.0,
            threshold_fraction: 0.3,
            threshold_floor_mps2: 0.25,
            min_step_s: 0.25,
            max_step_s: 1.5,
        }
    }
}

/// One detected step, with the statistics of acceleration over it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Step {
    pub t_start_s: f64,
    pub t_end_s: f64,
    /// Time of the bounce's peak.
    pub t_peak_s: f64,
    /// SF: 1 / duration (Hz).
    pub frequency_hz: f64,
    /// SV: variance of `|f|` over the step ((m/s²)²).
    pub variance_mps2_sq: f64,
    /// Amax and Amin: the largest and smallest low-passed `|f|` over the step (m/s²).
    pub a_max_mps2: f64,
    pub a_min_mps2: f64,
    /// Whether the step closed a bout (its end is estimated, not observed).
    pub ends_bout: bool,
}

impl Step {
    pub fn duration_s(&self) -> f64 {
        self.t_end_s - self.t_start_s
    }

    pub fn mid_s(&self) -> f64 {
        0.5 * (self.t_start_s + self.t_end_s)
    }
}

/// The steps of a recording and what the user should know about them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepDetection {
    pub steps: Vec<Step>,
    /// Walking bouts (runs of steps without a pause longer than `max_step_s`).
    pub n_bouts: usize,
    pub notes: Vec<String>,
}

impl StepDetection {
    /// Mean step frequency over the steps whose end was observed (Hz).
    pub fn mean_frequency_hz(&self) -> Option<f64> {
        mean_frequency_hz(&self.steps)
    }
}

/// Mean step frequency over the steps whose end was observed (Hz).
pub fn mean_frequency_hz(steps: &[Step]) -> Option<f64> {
    let observed: Vec<f64> = steps
        .iter()
        .filter(|step| !step.ends_bout)
        .map(|step| step.frequency_hz)
        .collect();
    (!observed.is_empty()).then(|| observed.iter().sum::<f64>() / observed.len() as f64)
}

/// The index ranges of the bouts of walking: a bout ends at a step that `ends_bout`
/// (no step starts within the detector's `max_step_s` after it).
pub fn bout_ranges(steps: &[Step]) -> Vec<std::ops::Range<usize>> {
    let mut bouts = Vec::new();
    let mut start = 0;
    for (idx, step) in steps.iter().enumerate() {
        if step.ends_bout || idx + 1 == steps.len() {
            bouts.push(start..idx + 1);
            start = idx + 1;
        }
    }
    bouts
}

/// Detects the steps in the accelerometer stream (specific force in the body frame).
/// Samples with a non-finite value or a time that does not increase are left out and
/// counted in a note.
pub fn detect_steps(acc: &Stream<Vector3<f64>>, options: &StepOptions) -> StepDetection {
    let mut notes = Vec::new();
    let mut t_s = Vec::with_capacity(acc.len());
    let mut magnitude = Vec::with_capacity(acc.len());
    let mut n_left_out = 0usize;
    for (&sample_t_s, value) in acc.t_s.iter().zip(&acc.values) {
        let norm = value.norm();
        let increases = t_s.last().is_none_or(|&last_s| sample_t_s > last_s);
        if norm.is_finite() && sample_t_s.is_finite() && increases {
            t_s.push(sample_t_s);
            magnitude.push(norm);
        } else {
            n_left_out += 1;
        }
    }
    if n_left_out > 0 {
        notes.push(format!(
            "{n_left_out} accelerometer samples with a non-finite value or a repeated time were left out of step detection."
        ));
    }
    if t_s.len() < 3 {
        notes.push("Fewer than 3 accelerometer samples: no steps can be detected.".to_string());
        return StepDetection {
            steps: Vec::new(),
            n_bouts: 0,
            notes,
        };
    }
    let smooth = zero_phase_lowpass(&t_s, &magnitude, options.lowpass_hz);
    let gentle = zero_phase_lowpass(&t_s, &magnitude, options.stats_lowpass_hz);
    let trend = centred_moving_mean(&t_s, &smooth, options.detrend_window_s);
    let detrended: Vec<f64> = smooth.iter().zip(&trend).map(|(s, m)| s - m).collect();
    let squares: Vec<f64> = detrended.iter().map(|d| d * d).collect();
    let mean_square = centred_moving_mean(&t_s, &squares, options.threshold_window_s);

    // Bounces: (start time, index of the peak). The detector is armed at the start and
    // whenever the signal has been below the band, so the first bounce of a bout (which
    // rises from rest) counts as well as the later ones.
    let mut starts: Vec<(f64, usize)> = Vec::new();
    let mut armed = true;
    let mut last_crossing_s: Option<f64> = None;
    let mut in_bounce = false;
    for idx in 0..t_s.len() {
        let band = options
            .threshold_floor_mps2
            .max(options.threshold_fraction * mean_square[idx].max(0.0).sqrt());
        let value = detrended[idx];
        if idx > 0 && detrended[idx - 1] <= 0.0 && value > 0.0 {
            let (t0, t1) = (t_s[idx - 1], t_s[idx]);
            let (v0, v1) = (detrended[idx - 1], value);
            last_crossing_s = Some(t0 + (t1 - t0) * (-v0) / (v1 - v0));
        }
        if value < -band {
            in_bounce = false;
            armed = true;
        } else if value > band && armed {
            armed = false;
            in_bounce = true;
            let start_s = last_crossing_s.unwrap_or(t_s[idx]);
            let too_soon = starts
                .last()
                .is_some_and(|&(previous_s, _)| start_s - previous_s < options.min_step_s);
            if !too_soon {
                starts.push((start_s, idx));
            }
        }
        // The peak of the current bounce (a bounce that came too soon extends the last).
        if in_bounce {
            if let Some(last) = starts.last_mut() {
                if value > detrended[last.1] {
                    last.1 = idx;
                }
            }
        }
    }

    let mut steps = Vec::with_capacity(starts.len());
    let mut n_bouts = 0usize;
    let mut previous_duration_s: Option<f64> = None;
    for (k, &(start_s, peak)) in starts.iter().enumerate() {
        let next_start_s = starts.get(k + 1).map(|&(s, _)| s);
        let (end_s, ends_bout) = match next_start_s {
            Some(next_s) if next_s - start_s <= options.max_step_s => (next_s, false),
            _ => {
                let guess_s = previous_duration_s.unwrap_or(1.0 / 1.8);
                (start_s + guess_s, true)
            }
        };
        if k == 0 || previous_duration_s.is_none() {
            n_bouts += 1;
        }
        let duration_s = end_s - start_s;
        previous_duration_s = (!ends_bout).then_some(duration_s);
        let span = index_span(&t_s, start_s, end_s);
        let (variance, a_max, a_min) = span_statistics(&magnitude[span.clone()], &gentle[span]);
        steps.push(Step {
            t_start_s: start_s,
            t_end_s: end_s,
            t_peak_s: t_s.get(peak).copied().unwrap_or(start_s),
            frequency_hz: 1.0 / duration_s,
            variance_mps2_sq: variance,
            a_max_mps2: a_max,
            a_min_mps2: a_min,
            ends_bout,
        });
    }
    StepDetection {
        steps,
        n_bouts,
        notes,
    }
}

/// The indices of samples with `start_s ≤ t < end_s` (at least one sample when the
/// span holds any time at all).
fn index_span(t_s: &[f64], start_s: f64, end_s: f64) -> std::ops::Range<usize> {
    let first = t_s.partition_point(|&t| t < start_s);
    let last = t_s
        .partition_point(|&t| t < end_s)
        .max(first + 1)
        .min(t_s.len());
    first.min(last)..last
}

/// (variance of the raw magnitude, max and min of the low-passed one) over a span.
fn span_statistics(raw: &[f64], smooth: &[f64]) -> (f64, f64, f64) {
    if raw.is_empty() {
        return (0.0, f64::NAN, f64::NAN);
    }
    let n = raw.len() as f64;
    let mean = raw.iter().sum::<f64>() / n;
    let variance = raw.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    let a_max = smooth.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let a_min = smooth.iter().copied().fold(f64::INFINITY, f64::min);
    (variance, a_max, a_min)
}

/// A first-order low-pass run forwards then backwards (zero phase), with the gain of
/// each sample from its own time step, so irregular sampling is fine.
fn zero_phase_lowpass(t_s: &[f64], values: &[f64], cutoff_hz: f64) -> Vec<f64> {
    let tau_s = 1.0 / (std::f64::consts::TAU * cutoff_hz.max(1e-3));
    let mut out = values.to_vec();
    for idx in 1..out.len() {
        let dt_s = t_s[idx] - t_s[idx - 1];
        let gain = dt_s / (tau_s + dt_s);
        out[idx] = out[idx - 1] + gain * (out[idx] - out[idx - 1]);
    }
    for idx in (0..out.len().saturating_sub(1)).rev() {
        let dt_s = t_s[idx + 1] - t_s[idx];
        let gain = dt_s / (tau_s + dt_s);
        out[idx] = out[idx + 1] + gain * (out[idx] - out[idx + 1]);
    }
    out
}

/// The mean of `values` over the samples within `window_s / 2` of each sample's time.
fn centred_moving_mean(t_s: &[f64], values: &[f64], window_s: f64) -> Vec<f64> {
    let half_s = 0.5 * window_s;
    let mut out = Vec::with_capacity(values.len());
    let (mut lo, mut hi) = (0usize, 0usize);
    let mut sum = 0.0;
    for &centre_s in t_s {
        while hi < t_s.len() && t_s[hi] <= centre_s + half_s {
            sum += values[hi];
            hi += 1;
        }
        while lo < hi && t_s[lo] < centre_s - half_s {
            sum -= values[lo];
            lo += 1;
        }
        out.push(sum / (hi - lo).max(1) as f64);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::STANDARD_GRAVITY_MPS2;

    /// A walk of `n_steps` bounces at `freq_hz` with `amp` (m/s²), sampled at `rate_hz`,
    /// with a second of rest before and after.
    fn bouncing(n_steps: usize, freq_hz: f64, amp: f64, rate_hz: f64) -> Stream<Vector3<f64>> {
        let mut stream = Stream::default();
        let walk_s = n_steps as f64 / freq_hz;
        let total_s = walk_s + 2.0;
        let n = (total_s * rate_hz) as usize;
        for idx in 0..n {
            let t = idx as f64 / rate_hz;
            let phase = (t - 1.0) * freq_hz * std::f64::consts::TAU;
            let bounce = if (1.0..1.0 + walk_s).contains(&t) {
                amp * (phase.sin() + 0.3 * (2.0 * phase + 0.5).sin())
            } else {
                0.0
            };
            // The phone held flat: gravity on z, the bounce along it.
            stream.push(t, Vector3::new(0.1, -0.2, -STANDARD_GRAVITY_MPS2 - bounce));
        }
        stream
    }

    #[test]
    fn counts_every_bounce_at_50_and_100_hz() {
        for rate_hz in [50.0, 100.0] {
            for freq_hz in [1.4, 1.8, 2.3] {
                let detection = detect_steps(
                    &bouncing(40, freq_hz, 2.0, rate_hz),
                    &StepOptions::default(),
                );
                let starts: Vec<String> = detection
                    .steps
                    .iter()
                    .map(|s| format!("{:.2}", s.t_start_s))
                    .collect();
                assert_eq!(
                    detection.steps.len(),
                    40,
                    "{rate_hz} Hz, {freq_hz} Hz steps: {starts:?}"
                );
                assert_eq!(detection.n_bouts, 1);
                let mean = detection.mean_frequency_hz().expect("steps");
                assert!((mean - freq_hz).abs() < 0.02, "{mean} vs {freq_hz}");
            }
        }
    }

    #[test]
    fn a_phone_at_rest_counts_no_steps() {
        let mut stream = Stream::default();
        let mut rng = crate::base::rng::SplitMix64::new(3);
        for idx in 0..3000 {
            let noise = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * 0.05;
            stream.push(
                idx as f64 / 50.0,
                Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2) + noise,
            );
        }
        assert!(detect_steps(&stream, &StepOptions::default())
            .steps
            .is_empty());
    }

    #[test]
    fn per_step_statistics_follow_the_bounce() {
        let detection = detect_steps(&bouncing(20, 2.0, 3.0, 100.0), &StepOptions::default());
        let middle = detection.steps[10];
        // Peak to peak of sin + 0.3 sin(2φ + 0.5) is about 2.3 × amplitude, a little
        // less after the low-pass.
        let peak_to_peak = middle.a_max_mps2 - middle.a_min_mps2;
        assert!((5.5..7.0).contains(&peak_to_peak), "{peak_to_peak}");
        assert!((middle.duration_s() - 0.5).abs() < 0.01, "{middle:?}");
        assert!(middle.variance_mps2_sq > 3.0, "{middle:?}");
        assert!(detection.steps.last().is_some_and(|step| step.ends_bout));
    }

    #[test]
    fn bad_samples_are_left_out_and_said() {
        let mut stream = bouncing(10, 2.0, 2.0, 50.0);
        stream.values[100] = Vector3::new(f64::NAN, 0.0, 0.0);
        stream.t_s[200] = stream.t_s[199];
        let detection = detect_steps(&stream, &StepOptions::default());
        assert_eq!(detection.steps.len(), 10);
        assert!(
            detection.notes[0].contains("2 accelerometer samples"),
            "{:?}",
            detection.notes
        );
        let empty = detect_steps(&Stream::default(), &StepOptions::default());
        assert!(empty.steps.is_empty() && !empty.notes.is_empty());
    }
}
