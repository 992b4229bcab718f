//! Reference headings: the truth a heading is compared with and fitted to.
//!
//! Today two sources, in this order of preference: a reference-heading column in the
//! log (`ref_heading_deg`: a simulator's truth, or a survey), and the GPS course over
//! ground while moving fast enough for it to be the direction the vehicle faces (the
//! course of a slow or stationary receiver is noise). Gyro integration and map legs come
//! with the heading-model work.

use serde::Serialize;

use crate::recording::{Recording, Stream};

/// Where a reference heading came from, as the result reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum ReferenceSource {
    /// The log's own reference-heading column.
    Column,
    /// GPS course over ground at speeds of at least `min_speed_mps`.
    GpsCourse { min_speed_mps: f64 },
}

/// A reference heading stream, clockwise from true north.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub source: ReferenceSource,
    pub heading_rad: Stream<f64>,
}

/// The speed above which the course over ground is taken as the heading of a vehicle
/// (the vehicle log's README uses 5 m/s).
pub const DEFAULT_MIN_COURSE_SPEED_MPS: f64 = 5.0;

/// The best reference the recording has, or `None`.
pub fn choose_reference(recording: &Recording, min_course_speed_mps: f64) -> Option<Reference> {
    if !recording.ref_heading_rad.is_empty() {
        return Some(Reference {
            source: ReferenceSource::Column,
            heading_rad: recording.ref_heading_rad.clone(),
        });
    }
    let mut course = Stream::default();
    for (&t_s, fix) in recording.gnss.t_s.iter().zip(&recording.gnss.values) {
        if let (Some(speed_mps), Some(course_rad)) = (fix.speed_mps, fix.course_rad) {
            if speed_mps >= min_course_speed_mps && course_rad.is_finite() {
                course.push(t_s, course_rad);
            }
        }
    }
    (!course.is_empty()).then_some(Reference {
        source: ReferenceSource::GpsCourse {
            min_speed_mps: min_course_speed_mps,
        },
        heading_rad: course,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::GnssFix;

    #[test]
    fn a_reference_column_wins_over_gps() {
        let mut recording = Recording::default();
        recording.ref_heading_rad.push(0.0, 1.0);
        recording.gnss.push(
            0.0,
            GnssFix {
                speed_mps: Some(10.0),
                course_rad: Some(2.0),
                ..GnssFix::default()
            },
        );
        assert_eq!(
            choose_reference(&recording, 5.0).map(|reference| reference.source),
            Some(ReferenceSource::Column)
        );
    }

    #[test]
    fn gps_course_counts_only_when_moving_fast_enough() {
        let mut recording = Recording::default();
        for (t_s, speed_mps) in [(0.0, 1.0), (1.0, 6.0), (2.0, 12.0), (3.0, 4.9)] {
            recording.gnss.push(
                t_s,
                GnssFix {
                    speed_mps: Some(speed_mps),
                    course_rad: Some(0.5),
                    ..GnssFix::default()
                },
            );
        }
        let reference = choose_reference(&recording, 5.0).expect("two fast fixes");
        assert_eq!(reference.heading_rad.t_s, vec![1.0, 2.0]);
        assert!(choose_reference(&Recording::default(), 5.0).is_none());
    }
}
