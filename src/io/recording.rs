//! The recording model: time-stamped streams, each at its own rate.
//!
//! Every importer produces a [`Recording`]. Units and frames are fixed here, so that
//! the algorithms never convert: vectors are in the body frame (x forward, y right,
//! z down), magnetic field in µT, specific force in m/s², rates in rad/s, angles in
//! radians clockwise from north, positions in metres east and north of a local origin.
//!
//! Each sensor is one [`Stream`] (times and values). Interpolating one never
//! extrapolates beyond its ends and never bridges a gap longer than the caller allows.
//! Beside the streams, the recording keeps what the log says of them where it matters
//! to a fit: [`GyroBias`], whether the OS removed the gyroscope's bias (as Android's
//! `TYPE_GYROSCOPE` does), which sets the attitude filter's prior.

use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use crate::base::angle::wrap_to_pi;
use crate::base::geodesy::Geodetic;

/// One stream: sample times and values, sorted by time (importers sort and report).
#[derive(Debug, Clone, PartialEq)]
pub struct Stream<T> {
    pub t_s: Vec<f64>,
    pub values: Vec<T>,
}

impl<T> Default for Stream<T> {
    fn default() -> Self {
        Self {
            t_s: Vec::new(),
            values: Vec::new(),
        }
    }
}

impl<T> Stream<T> {
    pub fn push(&mut self, t_s: f64, value: T) {
        self.t_s.push(t_s);
        self.values.push(value);
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Time from the first to the last sample, zero for fewer than two samples.
    pub fn duration_s(&self) -> f64 {
        match (self.t_s.first(), self.t_s.last()) {
            (Some(first_s), Some(last_s)) => last_s - first_s,
            _ => 0.0,
        }
    }

    /// The median of the positive intervals between successive samples (s); `None`
    /// with fewer than two distinct times.
    pub fn median_interval_s(&self) -> Option<f64> {
        let mut intervals: Vec<f64> = self
            .t_s
            .windows(2)
            .map(|pair| pair[1] - pair[0])
            .filter(|dt| *dt > 0.0)
            .collect();
        if intervals.is_empty() {
            return None;
        }
        let middle = intervals.len() / 2;
        Some(*intervals.select_nth_unstable_by(middle, f64::total_cmp).1)
    }

    /// The longest interval between samples that is not a gap: `min_gap_s`, or three of
    /// the stream's typical intervals where that is longer (a log of per-second means).
    pub fn gap_limit_s(&self, min_gap_s: f64) -> f64 {
        self.median_interval_s()
            .map_or(min_gap_s, |median| min_gap_s.max(3.0 * median))
    }

    /// Sorts the samples by time, keeping the order of equal times. Returns how many
    /// samples were out of order before sorting.
    pub fn sort_by_time(&mut self) -> usize
    where
        T: Clone,
    {
        let n_out_of_order = self.t_s.windows(2).filter(|pair| pair[1] < pair[0]).count();
        if n_out_of_order > 0 {
            let order = crate::base::sort::ascending(&self.t_s);
            self.t_s = order.iter().map(|&idx| self.t_s[idx]).collect();
            self.values = order.iter().map(|&idx| self.values[idx].clone()).collect();
        }
        n_out_of_order
    }

    /// The index of the first sample at or after `t_s` (`partition_point` of `t < t_s`).
    /// Streams are nearly evenly sampled, so the index is first guessed from the time
    /// span and then corrected by a few steps; an uneven stream falls back to a binary
    /// search. The answer is the same either way; this makes the per-sample lookups of
    /// an hour at 100 Hz cheap.
    fn first_at_or_after(&self, t_s: f64) -> usize {
        const MAX_WALK: usize = 8;
        let times = &self.t_s;
        let binary = || times.partition_point(|&sample_t_s| sample_t_s < t_s);
        let (Some(&first_s), Some(&last_s)) = (times.first(), times.last()) else {
            return 0;
        };
        if !(t_s > first_s && t_s <= last_s && last_s > first_s) {
            return binary();
        }
        let fraction = (t_s - first_s) / (last_s - first_s);
        let mut idx = ((fraction * (times.len() - 1) as f64) as usize).min(times.len() - 1);
        for _ in 0..MAX_WALK {
            let below = times.get(idx).is_some_and(|&t| t < t_s);
            let previous_reaches = idx > 0 && times.get(idx - 1).is_some_and(|&t| t >= t_s);
            if below {
                idx += 1;
            } else if previous_reaches {
                idx -= 1;
            } else {
                return idx;
            }
        }
        binary()
    }

    /// The samples bracketing `t_s`, with the fraction of the way from the first to the
    /// second. `None` outside the stream's time span (never extrapolate) and across gaps
    /// longer than `max_gap_s` (never bridge missing data).
    fn bracket(&self, t_s: f64, max_gap_s: f64) -> Option<(&T, &T, f64)> {
        let after_idx = self.first_at_or_after(t_s);
        let after_t_s = *self.t_s.get(after_idx)?;
        let after_value = self.values.get(after_idx)?;
        if after_t_s == t_s {
            return Some((after_value, after_value, 0.0));
        }
        let before_idx = after_idx.checked_sub(1)?;
        let before_t_s = *self.t_s.get(before_idx)?;
        let before_value = self.values.get(before_idx)?;
        let gap_s = after_t_s - before_t_s;
        if !(gap_s > 0.0 && gap_s <= max_gap_s) {
            return None;
        }
        Some((before_value, after_value, (t_s - before_t_s) / gap_s))
    }
}

impl Stream<f64> {
    /// Linear interpolation at `t_s`; see `Stream::bracket` for when it is `None`.
    pub fn interpolate_at(&self, t_s: f64, max_gap_s: f64) -> Option<f64> {
        let (before, after, fraction) = self.bracket(t_s, max_gap_s)?;
        Some(before + (after - before) * fraction)
    }

    /// Interpolation of an angle stream along the shorter arc (359° and 1° meet at 0°).
    pub fn interpolate_angle_at(&self, t_s: f64, max_gap_s: f64) -> Option<f64> {
        let (before_rad, after_rad, fraction) = self.bracket(t_s, max_gap_s)?;
        Some(before_rad + wrap_to_pi(after_rad - before_rad) * fraction)
    }
}

impl Stream<Vector2<f64>> {
    /// Component-wise linear interpolation at `t_s` (positions in a plane).
    pub fn interpolate_at(&self, t_s: f64, max_gap_s: f64) -> Option<Vector2<f64>> {
        let (before, after, fraction) = self.bracket(t_s, max_gap_s)?;
        Some(before + (after - before) * fraction)
    }
}

impl Stream<Vector3<f64>> {
    /// Component-wise linear interpolation at `t_s`.
    pub fn interpolate_at(&self, t_s: f64, max_gap_s: f64) -> Option<Vector3<f64>> {
        let (before, after, fraction) = self.bracket(t_s, max_gap_s)?;
        Some(before + (after - before) * fraction)
    }
}

/// One GNSS fix as the receiver reports it. Any field may be missing.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct GnssFix {
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    /// Altitude above mean sea level (or the ellipsoid, as the source gives it).
    pub alt_m: Option<f64>,
    pub speed_mps: Option<f64>,
    /// Course over ground, clockwise from true north.
    pub course_rad: Option<f64>,
    /// Horizontal accuracy (1 σ) as reported.
    pub hacc_m: Option<f64>,
}

impl GnssFix {
    /// Where the fix is on the ellipsoid (altitude left at 0: the horizontal position is
    /// what the headings and speeds use), when it states a usable one: finite, the
    /// latitude within ±90°.
    pub fn position(&self) -> Option<Geodetic> {
        let (lat_deg, lon_deg) = (self.lat_deg?, self.lon_deg?);
        (lat_deg.is_finite() && lon_deg.is_finite() && lat_deg.abs() <= 90.0).then_some(Geodetic {
            lat_deg,
            lon_deg,
            alt_m: 0.0,
        })
    }
}

/// Roll, pitch and yaw of the body frame as the device itself reports them (for
/// example Android's rotation vector or a compass module's HPR sentence). Yaw is
/// clockwise from north; `None` where the device gives only tilt.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Attitude {
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: Option<f64>,
}

/// Which north a heading is measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum North {
    Magnetic,
    True,
}

/// What the device did to its gyroscope's samples before logging them: it sets how much
/// bias the attitude filter expects ([`crate::attitude::AttitudeOptions::for_gyro`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GyroBias {
    /// Raw, or not said: a MEMS gyroscope's turn-on bias can reach about 1°/s.
    #[default]
    Unknown,
    /// The OS subtracted its own running estimate of the bias: Android's
    /// `TYPE_GYROSCOPE` (its `_UNCALIBRATED` twin is the raw rate), which the importers
    /// name where the log says so.
    RemovedByDevice,
}

/// A heading that a compass device computed itself (NMEA HDG/HDM/HDT, a compass
/// module's HPR), clockwise from the stated north.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeviceHeading {
    pub heading_rad: f64,
    pub north: North,
}

/// Everything read from one log, in the units and frames stated in the module header.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// When `t_s = 0` was, in seconds since 1970 (UTC), where the log says (date-times,
    /// epoch timestamps, NMEA dates): it dates the log for the magnetic model.
    pub start_unix_s: Option<f64>,
    /// Specific force in the body frame (a level device at rest reads z ≈ −9.81).
    pub acc_in_body_mps2: Stream<Vector3<f64>>,
    pub gyro_in_body_radps: Stream<Vector3<f64>>,
    /// Whether the device removed the gyroscope's bias before logging it.
    pub gyro_bias: GyroBias,
    pub mag_in_body_ut: Stream<Vector3<f64>>,
    /// The device's own hard-iron estimate, where it reports one (Android's
    /// `TYPE_MAGNETIC_FIELD_UNCALIBRATED`): raw field minus this is its calibrated field.
    pub mag_bias_in_body_ut: Stream<Vector3<f64>>,
    pub temp_c: Stream<f64>,
    pub pressure_hpa: Stream<f64>,
    pub gnss: Stream<GnssFix>,
    pub attitude: Stream<Attitude>,
    pub device_heading: Stream<DeviceHeading>,
    /// Reference (true) heading, clockwise from true north.
    pub ref_heading_rad: Stream<f64>,
    /// The heading an autopilot's own estimator logged (ArduPilot's `ATT`, PX4's
    /// `vehicle_attitude`), clockwise from true north: the reference for a vehicle whose
    /// GPS course is not where it points (a multicopter flies sideways).
    pub autopilot_heading_rad: Stream<f64>,
    /// Reference positions (landmarks, waypoints), metres east and north of a local
    /// origin.
    pub ref_position_en_m: Stream<Vector2<f64>>,
    /// Reference positions given as latitude and longitude, in degrees.
    pub ref_position_lat_lon_deg: Stream<Vector2<f64>>,
}

impl Recording {
    /// Appends every stream of `other` to this one's (sorting is the caller's). The start
    /// time kept is this one's, else the other's.
    pub fn append(&mut self, other: Recording) {
        self.start_unix_s = self.start_unix_s.or(other.start_unix_s);
        fn append<T>(into: &mut Stream<T>, from: Stream<T>) {
            // Moving into an empty stream keeps the other's memory instead of copying it.
            if into.is_empty() {
                *into = from;
            } else {
                into.t_s.extend(from.t_s);
                into.values.extend(from.values);
            }
        }
        append(&mut self.acc_in_body_mps2, other.acc_in_body_mps2);
        // Rates of two kinds in one stream can only be said to be raw.
        if self.gyro_in_body_radps.is_empty() {
            self.gyro_bias = other.gyro_bias;
        } else if !other.gyro_in_body_radps.is_empty() && other.gyro_bias != self.gyro_bias {
            self.gyro_bias = GyroBias::Unknown;
        }
        append(&mut self.gyro_in_body_radps, other.gyro_in_body_radps);
        append(&mut self.mag_in_body_ut, other.mag_in_body_ut);
        append(&mut self.mag_bias_in_body_ut, other.mag_bias_in_body_ut);
        append(&mut self.temp_c, other.temp_c);
        append(&mut self.pressure_hpa, other.pressure_hpa);
        append(&mut self.gnss, other.gnss);
        append(&mut self.attitude, other.attitude);
        append(&mut self.device_heading, other.device_heading);
        append(&mut self.ref_heading_rad, other.ref_heading_rad);
        append(&mut self.autopilot_heading_rad, other.autopilot_heading_rad);
        append(&mut self.ref_position_en_m, other.ref_position_en_m);
        append(
            &mut self.ref_position_lat_lon_deg,
            other.ref_position_lat_lon_deg,
        );
    }

    /// Sorts every stream by time; returns how many samples were out of order in all.
    pub fn sort_all_by_time(&mut self) -> usize {
        self.acc_in_body_mps2.sort_by_time()
            + self.gyro_in_body_radps.sort_by_time()
            + self.mag_in_body_ut.sort_by_time()
            + self.mag_bias_in_body_ut.sort_by_time()
            + self.temp_c.sort_by_time()
            + self.pressure_hpa.sort_by_time()
            + self.gnss.sort_by_time()
            + self.attitude.sort_by_time()
            + self.device_heading.sort_by_time()
            + self.ref_heading_rad.sort_by_time()
            + self.autopilot_heading_rad.sort_by_time()
            + self.ref_position_en_m.sort_by_time()
            + self.ref_position_lat_lon_deg.sort_by_time()
    }
}

#[cfg(test)]
mod lookup_tests {
    use super::*;

    #[test]
    fn the_guessed_index_is_the_binary_searchs() {
        let mut rng = crate::base::rng::SplitMix64::new(9);
        let mut stream: Stream<f64> = Stream::default();
        let mut t = 0.0;
        for idx in 0..2000 {
            // Even sampling, with jitter, repeated times and a long gap.
            t += if idx == 1000 {
                50.0
            } else if idx % 97 == 0 {
                0.0
            } else {
                0.01 + 0.004 * rng.uniform_in(-1.0, 1.0)
            };
            stream.push(t, t);
        }
        for k in 0..20_000 {
            let query = -1.0 + (t + 2.0) * k as f64 / 20_000.0;
            let expected = stream.t_s.partition_point(|&s| s < query);
            assert_eq!(stream.first_at_or_after(query), expected, "{query}");
        }
        for &query in &stream.t_s {
            assert_eq!(
                stream.first_at_or_after(query),
                stream.t_s.partition_point(|&s| s < query)
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(points: &[(f64, f64)]) -> Stream<f64> {
        let mut stream = Stream::default();
        for &(t_s, value) in points {
            stream.push(t_s, value);
        }
        stream
    }

    #[test]
    fn interpolation_never_extrapolates_or_bridges_gaps() {
        let s = stream(&[(0.0, 0.0), (1.0, 10.0), (5.0, 50.0)]);
        assert_eq!(s.interpolate_at(0.5, 2.0), Some(5.0));
        assert_eq!(s.interpolate_at(1.0, 2.0), Some(10.0));
        assert_eq!(s.interpolate_at(-0.1, 2.0), None);
        assert_eq!(s.interpolate_at(5.1, 2.0), None);
        assert_eq!(
            s.interpolate_at(3.0, 2.0),
            None,
            "the 4 s gap is longer than 2 s"
        );
        assert_eq!(s.interpolate_at(3.0, 4.0), Some(30.0));
    }

    #[test]
    fn angle_interpolation_takes_the_short_way_round() {
        let s = stream(&[(0.0, 359f64.to_radians()), (1.0, 1f64.to_radians())]);
        let mid_rad = s.interpolate_angle_at(0.5, 2.0).unwrap_or(f64::NAN);
        assert!(wrap_to_pi(mid_rad).abs() < 1e-12);
    }

    #[test]
    fn sorting_reports_and_repairs_out_of_order_samples() {
        let mut s = stream(&[(0.0, 0.0), (2.0, 2.0), (1.0, 1.0), (3.0, 3.0)]);
        assert_eq!(s.sort_by_time(), 1);
        assert_eq!(s.t_s, vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(s.values, vec![0.0, 1.0, 2.0, 3.0]);
    }
}

#[cfg(test)]
mod append_tests {
    use super::*;

    fn with_gyro(gyro_bias: GyroBias, n: usize) -> Recording {
        let mut recording = Recording {
            gyro_bias,
            ..Recording::default()
        };
        for idx in 0..n {
            recording
                .gyro_in_body_radps
                .push(idx as f64, Vector3::zeros());
        }
        recording
    }

    #[test]
    fn the_gyroscope_keeps_its_bias_kind_unless_two_kinds_are_mixed() {
        use GyroBias::{RemovedByDevice as Removed, Unknown};
        for (first, second, expected) in [
            (with_gyro(Unknown, 0), with_gyro(Removed, 2), Removed),
            (with_gyro(Removed, 2), with_gyro(Unknown, 0), Removed),
            (with_gyro(Removed, 2), with_gyro(Removed, 2), Removed),
            (with_gyro(Removed, 2), with_gyro(Unknown, 2), Unknown),
            (with_gyro(Unknown, 2), with_gyro(Removed, 2), Unknown),
        ] {
            let mut merged = first.clone();
            merged.append(second.clone());
            assert_eq!(merged.gyro_bias, expected, "{first:?} + {second:?}");
        }
    }
}
