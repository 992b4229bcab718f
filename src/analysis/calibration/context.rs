//! What every method of one log stands on besides the samples: the reference heading
//! turned onto the compass where it is relative, the declination (the user's or the
//! WMM's), the expected field at the log's place and date, the train/check split, the
//! conditions the networks learn from, and the notes that compare the field with the
//! expected one.

use crate::attitude::down::GravityEstimate;
use crate::earth::wmm::{date_of_unix_s, expected_field, CalendarDate, ExpectedField};
use crate::fit::ellipse::PlaneOptions;
use crate::fit::ellipsoid::{FieldPrior, InertialOptions};
use crate::io::recording::Recording;
use crate::io::SensorFrame;
use crate::reference::ReferenceSource;

use super::{
    DeclinationChoice, DeclinationUsed, FIELD_RATIO_WARNING, MAX_CONDITION_GAP_S, MAX_FIT_SAMPLES,
};

/// The temperature and the gyro's heading at each sample, where the log has them: the
/// conditions the neural heading model takes as inputs.
pub(super) fn conditions(
    recording: &Recording,
    t_s: &[f64],
    gravity: &GravityEstimate,
) -> (Vec<Option<f64>>, Vec<Option<f64>>) {
    let temp_c: Vec<Option<f64>> = t_s
        .iter()
        .map(|&t_s| recording.temp_c.interpolate_at(t_s, MAX_CONDITION_GAP_S))
        .collect();
    let gyro = crate::reference::gyro::gyro_heading(recording, gravity, None, false);
    let gyro_heading_deg: Vec<Option<f64>> = t_s
        .iter()
        .map(|&t_s| {
            gyro.as_ref()
                .and_then(|gyro| {
                    gyro.heading_rad
                        .interpolate_angle_at(t_s, MAX_CONDITION_GAP_S)
                })
                .map(f64::to_degrees)
        })
        .collect();
    (temp_c, gyro_heading_deg)
}

/// What the user should know about the raw field's size and a missing reference.
pub(super) fn field_and_reference_notes(
    mean_raw_field_ut: f64,
    expected: Option<&ExpectedField>,
    has_reference: bool,
) -> Vec<String> {
    let mut notes = Vec::new();
    if let Some(expected) = expected {
        let ratio = mean_raw_field_ut / expected.total_ut;
        if !(1.0 / FIELD_RATIO_WARNING..=FIELD_RATIO_WARNING).contains(&ratio) {
            notes.push(format!(
                "the raw field averages {mean_raw_field_ut:.1} µT where {:.1} µT is expected: wrong units, or a magnet \
                 or iron close to the sensor",
                expected.total_ut
            ));
        }
    }
    if !has_reference {
        notes.push(
            "the log has no reference heading (a ref_heading_deg column, or GPS course while moving), so heading \
             errors cannot be computed"
                .to_string(),
        );
    }
    notes
}

/// A relative reference (a gyro heading that does not know north) turned onto the raw
/// compass heading's circular mean: the methods are then compared on the shape of their
/// heading, not on a constant offset that nothing here can observe. The note says so.
pub(super) fn turn_onto_raw_heading(
    source: ReferenceSource,
    raw_heading_rad: &[f64],
    ref_heading_rad: &mut [Option<f64>],
) -> String {
    let (sum_sin, sum_cos) = raw_heading_rad
        .iter()
        .zip(ref_heading_rad.iter())
        .filter_map(|(&raw_rad, &reference_rad)| Some(raw_rad - reference_rad?))
        .fold((0.0, 0.0), |(sum_sin, sum_cos), offset_rad| {
            (sum_sin + offset_rad.sin(), sum_cos + offset_rad.cos())
        });
    let offset_rad = sum_sin.atan2(sum_cos);
    for reference_rad in ref_heading_rad.iter_mut().flatten() {
        *reference_rad = crate::base::angle::wrap_to_2pi(*reference_rad + offset_rad);
    }
    format!(
        "the reference ({}) does not know north, so it was turned by {:.1}° onto the raw compass heading's \
         mean: constant offsets (declination, misalignment) cannot be judged against it",
        source.label(),
        offset_rad.to_degrees()
    )
}

/// The declination the headings use: the user's, else the model's at the log's place and
/// date, else an autopilot's own (its heading, the reference, was made with it), else 0°
/// (with a note when the reference is absolute, so that it matters).
pub(super) fn declination_used(
    (choice, autopilot): (DeclinationChoice, Option<(f64, &str)>),
    expected: Option<&ExpectedField>,
    reference_source: Option<ReferenceSource>,
    notes: &mut Vec<String>,
) -> DeclinationUsed {
    if let (DeclinationChoice::Auto, None, Some((declination_deg, param))) =
        (choice, expected, autopilot)
    {
        return DeclinationUsed {
            declination_deg,
            source: format!(
                "the autopilot's own ({param}); the log has no position for the magnetic model"
            ),
        };
    }
    match (choice, expected) {
        (DeclinationChoice::Degrees(declination_deg), _) => DeclinationUsed {
            declination_deg,
            source: "given by the user".to_string(),
        },
        (DeclinationChoice::Auto, Some(expected)) => DeclinationUsed {
            declination_deg: expected.declination_deg,
            source: format!(
                "{} on {} at the log's first position",
                expected.model, expected.model_date
            ),
        },
        (DeclinationChoice::Auto, None) => {
            if reference_source.is_some_and(|source| source != ReferenceSource::Column) {
                notes.push(
                    "no position and date for the magnetic model, so the declination is taken as 0°; give \
                     --declination DEG for true headings"
                        .to_string(),
                );
            }
            DeclinationUsed {
                declination_deg: 0.0,
                source: super::NO_DECLINATION_SOURCE.to_string(),
            }
        }
    }
}

/// The one train/check split by time of an analysis, and the train samples the fits
/// see: every method, field-domain or learnt, sees only train samples and is scored on
/// check samples it never saw.
#[derive(Debug, Clone, PartialEq)]
pub struct Split {
    /// The last train time (s); `None` when every sample trains (no check part).
    pub train_until_s: Option<f64>,
    /// Per sample: on the train part.
    pub is_train: Vec<bool>,
    /// Per sample: one of the train samples the fits are given (at most
    /// [`MAX_FIT_SAMPLES`], evenly spread).
    pub is_fit: Vec<bool>,
    pub n_train: usize,
    pub n_check: usize,
}

/// Train up to `train_until_s` (given, else the middle of the referenced samples), check
/// after; the fits see at most [`MAX_FIT_SAMPLES`] of the train samples.
pub(super) fn split(
    t_s: &[f64],
    ref_heading_rad: &[Option<f64>],
    train_until_s: Option<f64>,
    notes: &mut Vec<String>,
) -> Split {
    let train_until_s = train_until_s.or_else(|| {
        let referenced: Vec<f64> = t_s
            .iter()
            .zip(ref_heading_rad)
            .filter(|(_, reference)| reference.is_some())
            .map(|(&t_s, _)| t_s)
            .collect();
        // Half of the referenced samples on each side: a sparse tail of reference (a
        // few fixes at the end of a drive) does not move the split.
        let middle = referenced.len() / 2;
        match (
            referenced.first(),
            referenced.get(middle),
            referenced.last(),
        ) {
            (Some(first_s), Some(&middle_s), Some(last_s)) if last_s > first_s => Some(middle_s),
            _ => None,
        }
    });
    let is_train: Vec<bool> = t_s
        .iter()
        .map(|&t_s| train_until_s.is_none_or(|until_s| t_s <= until_s))
        .collect();
    let n_train = is_train.iter().filter(|&&train| train).count();
    let n_check = is_train.len() - n_train;
    // The fits see at most MAX_FIT_SAMPLES of the train samples, evenly spread: more add
    // little to parameters fitted from thousands of samples, and cost the page seconds.
    let fit_stride = n_train.div_ceil(MAX_FIT_SAMPLES).max(1);
    let mut n_train_seen = 0usize;
    let is_fit: Vec<bool> = is_train
        .iter()
        .map(|&train| {
            let fit = train && n_train_seen.is_multiple_of(fit_stride);
            n_train_seen += usize::from(train);
            fit
        })
        .collect();
    if fit_stride > 1 {
        notes.push(format!(
            "the methods were fitted to every {} train sample ({} of {n_train})",
            crate::base::words::ordinal(fit_stride),
            n_train.div_ceil(fit_stride)
        ));
    }
    Split {
        train_until_s,
        is_train,
        is_fit,
        n_train,
        n_check,
    }
}

/// What [`super::calibrate`] tells the tilt-aware ellipse fit: the model's dip at the
/// log's place.
pub fn plane_options(expected: Option<&ExpectedField>) -> PlaneOptions {
    PlaneOptions {
        inclination_deg: expected.map(|expected| expected.inclination_deg),
        ..PlaneOptions::default()
    }
}

/// What [`super::calibrate`] tells the 3D fit: the model's intensity and dip as priors,
/// and whether the sensor's gain is known (values in µT, or converted to µT, come with
/// the sensor's factory gains; raw counts do not).
pub fn inertial_options(
    expected: Option<&ExpectedField>,
    mag_frame: Option<&SensorFrame>,
) -> InertialOptions {
    InertialOptions {
        field: expected.map(|expected| FieldPrior {
            total_ut: expected.total_ut,
            inclination_deg: expected.inclination_deg,
        }),
        gain_known: mag_frame.is_none_or(|frame| frame.unit.ut_per_unit.is_some()),
    }
}

/// The day the model is evaluated on when the log has a position but no date: the
/// current model's epoch (WMM2025). The field changes by well under 1° and 1 % in the
/// five years a model covers, less than a compass's other errors.
const MODEL_EPOCH_WITHOUT_DATE: CalendarDate = CalendarDate {
    year: 2025,
    month: 1,
    day: 1,
};

/// The expected field at the log's first position (the user's, else the first GNSS fix,
/// else the first reference position given as latitude and longitude) and date (the
/// model's epoch when the log has none, with a note), with a note when the model warns:
/// what [`super::calibrate`] gives the fits as priors (public for the fit benchmark,
/// which feeds the fits as `calibrate` does).
pub fn expected_field_of(
    recording: &Recording,
    position_deg: Option<(f64, f64)>,
    notes: &mut Vec<String>,
) -> Option<ExpectedField> {
    let given = position_deg.map(|(lat_deg, lon_deg)| (lat_deg, lon_deg, 0.0));
    let position = given
        .or_else(|| {
            recording
                .gnss
                .values
                .iter()
                .find_map(|fix| Some((fix.lat_deg?, fix.lon_deg?, fix.alt_m.unwrap_or(0.0))))
        })
        .or_else(|| {
            recording
                .ref_position_lat_lon_deg
                .values
                .first()
                .map(|lat_lon| (lat_lon.x, lat_lon.y, 0.0))
        });
    let (lat_deg, lon_deg, alt_m) = position?;
    let date = match recording.start_unix_s.and_then(date_of_unix_s) {
        Some(date) => date,
        None => {
            notes.push(format!(
                "the log gives a position but no date: the magnetic model was evaluated at \
                 its epoch, {MODEL_EPOCH_WITHOUT_DATE}; the field changes by well under 1° and \
                 1 % in five years"
            ));
            MODEL_EPOCH_WITHOUT_DATE
        }
    };
    match expected_field(lat_deg, lon_deg, alt_m, date) {
        Ok(expected) => {
            notes.extend(expected.warnings.iter().map(ToString::to_string));
            Some(expected)
        }
        Err(error) => {
            notes.push(format!("no magnetic model value: {error}"));
            None
        }
    }
}
