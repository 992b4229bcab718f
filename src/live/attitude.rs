//! The attitude filter on a live stream ([`super::LiveSession`]): a board that prints
//! its gyroscope and accelerometer beside the magnetometer (MotionCal `Raw:` lines, the
//! plotter's nine values) gets its dial from [`crate::attitude::AttitudeFilter`], the
//! gyroscope carrying the heading and the calibrated field correcting it only while its
//! magnitude, dip and direction say it is the Earth's, rather than from the compass
//! alone.
//!
//! The filter starts at the first fit, on the samples that come after it (nothing is
//! replayed), and takes each later fit's calibration for the field and the gate's
//! reference. Lines carry the arrival time of their chunk, so the samples of one chunk
//! share a time: the samples that came since the last call are spread evenly over the
//! time since then before the filter sees them, since it integrates the gyroscope over
//! the intervals between samples.

use nalgebra::Vector3;

use crate::attitude::gates::{dip_of, FieldReference};
use crate::attitude::{
    AttitudeEstimate, AttitudeFilter, AttitudeOptions, StreamTiming, MAX_GYRO_GAP_S,
};
use crate::fit::model::FieldCalibration;
use crate::io::recording::{Recording, Stream};
use crate::io::serial_lines::sensor_to_body;

/// The filter and how far it has read the session's streams.
#[derive(Debug, Clone)]
pub(super) struct LiveAttitude {
    filter: AttitudeFilter,
    /// Samples of the gyroscope, accelerometer and magnetometer streams already fed.
    n_used: [usize; 3],
    /// The latest sample time fed (s), after spreading.
    last_t_s: Option<f64>,
    latest: Option<AttitudeEstimate>,
}

impl LiveAttitude {
    /// A filter on the samples to come, when the stream has a gyroscope that has turned
    /// and an accelerometer that feels gravity.
    pub(super) fn start(
        recording: &Recording,
        calibration: &FieldCalibration,
    ) -> Option<LiveAttitude> {
        // MotionCal's sketch prints zeros for a board without a gyroscope (or an
        // accelerometer): those are no rates, and no gravity.
        let gyro_moves = recording
            .gyro_in_body_radps
            .values
            .iter()
            .any(|rate| rate.iter().any(|&value| value != 0.0));
        let acc_feels_gravity = recording
            .acc_in_body_mps2
            .values
            .iter()
            .any(|force| force.norm() > 1.0);
        if !(gyro_moves && acc_feels_gravity) {
            return None;
        }
        let mag = &recording.mag_in_body_ut;
        let field_interval_s = match (mag.t_s.first(), mag.t_s.last()) {
            (Some(first_s), Some(last_s)) if last_s > first_s && mag.len() > 1 => {
                (last_s - first_s) / (mag.len() - 1) as f64
            }
            _ => 0.02,
        };
        let timing = StreamTiming {
            field_interval_s,
            max_gyro_gap_s: MAX_GYRO_GAP_S,
            expects_field: true,
        };
        let options = AttitudeOptions::for_gyro(recording.gyro_bias);
        let filter = AttitudeFilter::new(reference(recording, calibration), timing, &options);
        Some(LiveAttitude {
            filter,
            n_used: [
                recording.gyro_in_body_radps.len(),
                recording.acc_in_body_mps2.len(),
                mag.len(),
            ],
            last_t_s: mag.t_s.last().copied(),
            latest: None,
        })
    }

    /// A new fit: the gate's reference from it (the field's magnitude, and the dip of
    /// the session's samples so far).
    pub(super) fn recalibrate(&mut self, recording: &Recording, calibration: &FieldCalibration) {
        if let Some(reference) = reference(recording, calibration) {
            self.filter.set_reference(reference);
        }
    }

    /// Feeds the samples that came since the last call, in time order, the field
    /// corrected by `calibration`.
    pub(super) fn take(&mut self, recording: &Recording, calibration: &FieldCalibration) {
        let gyro = spread(&recording.gyro_in_body_radps, self.n_used[0], self.last_t_s);
        let acc = spread(&recording.acc_in_body_mps2, self.n_used[1], self.last_t_s);
        let field = spread(&recording.mag_in_body_ut, self.n_used[2], self.last_t_s);
        self.n_used = [
            recording.gyro_in_body_radps.len(),
            recording.acc_in_body_mps2.len(),
            recording.mag_in_body_ut.len(),
        ];
        let mut cursors = [0usize; 3];
        loop {
            // The earliest, gyroscope first at equal times (as for a log).
            let candidates = [
                gyro.get(cursors[0]),
                acc.get(cursors[1]),
                field.get(cursors[2]),
            ];
            let mut next: Option<(usize, f64)> = None;
            for (idx, sample) in candidates.iter().enumerate() {
                if let Some((t_s, _)) = sample {
                    if next.is_none_or(|(_, best_s)| *t_s < best_s) {
                        next = Some((idx, *t_s));
                    }
                }
            }
            let Some((idx, t_s)) = next else { break };
            match idx {
                0 => {
                    if let Some(estimate) = self.filter.gyro(t_s, gyro[cursors[0]].1) {
                        self.latest = Some(estimate);
                    }
                }
                1 => self.filter.acc(t_s, acc[cursors[1]].1),
                _ => self
                    .filter
                    .field(t_s, corrected_in_body(calibration, field[cursors[2]].1)),
            }
            cursors[idx] += 1;
            self.last_t_s = Some(self.last_t_s.map_or(t_s, |last_s| last_s.max(t_s)));
        }
    }

    /// The filter's heading (rad, clockwise from magnetic north) once the field has
    /// corrected it at least once; before, it knows no north.
    pub(super) fn heading_rad(&self) -> Option<f64> {
        (self.filter.summary().n_field_fused > 0)
            .then_some(self.latest?)
            .map(|estimate| estimate.yaw_rad)
    }

    /// The filter's heading with its 1σ (rad), as [`LiveAttitude::heading_rad`].
    pub(super) fn heading_sigma_rad(&self) -> Option<f64> {
        self.heading_rad()?;
        Some(self.latest?.yaw_sigma_rad)
    }
}

/// A field sample in body axes corrected by a calibration made in the sensor's axes.
fn corrected_in_body(calibration: &FieldCalibration, v_in_body: Vector3<f64>) -> Vector3<f64> {
    sensor_to_body(calibration.apply(sensor_to_body(v_in_body)))
}

/// The samples of `stream` from `from` on, spread evenly over the interval from
/// `last_t_s` to the latest of their times: the lines of a chunk share its arrival time,
/// and a reading held for its next line (a `Uni:` line may follow it) carries the chunk
/// before's. Without an interval, their own times.
fn spread(
    stream: &Stream<Vector3<f64>>,
    from: usize,
    last_t_s: Option<f64>,
) -> Vec<(f64, Vector3<f64>)> {
    let times = stream.t_s.get(from..).unwrap_or_default();
    let values = stream.values.get(from..).unwrap_or_default();
    let latest_s = times.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let n = times.len();
    match last_t_s {
        Some(last_s) if latest_s > last_s => values
            .iter()
            .enumerate()
            .map(|(k, value)| {
                (
                    last_s + (latest_s - last_s) * (k + 1) as f64 / n as f64,
                    *value,
                )
            })
            .collect(),
        _ => times.iter().copied().zip(values.iter().copied()).collect(),
    }
}

/// The gate's reference ([`FieldReference::of_samples`]): the calibrated sphere's radius,
/// and the median dip of the session's undisturbed field samples, each against the
/// latest specific force at or before it (a chunk's samples share their time, so none
/// is interpolated between).
fn reference(recording: &Recording, calibration: &FieldCalibration) -> Option<FieldReference> {
    let field_ut = calibration.field_ut;
    if !(field_ut.is_finite() && field_ut > 0.0) {
        return None;
    }
    let (mag, acc) = (&recording.mag_in_body_ut, &recording.acc_in_body_mps2);
    let (mut magnitudes, mut dips) = (Vec::new(), Vec::new());
    let mut acc_idx = 0usize;
    for (&t_s, &raw) in mag.t_s.iter().zip(&mag.values) {
        while acc
            .t_s
            .get(acc_idx + 1)
            .is_some_and(|&next_s| next_s <= t_s)
        {
            acc_idx += 1;
        }
        let Some(down) = acc
            .values
            .get(acc_idx)
            .and_then(|force| (-force).try_normalize(1e-9))
        else {
            continue;
        };
        let field = corrected_in_body(calibration, raw);
        if let Some(dip) = dip_of(field, down).filter(|dip| dip.is_finite()) {
            magnitudes.push(field.norm());
            dips.push(dip);
        }
    }
    FieldReference::of_samples(&magnitudes, &dips, (Some(field_ut), None))
}

#[cfg(test)]
mod tests {
    use super::super::LiveSession;
    use crate::base::stats::HeadingErrorStats;

    #[test]
    fn a_board_that_prints_zeros_for_its_gyroscope_gets_no_filter() {
        let mut text = String::new();
        // A field swept over the sphere (480 µT as counts), gravity along z, no rates.
        let n = 600;
        for idx in 0..n {
            let z = 1.0 - 2.0 * (idx as f64 + 0.5) / n as f64;
            let azimuth = idx as f64 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let (x, y, z) = (
                480.0 * r * azimuth.cos(),
                480.0 * r * azimuth.sin(),
                480.0 * z,
            );
            text.push_str(&format!("Raw:0,0,8192,0,0,0,{x:.0},{y:.0},{z:.0}\r\n"));
        }
        let mut session = LiveSession::new();
        session.feed(text.as_bytes(), 1.0);
        assert!(session.refit().is_ok(), "a sphere of samples fits");
        session.feed(text.as_bytes(), 2.0);
        assert!(session.attitude.is_none());
        assert_eq!(session.filter_heading_rad(), None);
    }
    use crate::sim::dance::{board_attitude, motioncal_raw_lines, DanceConfig};

    /// A board dancing as MotionCal asks, its lines arriving in chunks of a tenth of a
    /// second and refitted every two seconds, as the page does; from 40 s to 44 s a
    /// steel tool near the board adds 20 µT along its x axis.
    #[test]
    fn a_board_with_a_gyroscope_gets_a_filter_needle_that_a_passing_tool_does_not_bend() {
        const TOOL: (f64, f64) = (40.0, 44.0);
        for seed in 1..=3 {
            let config = DanceConfig::from_seed(seed, 60.0);
            let (text, _) = motioncal_raw_lines(&config);
            let lines: Vec<String> = text
                .split_inclusive('\n')
                .enumerate()
                .map(|(idx, line)| {
                    let t_s = idx as f64 / config.rate_hz;
                    if !(TOOL.0..TOOL.1).contains(&t_s) {
                        return line.to_string();
                    }
                    let mut counts: Vec<i64> = line
                        .trim_end()
                        .trim_start_matches("Raw:")
                        .split(',')
                        .map(|count| count.parse().expect("a count"))
                        .collect();
                    counts[6] += 200; // 0.1 µT per count
                    let counts: Vec<String> = counts.iter().map(i64::to_string).collect();
                    format!("Raw:{}\r\n", counts.join(","))
                })
                .collect();
            let mut session = LiveSession::new();
            // (filter, compass) errors in degrees, out of and under the tool.
            let mut errors: [(Vec<f64>, Vec<f64>); 2] = Default::default();
            for (chunk_idx, chunk) in lines.chunks(5).enumerate() {
                let last_line = (chunk_idx + 1) * 5 - 1;
                let arrival_s = last_line as f64 / config.rate_hz;
                session.feed(chunk.concat().as_bytes(), arrival_s);
                // Refits stop under the tool: a user who sees the field jump does not
                // send that fit, and the filter keeps the last good one.
                if chunk_idx % 20 == 19 && !(TOOL.0..TOOL.1 + 1.0).contains(&arrival_s) {
                    let _ = session.refit();
                }
                // The reading of a line waits for the next one (a `Uni:` line may follow).
                let t_s = (last_line - 1) as f64 / config.rate_hz;
                let body_x_in_ned = board_attitude(&config, t_s) * nalgebra::Vector3::x();
                if body_x_in_ned.z.abs() > 0.7 || t_s < 10.0 {
                    continue;
                }
                let truth_rad = body_x_in_ned.y.atan2(body_x_in_ned.x);
                let error_rad = |heading_rad: f64| heading_rad - truth_rad;
                let (filter, compass) = &mut errors[usize::from((TOOL.0..TOOL.1).contains(&t_s))];
                if let Some((heading_rad, sigma_rad)) = session.filter_heading_rad() {
                    assert!(sigma_rad > 0.0 && sigma_rad < 0.5, "{sigma_rad}");
                    filter.push(error_rad(heading_rad));
                }
                if let Some(heading_rad) = session.latest_heading_rad() {
                    compass.push(error_rad(heading_rad));
                }
            }
            let rms = |errors_rad: &[f64]| {
                HeadingErrorStats::from_errors_rad(errors_rad.iter().copied())
                    .map_or(0.0, |stats| stats.rms_deg)
            };
            let [(filter_out, compass_out), (filter_under, compass_under)] = &errors;
            eprintln!(
                "dance seed {seed}: away from the tool filter {:.2}° and compass {:.2}° RMS ({} and {} readings); under it {:.2}° and {:.2}° ({} and {})",
                rms(filter_out), rms(compass_out), filter_out.len(), compass_out.len(),
                rms(filter_under), rms(compass_under), filter_under.len(), compass_under.len()
            );
            assert_eq!(
                filter_out.len(),
                compass_out.len(),
                "the needle from the first fit on"
            );
            // Away from the tool the compass is the better needle on this tumbling
            // board (the filter trusts the gyroscope over seconds, as for a walk, and
            // the dance turns at over 100°/s); under the tool the filter is.
            assert!(rms(filter_out) < 10.0, "seed {seed}");
            assert!(!filter_under.is_empty());
            assert!(rms(filter_under) * 2.0 < rms(compass_under), "seed {seed}");
        }
    }

    /// The dance as the page's simulated board plays it: pieces of half a second cut
    /// anywhere in a line, on the board's clock (its lines at its rate), a refit every
    /// five seconds. (On a clock of the share of bytes sent, which drifts by seconds
    /// over the dance since lines differ in length, the filter was 35-40° off.)
    #[test]
    fn the_filter_follows_the_dance_played_as_the_page_plays_it() {
        for seed in 1..=3 {
            let config = DanceConfig::from_seed(seed, 60.0);
            let (text, _) = motioncal_raw_lines(&config);
            let bytes = text.as_bytes();
            let piece_len = (bytes.len() as f64 / config.duration_s * 0.5).ceil() as usize;
            let mut session = LiveSession::new();
            let (mut errors_rad, mut lines) = (Vec::new(), 0usize);
            for (piece_idx, piece) in bytes.chunks(piece_len).enumerate() {
                lines += piece.iter().filter(|&&byte| byte == b'\n').count();
                let board_t_s = lines as f64 / config.rate_hz;
                session.feed(piece, board_t_s);
                if piece_idx % 10 == 9 {
                    let _ = session.refit();
                }
                let body_x_in_ned = board_attitude(&config, board_t_s) * nalgebra::Vector3::x();
                if body_x_in_ned.z.abs() > 0.7 || board_t_s < 10.0 {
                    continue;
                }
                if let Some((heading_rad, _)) = session.filter_heading_rad() {
                    errors_rad.push(heading_rad - body_x_in_ned.y.atan2(body_x_in_ned.x));
                }
            }
            let rms_deg = HeadingErrorStats::from_errors_rad(errors_rad.iter().copied())
                .map_or(0.0, |stats| stats.rms_deg);
            eprintln!(
                "dance seed {seed} as the page plays it: filter {rms_deg:.2}° RMS over {} readings",
                errors_rad.len()
            );
            assert!(errors_rad.len() > 50, "{}", errors_rad.len());
            assert!(rms_deg < 12.0, "seed {seed}: {rms_deg:.2}°");
        }
    }
}
