//! Time alignment: the streams of a recording, each at its own rate and clock, sampled
//! onto one timeline for the algorithms that need synchronous samples.
//!
//! Every stream is linearly interpolated at each time of the timeline (headings along
//! the shorter arc). Nothing is extrapolated: a time before a stream's first sample or
//! after its last gets `None` for that stream, and so does a time inside a gap longer
//! than `max_gap_s` (missing data is not invented). Jittery or buffered timestamps (a
//! burst of samples, then a pause) need nothing special: interpolation uses each
//! sample's own time.

use nalgebra::Vector3;

use crate::recording::{Recording, Stream};

/// One instant of the common timeline, with every stream's value there, if it has one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlignedSample {
    pub t_s: f64,
    pub acc_in_body_mps2: Option<Vector3<f64>>,
    pub gyro_in_body_radps: Option<Vector3<f64>>,
    pub mag_in_body_ut: Option<Vector3<f64>>,
    pub temp_c: Option<f64>,
    pub ref_heading_rad: Option<f64>,
}

/// Samples the recording's streams at the times of `timeline_s`.
pub fn align(recording: &Recording, timeline_s: &[f64], max_gap_s: f64) -> Vec<AlignedSample> {
    timeline_s
        .iter()
        .map(|&t_s| AlignedSample {
            t_s,
            acc_in_body_mps2: recording.acc_in_body_mps2.interpolate_at(t_s, max_gap_s),
            gyro_in_body_radps: recording.gyro_in_body_radps.interpolate_at(t_s, max_gap_s),
            mag_in_body_ut: recording.mag_in_body_ut.interpolate_at(t_s, max_gap_s),
            temp_c: recording.temp_c.interpolate_at(t_s, max_gap_s),
            ref_heading_rad: recording
                .ref_heading_rad
                .interpolate_angle_at(t_s, max_gap_s),
        })
        .collect()
}

/// A regular timeline at `rate_hz` over the span where all the given streams have data
/// (the latest first sample to the earliest last sample); empty when they do not
/// overlap or the rate is not positive.
pub fn common_timeline<T>(streams: &[&Stream<T>], rate_hz: f64) -> Vec<f64> {
    let start_s = streams
        .iter()
        .filter_map(|stream| stream.t_s.first().copied())
        .fold(f64::NEG_INFINITY, f64::max);
    let end_s = streams
        .iter()
        .filter_map(|stream| stream.t_s.last().copied())
        .fold(f64::INFINITY, f64::min);
    // Written so that NaN rates or times also give an empty timeline.
    let usable = rate_hz.is_finite()
        && rate_hz > 0.0
        && end_s.is_finite()
        && start_s.is_finite()
        && end_s >= start_s;
    if streams.iter().any(|stream| stream.is_empty()) || !usable {
        return Vec::new();
    }
    let n_samples = ((end_s - start_s) * rate_hz).floor() as usize + 1;
    (0..n_samples)
        .map(|idx| start_s + idx as f64 / rate_hz)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_of_different_rates_meet_on_one_timeline() {
        let mut recording = Recording::default();
        // Magnetometer at 10 Hz, accelerometer at 4 Hz with jitter, x = time.
        for idx in 0..=20 {
            let t_s = idx as f64 * 0.1;
            recording
                .mag_in_body_ut
                .push(t_s, Vector3::new(t_s, 0.0, 0.0));
        }
        for (idx, jitter_s) in [0.0, 0.01, -0.02, 0.0, 0.015, 0.0, -0.01, 0.0, 0.0]
            .iter()
            .enumerate()
        {
            let t_s = idx as f64 * 0.25 + jitter_s;
            recording
                .acc_in_body_mps2
                .push(t_s, Vector3::new(t_s, 0.0, -9.81));
        }
        let timeline = common_timeline(
            &[&recording.mag_in_body_ut, &recording.acc_in_body_mps2],
            20.0,
        );
        assert_eq!(timeline.first().copied(), Some(0.0));
        assert!(timeline.last().copied().unwrap_or(0.0) <= 2.0);
        for sample in align(&recording, &timeline, 0.5) {
            let acc = sample
                .acc_in_body_mps2
                .expect("inside the accelerometer's span");
            let mag = sample
                .mag_in_body_ut
                .expect("inside the magnetometer's span");
            assert!(
                (acc.x - sample.t_s).abs() < 1e-9 && (mag.x - sample.t_s).abs() < 1e-9,
                "{sample:?}"
            );
        }
    }

    #[test]
    fn nothing_is_extrapolated_or_bridged() {
        let mut recording = Recording::default();
        for t_s in [1.0, 2.0, 10.0, 11.0] {
            recording.temp_c.push(t_s, 20.0 + t_s);
        }
        let aligned = align(&recording, &[0.5, 1.5, 5.0, 10.5, 12.0], 2.0);
        let temps: Vec<Option<f64>> = aligned.iter().map(|sample| sample.temp_c).collect();
        assert_eq!(temps, vec![None, Some(21.5), None, Some(30.5), None]);
        assert!(
            aligned.iter().all(|sample| sample.mag_in_body_ut.is_none()),
            "an empty stream stays empty"
        );
    }

    #[test]
    fn streams_that_do_not_overlap_have_no_common_timeline() {
        let mut early = Stream::default();
        early.push(0.0, 1.0);
        early.push(1.0, 1.0);
        let mut late = Stream::default();
        late.push(5.0, 1.0);
        late.push(6.0, 1.0);
        assert!(common_timeline(&[&early, &late], 10.0).is_empty());
        assert!(common_timeline(&[&early], 0.0).is_empty());
        assert_eq!(common_timeline(&[&early], 2.0), vec![0.0, 0.5, 1.0]);
    }
}
