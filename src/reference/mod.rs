//! Reference headings: the truth a heading is compared with and fitted to, each with
//! where it came from and how good it is.
//!
//! Sources, and the order in which [`ReferenceChoice::Auto`] tries them:
//!
//! 1. a reference-heading column in the log (`ref_heading_deg`: a simulator's truth, a
//!    survey);
//! 2. an autopilot's own heading (ArduPilot's `ATT`, PX4's `vehicle_attitude`): a drone
//!    log's best, since a multicopter's course is not its heading;
//! 3. the GPS course over ground, gated by speed and accuracy ([`gps`]);
//! 4. the map-direction constraint: straight legs between reference positions
//!    ([`legs`]);
//! 5. the integrated gyro heading ([`gyro`]), anchored to whichever of the above exists,
//!    else relative (and drift-corrected when the user says the walk is a closed loop).
//!
//! A relative reference has no absolute offset: a heading model fitted against it
//! learns the shape of the deviation, not its constant term, and the result says so.
//! The analysis turns such a reference onto the compass's mean heading
//! (`analysis/calibration/context.rs`), and its report says so.

pub mod gps;
pub mod gyro;
pub mod legs;

use serde::Serialize;

use crate::attitude::down::GravityEstimate;
use crate::base::geodesy::{Geodetic, LocalFrame};
use crate::io::recording::{Recording, Stream};
use gps::{course_reference, GpsCourseGates, GpsCourseUse};
use gyro::{gyro_heading, GyroAlignment};
use legs::{leg_reference, LegOptions};

/// Which reference the user asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceChoice {
    #[default]
    Auto,
    Column,
    Autopilot,
    Gps,
    Legs,
    Gyro,
}

impl ReferenceChoice {
    pub fn parse(text: &str) -> Option<ReferenceChoice> {
        match text.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(ReferenceChoice::Auto),
            "column" => Some(ReferenceChoice::Column),
            "autopilot" => Some(ReferenceChoice::Autopilot),
            "gps" => Some(ReferenceChoice::Gps),
            "legs" => Some(ReferenceChoice::Legs),
            "gyro" => Some(ReferenceChoice::Gyro),
            _ => None,
        }
    }
}

/// The short labels of the references that also score a track (a gyro reference names
/// its anchor by them).
const COLUMN_LABEL: &str = "reference column";
const LEGS_LABEL: &str = "map legs";

/// Where a reference heading came from, as the result reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum ReferenceSource {
    /// The log's own reference-heading column.
    Column,
    /// The autopilot's own heading estimate.
    Autopilot,
    /// GPS course over ground through the gates.
    GpsCourse {
        min_speed_mps: f64,
        max_hacc_m: f64,
        #[serde(flatten)]
        used: GpsCourseUse,
    },
    /// Straight legs between reference positions.
    Legs { n_legs: usize, total_length_m: f64 },
    /// The integrated gyro heading.
    Gyro {
        #[serde(flatten)]
        alignment: GyroAlignment,
        /// The absolute reference it was anchored to, if any.
        anchor: Option<&'static str>,
    },
}

impl ReferenceSource {
    /// Whether the reference is what also scores a track: the log's reference-heading
    /// column or its reference positions' legs (in a test log, the truth), or the gyro
    /// anchored to either.
    pub fn scores_the_track(&self) -> bool {
        match self {
            ReferenceSource::Column | ReferenceSource::Legs { .. } => true,
            ReferenceSource::Gyro { anchor, .. } => {
                matches!(anchor, Some(label) if [COLUMN_LABEL, LEGS_LABEL].contains(label))
            }
            ReferenceSource::Autopilot | ReferenceSource::GpsCourse { .. } => false,
        }
    }

    /// Whether the reference knows north (a relative gyro heading does not).
    pub fn is_absolute(&self) -> bool {
        !matches!(
            self,
            ReferenceSource::Gyro {
                alignment: GyroAlignment::ClosedLoop { .. } | GyroAlignment::Relative,
                ..
            }
        )
    }

    /// One sentence for the user: what the reference is and how it was gated or aligned.
    pub fn describe(&self) -> String {
        match self {
            ReferenceSource::Column => "the log's reference-heading column".to_string(),
            ReferenceSource::Autopilot => "the autopilot's own heading (its estimator fuses \
                the compass with its calibration in force, the gyroscopes and GPS, so it \
                leans slightly towards the calibration in force)"
                .to_string(),
            ReferenceSource::GpsCourse {
                min_speed_mps,
                max_hacc_m,
                used,
            } => {
                let from = if used.n_from_fixes > 0 {
                    format!("{} bearings between fixes", used.n_from_fixes)
                } else {
                    format!("{} course-over-ground samples", used.n_from_course_field)
                };
                format!(
                    "GPS course at {min_speed_mps} m/s or faster with accuracy within {max_hacc_m} m ({from}; {} too slow, {} inaccurate left out)",
                    used.n_too_slow, used.n_inaccurate
                )
            }
            ReferenceSource::Legs {
                n_legs,
                total_length_m,
            } => format!(
                "the bearings of {n_legs} straight legs ({total_length_m:.0} m) between reference positions, 15 % of each leg's time left out at either end"
            ),
            ReferenceSource::Gyro { alignment, anchor } => match alignment {
                GyroAlignment::Anchored {
                    n_anchor_samples,
                    drift_deg_per_min,
                    residual_rms_deg,
                } => format!(
                    "the integrated gyro heading, anchored to the {} ({n_anchor_samples} samples, {residual_rms_deg:.1}° RMS about it){}",
                    anchor.unwrap_or("reference"),
                    drift_deg_per_min.map_or_else(
                        || ", too short a span to fit a drift".to_string(),
                        |drift| format!(", drift {drift:.2}°/min removed")
                    )
                ),
                GyroAlignment::ClosedLoop {
                    drift_deg_per_min,
                    turned_deg,
                    closure_pct,
                } => format!(
                    "the integrated gyro heading over a closed loop (drift {drift_deg_per_min:.2}°/min removed, the rate \
                     that closes the walk to {closure_pct:.1} % of its length; {turned_deg:.0}° turned from start to end); \
                     it does not know north, so it fixes the shape of the deviation, not its constant term"
                ),
                GyroAlignment::Relative => "the integrated gyro heading, relative to the start (no drift correction; it does not know north)"
                    .to_string(),
            },
        }
    }

    /// A short name for tables.
    pub fn label(&self) -> &'static str {
        match self {
            ReferenceSource::Column => COLUMN_LABEL,
            ReferenceSource::Autopilot => "autopilot heading",
            ReferenceSource::GpsCourse { .. } => "GPS course",
            ReferenceSource::Legs { .. } => LEGS_LABEL,
            ReferenceSource::Gyro { .. } => "gyro",
        }
    }
}

/// A reference heading stream, clockwise from true north (from an arbitrary start for a
/// relative one).
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub source: ReferenceSource,
    pub heading_rad: Stream<f64>,
    /// The longest gap (s) between two of its samples across which it may be
    /// interpolated.
    pub max_gap_s: f64,
}

/// What shapes the choice.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ReferenceOptions {
    pub choice: ReferenceChoice,
    /// The GPS speed gate (m/s); `None` picks a vehicle's or a pedestrian's from the log.
    pub min_course_speed_mps: Option<f64>,
    /// The walk ends where and as it started (for a gyro reference without anchors).
    pub closed_loop: bool,
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        ReferenceOptions {
            choice: ReferenceChoice::Auto,
            min_course_speed_mps: None,
            closed_loop: false,
        }
    }
}

/// The longest gap (s) across which a column or GPS reference is interpolated: a 1 Hz
/// GPS course still counts.
const MAX_REFERENCE_GAP_S: f64 = 1.5;

fn column_reference(recording: &Recording) -> Option<Reference> {
    (!recording.ref_heading_rad.is_empty()).then(|| Reference {
        source: ReferenceSource::Column,
        heading_rad: recording.ref_heading_rad.clone(),
        max_gap_s: MAX_REFERENCE_GAP_S,
    })
}

fn autopilot_reference(recording: &Recording) -> Option<Reference> {
    (!recording.autopilot_heading_rad.is_empty()).then(|| Reference {
        source: ReferenceSource::Autopilot,
        heading_rad: recording.autopilot_heading_rad.clone(),
        max_gap_s: MAX_REFERENCE_GAP_S,
    })
}

fn gps_reference(recording: &Recording, options: &ReferenceOptions) -> Option<Reference> {
    let gates = options.min_course_speed_mps.map_or_else(
        || GpsCourseGates::auto(&recording.gnss),
        GpsCourseGates::with_min_speed,
    );
    let (course, used) = course_reference(&recording.gnss, &gates);
    (!course.is_empty()).then_some(Reference {
        source: ReferenceSource::GpsCourse {
            min_speed_mps: gates.min_speed_mps,
            max_hacc_m: gates.max_hacc_m,
            used,
        },
        heading_rad: course,
        // Courses from pairs of fixes are spaced by their baselines.
        max_gap_s: if used.n_from_fixes > 0 {
            gates.max_baseline_s / 2.0
        } else {
            MAX_REFERENCE_GAP_S
        },
    })
}

fn legs_reference(recording: &Recording) -> Option<Reference> {
    let mut positions = recording.ref_position_en_m.clone();
    if positions.is_empty() {
        // Latitude/longitude landmarks: into the tangent plane at the first.
        let lat_lon = &recording.ref_position_lat_lon_deg;
        let origin = lat_lon
            .values
            .iter()
            .find(|p| p.x.is_finite() && p.y.is_finite())?;
        let frame = LocalFrame::at(Geodetic {
            lat_deg: origin.x,
            lon_deg: origin.y,
            alt_m: 0.0,
        });
        for (&t_s, lat_lon_deg) in lat_lon.t_s.iter().zip(&lat_lon.values) {
            positions.push(t_s, frame.en_of(lat_lon_deg.x, lat_lon_deg.y));
        }
    }
    let options = LegOptions::default();
    let (heading, legs) = leg_reference(&positions, &options);
    (!heading.is_empty()).then(|| Reference {
        source: ReferenceSource::Legs {
            n_legs: legs.len(),
            total_length_m: legs.iter().map(|leg| leg.length_m).sum(),
        },
        heading_rad: heading,
        max_gap_s: options.sample_spacing_s * 1.5,
    })
}

/// The reference asked for, or in `Auto` the best the recording has; `None` when
/// there is none of the kind asked for. `gravity` levels the gyro of a gyro reference.
pub fn choose_reference(
    recording: &Recording,
    gravity: &GravityEstimate,
    options: &ReferenceOptions,
) -> Option<Reference> {
    let absolute = || {
        column_reference(recording)
            .or_else(|| autopilot_reference(recording))
            .or_else(|| gps_reference(recording, options))
            .or_else(|| legs_reference(recording))
    };
    match options.choice {
        ReferenceChoice::Auto => absolute().or_else(|| {
            // A closed loop is the one case where the gyro alone is a useful reference.
            options
                .closed_loop
                .then(|| gyro_reference(recording, gravity, options, None))
                .flatten()
        }),
        ReferenceChoice::Column => column_reference(recording),
        ReferenceChoice::Autopilot => autopilot_reference(recording),
        ReferenceChoice::Gps => gps_reference(recording, options),
        ReferenceChoice::Legs => legs_reference(recording),
        ReferenceChoice::Gyro => gyro_reference(recording, gravity, options, absolute()),
    }
}

fn gyro_reference(
    recording: &Recording,
    gravity: &GravityEstimate,
    options: &ReferenceOptions,
    anchor: Option<Reference>,
) -> Option<Reference> {
    let gyro = gyro_heading(
        recording,
        gravity,
        anchor.as_ref().map(|anchor| &anchor.heading_rad),
        options.closed_loop,
    )?;
    let anchor_label = match gyro.alignment {
        GyroAlignment::Anchored { .. } => anchor.map(|anchor| anchor.source.label()),
        _ => None,
    };
    Some(Reference {
        source: ReferenceSource::Gyro {
            alignment: gyro.alignment,
            anchor: anchor_label,
        },
        heading_rad: gyro.heading_rad,
        max_gap_s: 0.5,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::down::gravity_of;
    use crate::io::recording::GnssFix;

    fn options(choice: ReferenceChoice, min_speed: Option<f64>) -> ReferenceOptions {
        ReferenceOptions {
            choice,
            min_course_speed_mps: min_speed,
            ..ReferenceOptions::default()
        }
    }

    #[test]
    fn a_reference_column_wins_over_gps() {
        let level = gravity_of(&Recording::default(), 1.0);
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
        let auto = options(ReferenceChoice::Auto, Some(5.0));
        assert_eq!(
            choose_reference(&recording, &level, &auto).map(|reference| reference.source),
            Some(ReferenceSource::Column)
        );
        let gps = options(ReferenceChoice::Gps, Some(5.0));
        assert_eq!(
            choose_reference(&recording, &level, &gps).map(|reference| reference.source.label()),
            Some("GPS course")
        );
        assert!(
            choose_reference(&recording, &level, &options(ReferenceChoice::Legs, None)).is_none()
        );
    }

    #[test]
    fn gps_course_counts_only_when_moving_fast_enough() {
        let level = gravity_of(&Recording::default(), 1.0);
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
        let reference = choose_reference(
            &recording,
            &level,
            &options(ReferenceChoice::Auto, Some(5.0)),
        )
        .expect("two fast fixes");
        assert_eq!(reference.heading_rad.t_s, vec![1.0, 2.0]);
        // Auto gates: four fixes are no vehicle, so walking pace counts.
        let auto = choose_reference(&recording, &level, &options(ReferenceChoice::Auto, None))
            .expect("walking");
        assert_eq!(auto.heading_rad.t_s, vec![0.0, 1.0, 2.0, 3.0]);
        assert!(
            choose_reference(&Recording::default(), &level, &ReferenceOptions::default()).is_none()
        );
    }
}
