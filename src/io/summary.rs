//! Stream summaries: what an import found, per stream, for the user to check against
//! what they recorded (count, rate, duration, gaps, repeated times, magnitude). Each
//! pass over a stream runs in four independent lanes merged at the end, not one chain
//! of dependent additions (a test holds them to one pass's figures).

use nalgebra::Vector3;
use serde::Serialize;

use crate::io::recording::{Recording, Stream};

/// One stream of a recording, summarised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamSummary {
    pub stream: &'static str,
    pub unit: &'static str,
    pub n_samples: usize,
    pub duration_s: f64,
    /// Samples per second over the stream's duration (not from the median interval:
    /// buffered sensors deliver in bursts); `None` for fewer than two samples.
    pub rate_hz: Option<f64>,
    /// Intervals longer than three mean intervals (and than 0.1 s).
    pub n_gaps: usize,
    pub largest_gap_s: f64,
    /// Samples that share their time with the one before.
    pub n_repeated_times: usize,
    /// Mean magnitude of a vector stream (|B| in µT, |f| in m/s², |ω| in rad/s).
    pub mean_magnitude: Option<f64>,
}

/// Summaries of the streams of a recording that hold any samples. A long recording is
/// summarised on two threads ([`crate::base::par`]): each stream is a pass over memory the
/// import has just written (a 100 MB CSV's 135 MB of samples: 14 ms on one core).
pub fn summarize(recording: &Recording) -> Vec<StreamSummary> {
    let vectors: [(&'static str, &'static str, &Stream<Vector3<f64>>); 4] = [
        ("accelerometer", "m/s²", &recording.acc_in_body_mps2),
        ("gyroscope", "rad/s", &recording.gyro_in_body_radps),
        ("magnetometer", "µT", &recording.mag_in_body_ut),
        (
            "magnetometer bias (device's own)",
            "µT",
            &recording.mag_bias_in_body_ut,
        ),
    ];
    let times: [(&'static str, &'static str, &[f64]); 8] = [
        ("temperature", "°C", &recording.temp_c.t_s),
        ("pressure", "hPa", &recording.pressure_hpa.t_s),
        ("GNSS", "fix", &recording.gnss.t_s),
        ("attitude (device's own)", "rad", &recording.attitude.t_s),
        (
            "heading (device's own)",
            "rad",
            &recording.device_heading.t_s,
        ),
        ("reference heading", "rad", &recording.ref_heading_rad.t_s),
        ("reference positions", "m", &recording.ref_position_en_m.t_s),
        (
            "reference positions (lat/lon)",
            "deg",
            &recording.ref_position_lat_lon_deg.t_s,
        ),
    ];
    let jobs: Vec<Job> = vectors
        .into_iter()
        .map(|(name, unit, stream)| Job {
            name,
            unit,
            t_s: &stream.t_s,
            values: Some(&stream.values),
        })
        .chain(times.into_iter().map(|(name, unit, t_s)| Job {
            name,
            unit,
            t_s,
            values: None,
        }))
        .filter(|job| !job.t_s.is_empty())
        .collect();
    let n_samples: usize = jobs.iter().map(|job| job.t_s.len()).sum();
    if n_samples >= MIN_PARALLEL_SAMPLES && crate::base::par::n_threads() > 1 {
        // Two halves of about the same work: every stream's timing (a pass over its
        // times), and the vector streams' magnitudes (a square root per sample). Whole
        // streams per thread left one thread with the three vector streams of a
        // canonical CSV, the other waiting.
        if let Some(halves) =
            crate::base::par::on_each_small_part([false, true].into_iter(), |magnitudes| {
                if magnitudes {
                    (Vec::new(), jobs.iter().map(Job::mean_magnitude).collect())
                } else {
                    (jobs.iter().map(Job::timing).collect(), Vec::new())
                }
            })
        {
            let mut halves = halves.into_iter();
            if let (Some((timings, _)), Some((_, magnitudes))) = (halves.next(), halves.next()) {
                return timings
                    .into_iter()
                    .zip(magnitudes)
                    .map(|(timing, mean_magnitude)| StreamSummary {
                        mean_magnitude,
                        ..timing
                    })
                    .collect();
            }
        }
    }
    jobs.iter().map(Job::summary).collect()
}

/// Below this many samples in all, one thread summarises as fast.
const MIN_PARALLEL_SAMPLES: usize = 200_000;

/// One stream to summarise: its times, and its vectors for a vector stream.
struct Job<'a> {
    name: &'static str,
    unit: &'static str,
    t_s: &'a [f64],
    values: Option<&'a [Vector3<f64>]>,
}

impl Job<'_> {
    fn summary(&self) -> StreamSummary {
        StreamSummary {
            mean_magnitude: self.mean_magnitude(),
            ..self.timing()
        }
    }

    fn timing(&self) -> StreamSummary {
        timing(self.name, self.unit, self.t_s)
    }

    fn mean_magnitude(&self) -> Option<f64> {
        self.values
            .map(|values| sum_of_norms(values) / values.len() as f64)
    }
}

fn timing(stream: &'static str, unit: &'static str, t_s: &[f64]) -> StreamSummary {
    let duration_s = match (t_s.first(), t_s.last()) {
        (Some(first_s), Some(last_s)) => last_s - first_s,
        _ => 0.0,
    };
    let n_intervals = t_s.len().saturating_sub(1);
    let mean_interval_s =
        (n_intervals > 0 && duration_s > 0.0).then(|| duration_s / n_intervals as f64);
    let gap_threshold_s = mean_interval_s.map_or(f64::INFINITY, |mean_s| (3.0 * mean_s).max(0.1));
    let Intervals {
        largest_s: largest_gap_s,
        n_repeated: n_repeated_times,
        n_longer: n_gaps,
    } = Intervals::of(t_s, gap_threshold_s);
    StreamSummary {
        stream,
        unit,
        n_samples: t_s.len(),
        duration_s,
        rate_hz: mean_interval_s.map(|mean_s| 1.0 / mean_s),
        n_gaps,
        largest_gap_s,
        n_repeated_times,
        mean_magnitude: None,
    }
}

/// Independent sums and maxima this many wide: one chain per lane, so that a pass
/// over a stream is not one long chain of dependent additions (or maxima) at the
/// adder's latency. A 100 MB CSV's streams were 12 % of `inspect`'s CPU with one chain
/// each (`perf record`, 2026-12-03).
const LANES: usize = 4;

/// The sum of the vectors' magnitudes, in [`LANES`] partial sums.
fn sum_of_norms(values: &[Vector3<f64>]) -> f64 {
    let mut sums = [0.0f64; LANES];
    let mut chunks = values.chunks_exact(LANES);
    for chunk in &mut chunks {
        for (sum, value) in sums.iter_mut().zip(chunk) {
            *sum += value.norm();
        }
    }
    let rest: f64 = chunks.remainder().iter().map(Vector3::norm).sum();
    sums.iter().sum::<f64>() + rest
}

/// What the intervals between consecutive times hold.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Intervals {
    /// The longest (0 when none is positive; NaN intervals are passed over).
    largest_s: f64,
    /// Those of zero: a time repeated.
    n_repeated: usize,
    /// Those longer than the threshold.
    n_longer: usize,
}

impl Intervals {
    /// The intervals of `t_s`, in [`LANES`] lanes merged at the end.
    fn of(t_s: &[f64], threshold_s: f64) -> Intervals {
        let (Some(earlier), Some(later)) = (t_s.get(..t_s.len().saturating_sub(1)), t_s.get(1..))
        else {
            return Intervals::EMPTY;
        };
        let mut lanes = [Intervals::EMPTY; LANES];
        let (earlier, later) = (earlier.chunks_exact(LANES), later.chunks_exact(LANES));
        let rest = earlier.remainder().iter().zip(later.remainder());
        for (before, after) in earlier.zip(later) {
            for ((lane, before), after) in lanes.iter_mut().zip(before).zip(after) {
                lane.add(after - before, threshold_s);
            }
        }
        let mut intervals = lanes.into_iter().fold(Intervals::EMPTY, Intervals::merged);
        for (before, after) in rest {
            intervals.add(after - before, threshold_s);
        }
        intervals
    }

    #[inline(always)]
    fn add(&mut self, interval_s: f64, threshold_s: f64) {
        self.largest_s = self.largest_s.max(interval_s);
        self.n_repeated += usize::from(interval_s == 0.0);
        self.n_longer += usize::from(interval_s > threshold_s);
    }

    fn merged(self, other: Intervals) -> Intervals {
        Intervals {
            largest_s: self.largest_s.max(other.largest_s),
            n_repeated: self.n_repeated + other.n_repeated,
            n_longer: self.n_longer + other.n_longer,
        }
    }

    const EMPTY: Intervals = Intervals {
        largest_s: 0.0,
        n_repeated: 0,
        n_longer: 0,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes' sums and maxima against one chain over every interval, for every
    /// length around the lane width, with repeats, NaN and backward steps.
    #[test]
    fn intervals_in_lanes_are_those_of_one_pass() {
        let pattern = [
            0.0,
            0.02,
            0.02,
            0.5,
            f64::NAN,
            0.01,
            -0.3,
            0.04,
            3.0,
            0.02,
            0.0,
        ];
        for len in 0..40 {
            let mut t_s = vec![1.0f64];
            for idx in 1..len {
                let last = t_s[idx - 1];
                let step = pattern[(idx * 7) % pattern.len()];
                t_s.push(match (step.is_nan(), last.is_nan()) {
                    (true, _) => f64::NAN,
                    // Times go on after a NaN.
                    (false, true) => idx as f64,
                    (false, false) => last + step,
                });
            }
            t_s.truncate(len);
            let mut expected = Intervals::EMPTY;
            for pair in t_s.windows(2) {
                let interval_s = pair[1] - pair[0];
                expected.largest_s = expected.largest_s.max(interval_s);
                expected.n_repeated += usize::from(interval_s == 0.0);
                expected.n_longer += usize::from(interval_s > 0.1);
            }
            assert_eq!(Intervals::of(&t_s, 0.1), expected, "{len} times");
        }
        let values: Vec<Vector3<f64>> = (0..11)
            .map(|idx| Vector3::new(idx as f64, 1.0, -2.0))
            .collect();
        let one_chain: f64 = values.iter().map(Vector3::norm).sum();
        assert!((sum_of_norms(&values) - one_chain).abs() < 1e-12 * one_chain);
    }

    #[test]
    fn rate_gaps_and_repeats_are_counted() {
        let mut recording = Recording::default();
        for idx in 0..100 {
            recording
                .mag_in_body_ut
                .push(idx as f64 * 0.02, Vector3::new(30.0, 0.0, 40.0));
        }
        // A 2 s gap (1.98 s to 3.98 s) and a repeated time.
        recording
            .mag_in_body_ut
            .push(2.98 + 1.0, Vector3::new(30.0, 0.0, 40.0));
        recording
            .mag_in_body_ut
            .push(2.98 + 1.0, Vector3::new(30.0, 0.0, 40.0));
        let summaries = summarize(&recording);
        assert_eq!(summaries.len(), 1);
        let mag = &summaries[0];
        assert_eq!(mag.n_samples, 102);
        // 101 intervals over 3.98 s.
        assert!((mag.rate_hz.unwrap_or(0.0) - 101.0 / 3.98).abs() < 1e-6);
        assert_eq!(mag.n_gaps, 1);
        assert!((mag.largest_gap_s - 2.0).abs() < 1e-9);
        assert_eq!(mag.n_repeated_times, 1);
        assert!((mag.mean_magnitude.unwrap_or(0.0) - 50.0).abs() < 1e-9);
    }

    #[test]
    fn empty_streams_are_left_out() {
        assert!(summarize(&Recording::default()).is_empty());
    }

    /// A long recording is summarised side by side; the summaries are the ones each
    /// stream gets alone, in the same order.
    #[test]
    fn a_long_recording_is_summarised_as_its_streams_alone() {
        let mut recording = Recording::default();
        for idx in 0..120_000 {
            let t_s = idx as f64 * 0.01;
            recording
                .acc_in_body_mps2
                .push(t_s, Vector3::new(0.0, 0.0, 9.81));
            recording
                .mag_in_body_ut
                .push(t_s, Vector3::new(30.0, 0.0, 40.0));
            recording.temp_c.push(t_s, 21.0);
            if idx % 100 == 0 {
                recording.ref_heading_rad.push(t_s, 0.5);
            }
        }
        let summaries = summarize(&recording);
        let alone = |stream: fn(&mut Recording) -> ()| {
            let mut single = Recording::default();
            stream(&mut single);
            summarize(&single)
        };
        let names: Vec<_> = summaries.iter().map(|summary| summary.stream).collect();
        assert_eq!(
            names,
            [
                "accelerometer",
                "magnetometer",
                "temperature",
                "reference heading"
            ]
        );
        let mut expected = Vec::new();
        expected.extend(alone(|single| {
            for idx in 0..120_000 {
                single
                    .acc_in_body_mps2
                    .push(idx as f64 * 0.01, Vector3::new(0.0, 0.0, 9.81));
            }
        }));
        expected.extend(alone(|single| {
            for idx in 0..120_000 {
                single
                    .mag_in_body_ut
                    .push(idx as f64 * 0.01, Vector3::new(30.0, 0.0, 40.0));
            }
        }));
        expected.extend(alone(|single| {
            for idx in 0..120_000 {
                single.temp_c.push(idx as f64 * 0.01, 21.0);
            }
        }));
        expected.extend(alone(|single| {
            for idx in (0..120_000).step_by(100) {
                single.ref_heading_rad.push(idx as f64 * 0.01, 0.5);
            }
        }));
        assert_eq!(summaries, expected);
    }
}
