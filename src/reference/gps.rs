//! GPS course over ground as a reference heading, with the gates that make it one.
//!
//! Source: the PDR paper (`pdr-unified-heading-model.txt`, Section IV) trains its
//! heading model on the GPS course while the pedestrian walks in open sky. The course of
//! a receiver is the direction of its velocity: it is the heading only while the
//! platform moves forward, fast enough for the velocity to dominate the receiver noise,
//! and with a fix accurate enough. Two ways to get it:
//!
//! - the receiver's own course field (NMEA RMC/VTG, a phone's `bearing`), gated by the
//!   reported speed (5 m/s for a vehicle's log, 0.8 m/s for a pedestrian's, told apart
//!   by the log's sustained speed), the horizontal accuracy and the course's
//!   steadiness (a turn's course lags the heading);
//! - the bearing between two fixes, for logs without a course field: the pair must be at
//!   least `min_baseline_m` and at least four times their accuracies apart, and no more
//!   than `max_baseline_s` apart in time; the bearing is assigned to the midpoint time.
//!   With 3 m accuracy, a 12 m baseline gives about 20° of noise at worst and 10° (1 σ)
//!   typically, which the heading model's least squares averages down.

use nalgebra::Vector2;
use serde::Serialize;

use crate::base::geodesy::{Geodetic, LocalFrame};
use crate::io::recording::{GnssFix, Stream};

/// The gates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GpsCourseGates {
    /// Course counts only at or above this speed (m/s).
    pub min_speed_mps: f64,
    /// Fixes less accurate than this (1 σ, m) are left out, where the log says.
    pub max_hacc_m: f64,
    /// Shortest baseline for a bearing between two fixes (m).
    pub min_baseline_m: f64,
    /// Longest time between the two fixes of a bearing (s).
    pub max_baseline_s: f64,
    /// A course sample counts only while the course is steady: its neighbours within
    /// [`STEADY_WINDOW_S`] turn no faster than this (deg/s). In a turn, a receiver's
    /// course lags and interpolating between fixes cuts the corner.
    pub max_turn_rate_dps: f64,
}

/// How far either side (s) a course sample's neighbours are looked for.
pub const STEADY_WINDOW_S: f64 = 1.5;

/// How long (s) before and after a vehicle's turn (at [`VEHICLE_MIN_SPEED_MPS`] or
/// faster) the course is not taken either. In a turn a vehicle's centripetal
/// acceleration tilts the accelerometer's gravity (v·ω: 2.4 m/s², 14° of false roll, at
/// 12 m/s and 11°/s), and the tilt, averaged over about a second, carries that into the
/// compass heading for a while after the turn as well as in it. A walker's turns are
/// too gentle for it, and too frequent to lose the courses around them.
pub const TURN_MARGIN_S: f64 = 2.0;

/// Speed above which a vehicle's course is its heading (the vehicle log's README).
pub const VEHICLE_MIN_SPEED_MPS: f64 = 5.0;
/// Walking pace: below it a pedestrian's course is mostly receiver noise.
pub const PEDESTRIAN_MIN_SPEED_MPS: f64 = 0.8;

impl GpsCourseGates {
    /// Gates for a log whose fastest sustained speed tells vehicle from pedestrian: a
    /// log with at least 30 fixes at [`VEHICLE_MIN_SPEED_MPS`] or more is a vehicle's.
    pub fn auto(gnss: &Stream<GnssFix>) -> GpsCourseGates {
        let n_fast = gnss
            .values
            .iter()
            .filter(|fix| {
                fix.speed_mps
                    .is_some_and(|speed| speed >= VEHICLE_MIN_SPEED_MPS)
            })
            .count();
        GpsCourseGates::with_min_speed(if n_fast >= 30 {
            VEHICLE_MIN_SPEED_MPS
        } else {
            PEDESTRIAN_MIN_SPEED_MPS
        })
    }

    pub fn with_min_speed(min_speed_mps: f64) -> GpsCourseGates {
        GpsCourseGates {
            min_speed_mps,
            max_hacc_m: 15.0,
            min_baseline_m: 8.0,
            max_baseline_s: 20.0,
            max_turn_rate_dps: 10.0,
        }
    }
}

/// What the gates did, for the report.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct GpsCourseUse {
    /// Courses taken from the receiver's course field.
    pub n_from_course_field: usize,
    /// Courses computed from pairs of fixes (logs without a course field).
    pub n_from_fixes: usize,
    pub n_too_slow: usize,
    pub n_inaccurate: usize,
    /// Courses left out because the course was turning.
    pub n_turning: usize,
}

/// The GPS course reference (clockwise from true north) and how it was gated.
pub fn course_reference(
    gnss: &Stream<GnssFix>,
    gates: &GpsCourseGates,
) -> (Stream<f64>, GpsCourseUse) {
    let mut used = GpsCourseUse::default();
    let mut course = Stream::default();
    let mut speeds_mps = Vec::new();
    let accurate = |fix: &GnssFix| fix.hacc_m.is_none_or(|hacc_m| hacc_m <= gates.max_hacc_m);
    for (&t_s, fix) in gnss.t_s.iter().zip(&gnss.values) {
        let (Some(speed_mps), Some(course_rad)) = (fix.speed_mps, fix.course_rad) else {
            continue;
        };
        if !(course_rad.is_finite() && speed_mps.is_finite()) {
            continue;
        }
        if speed_mps < gates.min_speed_mps {
            used.n_too_slow += 1;
        } else if !accurate(fix) {
            used.n_inaccurate += 1;
        } else {
            course.push(t_s, course_rad);
            speeds_mps.push(speed_mps);
            used.n_from_course_field += 1;
        }
    }
    if !course.is_empty() {
        let steady = steady_only(&course, &speeds_mps, gates.max_turn_rate_dps);
        used.n_turning = course.len() - steady.len();
        used.n_from_course_field = steady.len();
        return (steady, used);
    }

    // No course field: bearings between fixes far enough apart.
    let positioned: Vec<(f64, Geodetic, f64)> = gnss
        .t_s
        .iter()
        .zip(&gnss.values)
        .filter_map(|(&t_s, fix)| Some((t_s, fix.position()?, fix.hacc_m.unwrap_or(0.0))))
        .collect();
    let Some(&(_, origin, _)) = positioned.first() else {
        return (course, used);
    };
    let frame = LocalFrame::at(origin);
    let en: Vec<Vector2<f64>> = positioned
        .iter()
        .map(|(_, position, _)| frame.en_of(position.lat_deg, position.lon_deg))
        .collect();
    let mut end_idx = 0usize;
    for (start_idx, (&(t0_s, _, hacc0_m), &en0)) in positioned.iter().zip(&en).enumerate() {
        if hacc0_m > gates.max_hacc_m {
            used.n_inaccurate += 1;
            continue;
        }
        end_idx = end_idx.max(start_idx + 1);
        // The first later fix far enough away.
        while let (Some(&(t1_s, _, hacc1_m)), Some(&en1)) =
            (positioned.get(end_idx), en.get(end_idx))
        {
            if t1_s - t0_s > gates.max_baseline_s {
                break;
            }
            let baseline_m = (en1 - en0).norm();
            if baseline_m >= gates.min_baseline_m.max(4.0 * (hacc0_m + hacc1_m)) {
                let speed_mps = baseline_m / (t1_s - t0_s).max(1e-9);
                if speed_mps < gates.min_speed_mps {
                    used.n_too_slow += 1;
                } else {
                    let delta = en1 - en0;
                    course.push(
                        (t0_s + t1_s) / 2.0,
                        crate::base::angle::wrap_to_2pi(delta.x.atan2(delta.y)),
                    );
                    used.n_from_fixes += 1;
                }
                break;
            }
            end_idx += 1;
        }
    }
    // Midpoint times of successive pairs can fall out of order when baselines differ.
    course.sort_by_time();
    (course, used)
}

/// The course samples whose neighbours within [`STEADY_WINDOW_S`] (both sides) turn no
/// faster than `max_turn_rate_dps`, and that are more than [`TURN_MARGIN_S`] from a
/// vehicle's turn (`speeds_mps`: the speed of each sample). A sample without a
/// neighbour on a side is judged by the other.
fn steady_only(course: &Stream<f64>, speeds_mps: &[f64], max_turn_rate_dps: f64) -> Stream<f64> {
    let max_rate_radps = max_turn_rate_dps.to_radians();
    let n = course.len();
    let mut turning = vec![false; n];
    for (idx, flag) in turning.iter_mut().enumerate() {
        let (Some(&t_s), Some(&value)) = (course.t_s.get(idx), course.values.get(idx)) else {
            continue;
        };
        let turn_rate_to = |other: usize| -> Option<f64> {
            let (&other_t_s, &other_value) = (course.t_s.get(other)?, course.values.get(other)?);
            let dt_s = (other_t_s - t_s).abs();
            (dt_s > 0.0 && dt_s <= STEADY_WINDOW_S)
                .then(|| crate::base::angle::wrap_to_pi(other_value - value).abs() / dt_s)
        };
        let before = idx.checked_sub(1).and_then(turn_rate_to);
        let after = turn_rate_to(idx + 1);
        let within = |rate: Option<f64>| rate.is_none_or(|rate| rate <= max_rate_radps);
        *flag = !(within(before) && within(after));
    }
    // The turns a vehicle made, whose neighbours go too.
    let turn_times_s: Vec<f64> = course
        .t_s
        .iter()
        .zip(&turning)
        .zip(speeds_mps)
        .filter_map(|((&t_s, &turning), &speed_mps)| {
            (turning && speed_mps >= VEHICLE_MIN_SPEED_MPS).then_some(t_s)
        })
        .collect();
    let mut steady = Stream::default();
    for ((&t_s, &value), &turning) in course.t_s.iter().zip(&course.values).zip(&turning) {
        // The turns nearest in time (the times are sorted).
        let next = turn_times_s.partition_point(|&turn_t_s| turn_t_s < t_s);
        let near_a_turn = [next.checked_sub(1), Some(next)]
            .into_iter()
            .flatten()
            .filter_map(|idx| turn_times_s.get(idx))
            .any(|&turn_t_s| (turn_t_s - t_s).abs() <= TURN_MARGIN_S);
        if !turning && !near_a_turn {
            steady.push(t_s, value);
        }
    }
    steady
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn courses_in_a_turn_and_near_it_are_left_out() {
        // 1 Hz: north until 10 s, a 45° turn from 10 to 14 s, then steady.
        let mut course = Stream::default();
        for t in 0..30 {
            let t_s = f64::from(t);
            let course_deg = 45.0 * ((t_s - 10.0) / 4.0).clamp(0.0, 1.0);
            course.push(t_s, course_deg.to_radians());
        }
        let kept = |speed_mps: f64| -> Vec<u32> {
            let speeds = vec![speed_mps; course.len()];
            let steady = steady_only(&course, &speeds, 10.0);
            steady.t_s.iter().map(|&t_s| t_s as u32).collect()
        };
        // Turning (11.25°/s to a neighbour): 10 to 14 s; a car's, within 2 s of those
        // too: 8, 9 and 15, 16.
        assert_eq!(kept(12.0), (0..8).chain(17..30).collect::<Vec<u32>>());
        // A walker's turn costs only the turning courses.
        assert_eq!(kept(1.3), (0..10).chain(15..30).collect::<Vec<u32>>());
    }

    fn fix(speed_mps: Option<f64>, course_deg: Option<f64>, hacc_m: Option<f64>) -> GnssFix {
        GnssFix {
            speed_mps,
            course_rad: course_deg.map(f64::to_radians),
            hacc_m,
            ..GnssFix::default()
        }
    }

    #[test]
    fn the_course_field_is_gated_by_speed_and_accuracy() {
        let mut gnss = Stream::default();
        gnss.push(0.0, fix(Some(1.0), Some(10.0), Some(3.0)));
        gnss.push(1.0, fix(Some(6.0), Some(20.0), Some(3.0)));
        gnss.push(2.0, fix(Some(6.0), Some(30.0), Some(40.0)));
        gnss.push(3.0, fix(Some(6.0), None, Some(3.0)));
        let (course, used) = course_reference(&gnss, &GpsCourseGates::with_min_speed(5.0));
        assert_eq!(course.t_s, vec![1.0]);
        assert_eq!((used.n_too_slow, used.n_inaccurate), (1, 1));
    }

    #[test]
    fn without_a_course_field_the_bearing_between_fixes_is_used() {
        // Walking north-east at 1.4 m/s, one fix a second, 2 m accuracy.
        let frame = LocalFrame::at(Geodetic {
            lat_deg: 60.0,
            lon_deg: 25.0,
            alt_m: 0.0,
        });
        let mut gnss = Stream::default();
        for idx in 0..60 {
            let distance_m = 1.4 * idx as f64;
            let position = frame.geodetic_of(nalgebra::Vector3::new(
                distance_m * 45f64.to_radians().sin(),
                distance_m * 45f64.to_radians().cos(),
                0.0,
            ));
            gnss.push(
                idx as f64,
                GnssFix {
                    lat_deg: Some(position.lat_deg),
                    lon_deg: Some(position.lon_deg),
                    hacc_m: Some(2.0),
                    ..GnssFix::default()
                },
            );
        }
        let gates = GpsCourseGates::auto(&gnss);
        assert_eq!(gates.min_speed_mps, PEDESTRIAN_MIN_SPEED_MPS);
        let (course, used) = course_reference(&gnss, &gates);
        assert!(used.n_from_fixes > 40, "{used:?}");
        for &course_rad in &course.values {
            assert!((course_rad.to_degrees() - 45.0).abs() < 0.01);
        }
        // Standing still gives nothing.
        let mut still = Stream::default();
        for idx in 0..30 {
            still.push(
                idx as f64,
                GnssFix {
                    lat_deg: Some(60.0),
                    lon_deg: Some(25.0),
                    hacc_m: Some(2.0),
                    ..GnssFix::default()
                },
            );
        }
        assert!(course_reference(&still, &gates).0.is_empty());
    }
}
