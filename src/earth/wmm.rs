//! The Earth's field expected at a place and date, from the World Magnetic Model (WMM).
//!
//! Source: the NOAA/BGS World Magnetic Model, WMM2020 (technical report
//! doi:10.25923/ytk1-yx35) and WMM2025 (doi:10.25923/prbc-s316), a degree-12 spherical
//! harmonic model of the core field with a linear secular variation over each five-year
//! epoch. It is evaluated by the `world_magnetic_model` crate (1.2025), which carries
//! both coefficient sets and so covers 2020-01-01 to 2029-12-31; the answers are
//! checked below against Table 6 of both reports.
//!
//! What the answers mean: declination `D` is the angle from true north to the
//! horizontal field, positive east, so `true heading = magnetic heading + D`;
//! inclination `I` is the angle of the field below the horizontal (positive down, as
//! in the northern hemisphere); `Z` (here `vertical_ut`) is the downward component.
//!
//! Limits:
//! - The model gives the core field only. Crustal anomalies, buildings, vehicles and
//!   magnetic storms are not in it; the reports put the global 1σ error at about 0.26°
//!   of declination away from the magnetic poles and about 0.14 µT of total intensity.
//!   The declination uncertainty for the place is returned with the answer.
//! - Near the magnetic poles the horizontal field is weak and a compass is unreliable;
//!   the answer then carries the report's caution or blackout warning (§1.8).
//! - Altitude is height above the WGS 84 ellipsoid. A GNSS altitude above mean sea
//!   level differs from it by the geoid height (under 110 m), which changes nothing
//!   that matters here.
//!
//! Dates outside the covered years: a recording made before 2020 (the Hangzhou walks of
//! November 2019, an ArduPilot flight of 2015) or after 2029 still gets an expected
//! field, since a declination of 0° would be wrong by the whole declination (12° at
//! Canberra). Each component of the field is extrapolated along the model's own
//! secular variation (the straight line through the first, or the last, covered year),
//! up to [`MAX_YEARS_OUTSIDE_MODEL`] away, and the answer carries a
//! [`WmmWarning::Extrapolated`] with a declination uncertainty that grows by
//! [`EXTRAPOLATED_DECLINATION_SIGMA_DEG_PER_YEAR`] a year. Both figures were set
//! against IGRF-14, an independent model whose coefficients are definitive for those
//! years (`tests/data/igrf14_field.py`, checked in `tests/wmm_against_igrf.rs`). Further
//! away the date is refused, and the message says to give the declination by hand.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;
use thiserror::Error;
use world_magnetic_model::time::{Date, Month};
use world_magnetic_model::uom::si::angle::degree;
use world_magnetic_model::uom::si::f32::{Angle, Length};
use world_magnetic_model::uom::si::length::meter;
use world_magnetic_model::uom::si::magnetic_flux_density::microtesla;
use world_magnetic_model::GeomagneticField;

/// The first day the bundled models cover (WMM2020's epoch).
pub const FIRST_MODEL_DATE: CalendarDate = CalendarDate {
    year: 2020,
    month: 1,
    day: 1,
};

/// The last day the bundled models cover (the end of WMM2025's five years).
pub const LAST_MODEL_DATE: CalendarDate = CalendarDate {
    year: 2029,
    month: 12,
    day: 31,
};

/// How far outside the covered years (in years) a date may lie and still be
/// extrapolated rather than refused: IGRF-14 at random places over 1990-2019
/// (`tests/data/igrf14_field.csv`) bounds the error there (`tests/independent.rs`).
pub const MAX_YEARS_OUTSIDE_MODEL: f64 = 30.0;

/// How much the declination's 1σ grows per year of extrapolation, beyond the model's
/// own σ at the place: from IGRF-14 at random places and dates (see
/// [`MAX_YEARS_OUTSIDE_MODEL`]).
pub const EXTRAPOLATED_DECLINATION_SIGMA_DEG_PER_YEAR: f64 = 0.05;

// The model's validity in altitude (WMM2025 TR §1.2; the crate's own bounds).
const MIN_ALT_M: f64 = -1_000.0;
const MAX_ALT_M: f64 = 850_000.0;

/// A day of the Gregorian calendar (UTC), so that callers need not know the `time`
/// crate. `month` is 1-12 and `day` 1-31.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct CalendarDate {
    pub year: i32,
    pub month: u8,
    pub day: u8,
}

impl CalendarDate {
    /// Checks that the day exists (30 February does not).
    pub fn new(year: i32, month: u8, day: u8) -> Result<Self, WmmError> {
        let date = CalendarDate { year, month, day };
        if (1..=12).contains(&month) && day >= 1 && day <= days_in_month(year, month) {
            Ok(date)
        } else {
            Err(WmmError::InvalidDate { year, month, day })
        }
    }

    /// Days since 1970-01-01 (negative before), for a valid date.
    fn days_since_unix_epoch(self) -> i64 {
        crate::base::calendar::days_from_civil(
            i64::from(self.year),
            u32::from(self.month),
            u32::from(self.day),
        )
    }

    fn to_time_date(self) -> Result<Date, WmmError> {
        let invalid = WmmError::InvalidDate {
            year: self.year,
            month: self.month,
            day: self.day,
        };
        let month = Month::try_from(self.month).map_err(|_| invalid.clone())?;
        Date::from_calendar_date(self.year, month, self.day).map_err(|_| invalid)
    }
}

impl fmt::Display for CalendarDate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:04}-{:02}-{:02}", self.year, self.month, self.day)
    }
}

impl FromStr for CalendarDate {
    type Err = WmmError;

    /// Reads `YYYY-MM-DD`.
    fn from_str(text: &str) -> Result<Self, WmmError> {
        let not_a_date = || WmmError::UnreadableDate {
            text: text.chars().take(40).collect(),
        };
        let mut parts = text.trim().splitn(3, '-');
        let (Some(year), Some(month), Some(day)) = (parts.next(), parts.next(), parts.next())
        else {
            return Err(not_a_date());
        };
        let all_digits = |part: &str| !part.is_empty() && part.bytes().all(|b| b.is_ascii_digit());
        if !(all_digits(year) && all_digits(month) && all_digits(day)) {
            return Err(not_a_date());
        }
        CalendarDate::new(
            year.parse().map_err(|_| not_a_date())?,
            month.parse().map_err(|_| not_a_date())?,
            day.parse().map_err(|_| not_a_date())?,
        )
    }
}

/// The field the model expects at one place and date.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExpectedField {
    /// From true north to the horizontal field, positive east.
    pub declination_deg: f64,
    /// Below the horizontal, positive down.
    pub inclination_deg: f64,
    /// Total intensity F.
    pub total_ut: f64,
    /// Horizontal intensity H.
    pub horizontal_ut: f64,
    /// Downward component Z (negative in the southern magnetic hemisphere).
    pub vertical_ut: f64,
    /// The model's 1σ uncertainty of the declination here; it grows near the magnetic
    /// poles, where the horizontal field is weak.
    pub declination_uncertainty_deg: f64,
    /// Which model was evaluated, e.g. `"WMM2020"`, or `"WMM2020 extrapolated 4.1 years
    /// back"` ([`WmmWarning::Extrapolated`]).
    pub model: String,
    /// The day the field is for.
    pub model_date: CalendarDate,
    /// What the user should know about this answer; empty when nothing.
    pub warnings: Vec<WmmWarning>,
}

/// Something the user should know about an [`ExpectedField`]. `Display` gives a sentence.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WmmWarning {
    /// The date lies `years` outside the covered years (negative before them, at most
    /// [`MAX_YEARS_OUTSIDE_MODEL`]): the field was extrapolated with the model's secular
    /// variation, and the declination is known to `declination_uncertainty_deg` (1σ).
    Extrapolated {
        requested_date: CalendarDate,
        years: f64,
        declination_uncertainty_deg: f64,
    },
    /// Horizontal field between 2 and 6 µT: use a compass with caution (WMM2025 TR §1.8).
    CautionZone { horizontal_ut: f64 },
    /// Horizontal field under 2 µT: a compass is unreliable here (WMM2025 TR §1.8).
    BlackoutZone { horizontal_ut: f64 },
}

impl fmt::Display for WmmWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WmmWarning::Extrapolated {
                requested_date,
                years,
                declination_uncertainty_deg,
            } => write!(
                f,
                "{requested_date} is {:.1} years {} the years the World Magnetic Model in this \
                 build covers ({FIRST_MODEL_DATE} to {LAST_MODEL_DATE}); the field was \
                 extrapolated with the model's own secular variation, so the declination is \
                 known to about ±{declination_uncertainty_deg:.1}° (1σ) here. Give \
                 --declination DEG if you know a better value.",
                years.abs(),
                if *years < 0.0 { "before" } else { "after" }
            ),
            WmmWarning::CautionZone { horizontal_ut } => write!(
                f,
                "the horizontal field here is only {horizontal_ut:.1} µT (near a magnetic \
                 pole): compass headings and the declination are less accurate than usual."
            ),
            WmmWarning::BlackoutZone { horizontal_ut } => write!(
                f,
                "the horizontal field here is only {horizontal_ut:.1} µT (at a magnetic \
                 pole): a compass is unreliable and the declination is meaningless."
            ),
        }
    }
}

/// Why the expected field could not be computed. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WmmError {
    #[error(
        "latitude {lat_deg}° is outside -90° to 90°. Check that latitude and longitude are \
         not swapped, or give --declination DEG."
    )]
    LatitudeOutOfRange { lat_deg: f64 },

    #[error(
        "longitude {lon_deg}° is outside -180° to 180° (east positive, west negative). \
         Give it in that range, or give --declination DEG."
    )]
    LongitudeOutOfRange { lon_deg: f64 },

    #[error(
        "altitude {alt_m} m is outside the model's range (-1 km to 850 km above the WGS 84 \
         ellipsoid). Give the altitude in metres, or leave it out to use 0 m."
    )]
    AltitudeOutOfRange { alt_m: f64 },

    #[error("{year:04}-{month:02}-{day:02} is not a calendar date. Give the date as YYYY-MM-DD.")]
    InvalidDate { year: i32, month: u8, day: u8 },

    #[error("\"{text}\" is not a date. Give the date as YYYY-MM-DD, for example 2023-08-09.")]
    UnreadableDate { text: String },

    #[error(
        "{date} is more than {max} years outside the years the World Magnetic Model in this \
         build covers ({first} to {last}: WMM2020 and WMM2025), too far to extrapolate. \
         Give --declination DEG (NOAA's online calculator gives it for past dates), or \
         update compass-pdr for later dates.",
        max = MAX_YEARS_OUTSIDE_MODEL
    )]
    DateOutsideModel {
        date: CalendarDate,
        first: CalendarDate,
        last: CalendarDate,
    },
}

/// The field the World Magnetic Model expects at `lat_deg`, `lon_deg` (WGS 84, east and
/// north positive), `alt_m` above the WGS 84 ellipsoid, on `date`.
///
/// Dates outside the covered years, up to [`MAX_YEARS_OUTSIDE_MODEL`] away, are
/// extrapolated with the model's own secular variation, with a warning and a wider
/// declination uncertainty; see the module header.
pub fn expected_field(
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    date: CalendarDate,
) -> Result<ExpectedField, WmmError> {
    // `contains` is false for NaN, so non-finite values are refused too.
    if !(-90.0..=90.0).contains(&lat_deg) {
        return Err(WmmError::LatitudeOutOfRange { lat_deg });
    }
    if !(-180.0..=180.0).contains(&lon_deg) {
        return Err(WmmError::LongitudeOutOfRange { lon_deg });
    }
    if !(MIN_ALT_M..=MAX_ALT_M).contains(&alt_m) {
        return Err(WmmError::AltitudeOutOfRange { alt_m });
    }
    let date = CalendarDate::new(date.year, date.month, date.day)?;
    let at = |day: CalendarDate| evaluate(lat_deg, lon_deg, alt_m, day, date);
    let (field, model, mut warnings) = match outside_model(date)? {
        None => (at(date)?, model_at(date), Vec::new()),
        Some((from, to, years)) => {
            // Each component changes linearly over a model's five years (its secular
            // variation); the same line is followed beyond them.
            let (first, second) = (at(from)?, at(to)?);
            let days = (date.days_since_unix_epoch() - from.days_since_unix_epoch()) as f64;
            let per_day = 1.0 / (to.days_since_unix_epoch() - from.days_since_unix_epoch()) as f64;
            let xyz_ut: [f64; 3] = std::array::from_fn(|axis| {
                first.xyz_ut[axis] + (second.xyz_ut[axis] - first.xyz_ut[axis]) * days * per_day
            });
            let [x, y, z] = xyz_ut;
            let horizontal_ut = x.hypot(y);
            let sigma_deg = first.declination_uncertainty_deg
                + EXTRAPOLATED_DECLINATION_SIGMA_DEG_PER_YEAR * years.abs();
            let field = Evaluated {
                xyz_ut,
                declination_deg: y.atan2(x).to_degrees(),
                inclination_deg: z.atan2(horizontal_ut).to_degrees(),
                total_ut: horizontal_ut.hypot(z),
                horizontal_ut,
                declination_uncertainty_deg: sigma_deg,
            };
            let model = format!(
                "{} extrapolated {:.1} years {}",
                model_at(from),
                years.abs(),
                if years < 0.0 { "back" } else { "on" }
            );
            let warning = WmmWarning::Extrapolated {
                requested_date: date,
                years,
                declination_uncertainty_deg: sigma_deg,
            };
            (field, model, vec![warning])
        }
    };
    let horizontal_ut = field.horizontal_ut;
    if horizontal_ut < BLACKOUT_ZONE_H_UT {
        warnings.push(WmmWarning::BlackoutZone { horizontal_ut });
    } else if horizontal_ut < CAUTION_ZONE_H_UT {
        warnings.push(WmmWarning::CautionZone { horizontal_ut });
    }
    Ok(ExpectedField {
        declination_deg: field.declination_deg,
        inclination_deg: field.inclination_deg,
        total_ut: field.total_ut,
        horizontal_ut,
        vertical_ut: field.xyz_ut[2],
        declination_uncertainty_deg: field.declination_uncertainty_deg,
        model,
        model_date: date,
        warnings,
    })
}

/// Horizontal fields under these (µT) are the WMM reports' blackout and caution zones
/// (WMM2025 TR §1.8), as the crate's `declination_warning` has them.
const BLACKOUT_ZONE_H_UT: f64 = 2.0;
const CAUTION_ZONE_H_UT: f64 = 6.0;

/// The model covering a date (each covers the five years from its epoch: 2020-2024,
/// 2025-2029).
fn model_at(date: CalendarDate) -> String {
    format!("WMM{}", date.year.div_euclid(5) * 5)
}

/// The field at one place and day: as the crate gives it on a covered day, or as
/// [`expected_field`] extrapolates it.
struct Evaluated {
    /// North, east and down (µT).
    xyz_ut: [f64; 3],
    declination_deg: f64,
    inclination_deg: f64,
    total_ut: f64,
    horizontal_ut: f64,
    declination_uncertainty_deg: f64,
}

fn evaluate(
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    day: CalendarDate,
    requested: CalendarDate,
) -> Result<Evaluated, WmmError> {
    // The crate computes in f32 (about 7 digits), far finer than the model's accuracy.
    let field = GeomagneticField::new(
        Length::new::<meter>(alt_m as f32),
        Angle::new::<degree>(lat_deg as f32),
        Angle::new::<degree>(lon_deg as f32),
        day.to_time_date()?,
    )
    .map_err(|error| from_model_error(error, lat_deg, lon_deg, alt_m, requested))?;
    let ut = |value: world_magnetic_model::uom::si::f32::MagneticFluxDensity| {
        f64::from(value.get::<microtesla>())
    };
    Ok(Evaluated {
        xyz_ut: [ut(field.x()), ut(field.y()), ut(field.z())],
        declination_deg: f64::from(field.declination().get::<degree>()),
        inclination_deg: f64::from(field.inclination().get::<degree>()),
        total_ut: ut(field.f()),
        horizontal_ut: ut(field.h()),
        declination_uncertainty_deg: f64::from(field.declination_uncertainty().get::<degree>()),
    })
}

/// The UTC calendar date of a Unix time in seconds; `None` when it is not finite or
/// absurdly far (more than a million years) from 1970.
pub fn date_of_unix_s(unix_s: f64) -> Option<CalendarDate> {
    let (year, month, day) = crate::base::calendar::civil_from_unix_s(unix_s)?;
    Some(CalendarDate {
        year: i32::try_from(year).ok()?,
        month: u8::try_from(month).ok()?,
        day: u8::try_from(day).ok()?,
    })
}

/// `None` when the model covers `date`; else the first and last day of the covered year
/// nearest to it (the line extrapolated), and how many years (negative before) `date`
/// lies outside the covered years: an error beyond [`MAX_YEARS_OUTSIDE_MODEL`].
fn outside_model(
    date: CalendarDate,
) -> Result<Option<(CalendarDate, CalendarDate, f64)>, WmmError> {
    let days = date.days_since_unix_epoch();
    let first_days = FIRST_MODEL_DATE.days_since_unix_epoch();
    let last_days = LAST_MODEL_DATE.days_since_unix_epoch();
    let (from, to, years) = if days < first_days {
        let year_later = CalendarDate {
            year: FIRST_MODEL_DATE.year + 1,
            ..FIRST_MODEL_DATE
        };
        (
            FIRST_MODEL_DATE,
            year_later,
            (days - first_days) as f64 / DAYS_PER_YEAR,
        )
    } else if days > last_days {
        let year_before = CalendarDate {
            year: LAST_MODEL_DATE.year - 1,
            ..LAST_MODEL_DATE
        };
        (
            year_before,
            LAST_MODEL_DATE,
            (days - last_days) as f64 / DAYS_PER_YEAR,
        )
    } else {
        return Ok(None);
    };
    if years.abs() > MAX_YEARS_OUTSIDE_MODEL {
        return Err(WmmError::DateOutsideModel {
            date,
            first: FIRST_MODEL_DATE,
            last: LAST_MODEL_DATE,
        });
    }
    Ok(Some((from, to, years)))
}

/// The mean Gregorian year.
const DAYS_PER_YEAR: f64 = 365.2425;

/// The crate's own refusals, in this module's words. The checks above make them
/// unreachable unless the crate's limits change.
fn from_model_error(
    error: world_magnetic_model::Error,
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    date: CalendarDate,
) -> WmmError {
    use world_magnetic_model::Error as ModelError;
    match error {
        ModelError::InvalidLatitude => WmmError::LatitudeOutOfRange { lat_deg },
        ModelError::InvalidLongitude => WmmError::LongitudeOutOfRange { lon_deg },
        ModelError::HeightOutsideOfValidityRange { .. } => WmmError::AltitudeOutOfRange { alt_m },
        ModelError::DateOutsideOfValidityRange { .. } => WmmError::DateOutsideModel {
            date,
            first: FIRST_MODEL_DATE,
            last: LAST_MODEL_DATE,
        },
    }
}

fn is_leap_year(year: i32) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

fn days_in_month(year: i32, month: u8) -> u8 {
    match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap_year(year) => 29,
        2 => 28,
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn date(year: i32, month: u8, day: u8) -> CalendarDate {
        CalendarDate::new(year, month, day).expect("a valid test date")
    }

    fn check_close(what: &str, actual: f64, expected: f64, tolerance: f64) {
        assert!(
            (actual - expected).abs() <= tolerance,
            "{what}: {actual} is not within {tolerance} of {expected}"
        );
    }

    /// WMM2020 TR Table 6 and WMM2025 TR Table 6 (the reports' test values, also in the
    /// `world_magnetic_model` crate's tests): date, height (km), latitude, longitude
    /// (240° written as −120°), then X, Y, Z, H, F (nT) and I, D (°). 2027.5 is
    /// 2027-07-03 (day 184, as the crate's own test converts it).
    type Table6Row = (CalendarDate, f64, f64, f64, [f64; 5], [f64; 2]);
    #[rustfmt::skip]
    const TABLE_6: [Table6Row; 12] = {
        const fn d(year: i32, month: u8, day: u8) -> CalendarDate { CalendarDate { year, month, day } }
        [
            (d(2020, 1, 1), 0.0, 80.0, 0.0, [6570.4, -146.3, 54606.0, 6572.0, 55000.1], [83.14, -1.28]),
            (d(2020, 1, 1), 0.0, 0.0, 120.0, [39624.3, 109.9, -10932.5, 39624.4, 41104.9], [-15.42, 0.16]),
            (d(2020, 1, 1), 0.0, -80.0, -120.0, [5940.6, 15772.1, -52480.8, 16853.8, 55120.6], [-72.20, 69.36]),
            (d(2020, 1, 1), 100.0, 0.0, 120.0, [37636.7, 104.9, -10474.8, 37636.9, 39067.3], [-15.55, 0.16]),
            (d(2025, 1, 1), 0.0, 80.0, 0.0, [6521.6, 145.9, 54791.5, 6523.2, 55178.5], [83.21, 1.28]),
            (d(2025, 1, 1), 0.0, 0.0, 120.0, [39677.8, -109.6, -10580.2, 39677.9, 41064.3], [-14.93, -0.16]),
            (d(2025, 1, 1), 0.0, -80.0, -120.0, [6117.5, 15751.9, -52022.5, 16898.1, 54698.2], [-72.00, 68.78]),
            (d(2025, 1, 1), 100.0, 80.0, 0.0, [6216.0, 92.4, 52598.8, 6216.7, 52964.9], [83.26, 0.85]),
            (d(2025, 1, 1), 100.0, 0.0, 120.0, [37688.6, -96.2, -10152.1, 37688.7, 39032.1], [-15.08, -0.15]),
            (d(2025, 1, 1), 100.0, -80.0, -120.0, [5907.6, 14780.3, -49540.7, 15917.1, 52035.0], [-72.19, 68.21]),
            (d(2027, 7, 3), 0.0, 80.0, 0.0, [6500.8, 294.5, 54869.4, 6507.5, 55253.9], [83.24, 2.59]),
            (d(2027, 7, 3), 100.0, -80.0, -120.0, [5984.0, 14760.1, -49317.7, 15927.0, 51825.7], [-72.10, 67.93]),
        ]
    };

    #[test]
    fn the_reports_test_values_are_reproduced() {
        // Tolerances as in the crate's test: the table is printed to 0.1 nT and 0.01°,
        // and f32 synthesis differs by up to 0.1 nT.
        const TOLERANCE_UT: f64 = 0.2e-3;
        const TOLERANCE_DEG: f64 = 0.03;
        for (date, height_km, lat_deg, lon_deg, [_, _, z_nt, h_nt, f_nt], [i_deg, d_deg]) in TABLE_6
        {
            let field = expected_field(lat_deg, lon_deg, height_km * 1000.0, date)
                .expect("inside the model");
            let place = format!("{date} {height_km} km {lat_deg} {lon_deg}");
            check_close(
                &format!("{place} F"),
                field.total_ut,
                f_nt / 1000.0,
                TOLERANCE_UT,
            );
            check_close(
                &format!("{place} H"),
                field.horizontal_ut,
                h_nt / 1000.0,
                TOLERANCE_UT,
            );
            check_close(
                &format!("{place} Z"),
                field.vertical_ut,
                z_nt / 1000.0,
                TOLERANCE_UT,
            );
            check_close(
                &format!("{place} I"),
                field.inclination_deg,
                i_deg,
                TOLERANCE_DEG,
            );
            check_close(
                &format!("{place} D"),
                field.declination_deg,
                d_deg,
                TOLERANCE_DEG,
            );
            assert_eq!(field.model_date, date);
            assert!(
                field.warnings.is_empty() || lat_deg.abs() == 80.0,
                "{place}: {:?}",
                field.warnings
            );
        }
    }

    #[test]
    fn the_model_is_named_by_its_epoch() {
        let model_at = |date| {
            expected_field(45.0, 10.0, 0.0, date)
                .expect("covered")
                .model
        };
        assert_eq!(model_at(date(2020, 1, 1)), "WMM2020");
        assert_eq!(model_at(date(2024, 12, 31)), "WMM2020");
        assert_eq!(model_at(date(2025, 1, 1)), "WMM2025");
        assert_eq!(model_at(date(2029, 12, 31)), "WMM2025");
    }

    #[test]
    fn hangzhou_in_november_2019_is_extrapolated_with_a_warning() {
        // ../shared/data README: about 48 µT, inclination about 46°, declination about −5°.
        // WMM2020 at 2020-01-01 gives 48.76 µT, 46.02° and −5.70°.
        let field = expected_field(30.3, 120.1, 0.0, date(2019, 11, 15)).expect("near enough");
        check_close("F", field.total_ut, 48.0, 1.0);
        check_close("I", field.inclination_deg, 46.0, 0.5);
        check_close("D", field.declination_deg, -5.0, 1.0);
        assert_eq!(field.model_date, date(2019, 11, 15));
        assert_eq!(field.model, "WMM2020 extrapolated 0.1 years back");
        let [WmmWarning::Extrapolated {
            requested_date,
            years,
            declination_uncertainty_deg,
        }] = field.warnings[..]
        else {
            panic!("{:?}", field.warnings);
        };
        assert_eq!(requested_date, date(2019, 11, 15));
        check_close("years", years, -47.0 / DAYS_PER_YEAR, 1e-9);
        assert_eq!(
            declination_uncertainty_deg,
            field.declination_uncertainty_deg
        );
        let sentence = field.warnings[0].to_string();
        assert!(
            sentence.contains("2019-11-15 is 0.1 years before"),
            "{sentence}"
        );
        assert!(sentence.contains("--declination DEG"), "{sentence}");
    }

    #[test]
    fn canberra_in_2015_gets_its_declination_not_zero() {
        // ArduPilot's log171 (../shared/data): Canberra, 2015-11-21. IGRF-14 gives
        // D 12.40°, and the extrapolation's stated 1σ covers the difference.
        let field =
            expected_field(-35.3624, 149.1659, 0.0, date(2015, 11, 21)).expect("extrapolated");
        check_close(
            "D",
            field.declination_deg,
            12.40,
            field.declination_uncertainty_deg,
        );
        assert!(field.declination_uncertainty_deg < 0.6, "{field:?}");
        assert!(field
            .model
            .starts_with("WMM2020 extrapolated 4.1 years back"));
    }

    #[test]
    fn the_pennsylvania_drive_of_2023_has_declination_near_minus_eleven_and_a_half() {
        // ../shared/data README: near 40.0 N, 75.2 W in 2023 declination is about −11.5°.
        // WMM2020 on the day of the drive gives −11.90°.
        let field = expected_field(40.0, -75.2, 0.0, date(2023, 8, 9)).expect("covered");
        check_close("D", field.declination_deg, -11.5, 0.5);
        assert!(field.warnings.is_empty());
        assert_eq!(field.model_date, date(2023, 8, 9));
    }

    #[test]
    fn dates_more_than_thirty_years_outside_are_refused_with_what_to_do() {
        assert!(expected_field(30.3, 120.1, 0.0, date(1990, 1, 2)).is_ok());
        assert!(expected_field(30.3, 120.1, 0.0, date(2059, 12, 30)).is_ok());
        for far in [date(1989, 12, 30), date(2060, 1, 2), date(1900, 6, 1)] {
            let error = expected_field(30.3, 120.1, 0.0, far).expect_err("too far");
            assert_eq!(
                error,
                WmmError::DateOutsideModel {
                    date: far,
                    first: FIRST_MODEL_DATE,
                    last: LAST_MODEL_DATE,
                }
            );
            let message = error.to_string();
            assert!(message.contains("more than 30 years outside"), "{message}");
            assert!(message.contains("--declination DEG"), "{message}");
            assert!(message.contains("2020-01-01 to 2029-12-31"), "{message}");
        }
    }

    #[test]
    fn after_2029_the_last_covered_year_is_extrapolated() {
        let field = expected_field(40.0, -75.2, 0.0, date(2030, 3, 1)).expect("near enough");
        assert_eq!(field.model_date, date(2030, 3, 1));
        assert_eq!(field.model, "WMM2025 extrapolated 0.2 years on");
        // Along the last covered year's line: its two ends and this day in a row.
        let ends = [date(2028, 12, 31), date(2029, 12, 31)].map(|day| {
            expected_field(40.0, -75.2, 0.0, day)
                .expect("covered")
                .declination_deg
        });
        let per_day = (ends[1] - ends[0]) / 365.0;
        check_close("D", field.declination_deg, ends[1] + 60.0 * per_day, 0.01);
        assert!(matches!(
            field.warnings.as_slice(),
            [WmmWarning::Extrapolated { years, .. }] if *years > 0.0
        ));
    }

    #[test]
    fn the_covered_years_agree_with_the_crate() {
        // If a new crate version carries other models, these constants must follow.
        let refused = GeomagneticField::new(
            Length::new::<meter>(0.0),
            Angle::new::<degree>(0.0),
            Angle::new::<degree>(0.0),
            Date::from_calendar_date(2019, Month::December, 31).expect("a date"),
        );
        assert_eq!(
            refused.err(),
            Some(world_magnetic_model::Error::DateOutsideOfValidityRange {
                min_date: FIRST_MODEL_DATE.to_time_date().expect("a date"),
                max_date: LAST_MODEL_DATE.to_time_date().expect("a date"),
            })
        );
    }

    #[test]
    fn places_outside_the_globe_are_refused() {
        let on = date(2025, 6, 1);
        assert_eq!(
            expected_field(90.5, 0.0, 0.0, on),
            Err(WmmError::LatitudeOutOfRange { lat_deg: 90.5 })
        );
        assert_eq!(
            expected_field(0.0, -180.5, 0.0, on),
            Err(WmmError::LongitudeOutOfRange { lon_deg: -180.5 })
        );
        assert_eq!(
            expected_field(0.0, 0.0, 900_000.0, on),
            Err(WmmError::AltitudeOutOfRange { alt_m: 900_000.0 })
        );
        assert!(matches!(
            expected_field(f64::NAN, 0.0, 0.0, on),
            Err(WmmError::LatitudeOutOfRange { .. })
        ));
        assert!(matches!(
            expected_field(0.0, f64::INFINITY, 0.0, on),
            Err(WmmError::LongitudeOutOfRange { .. })
        ));
        assert!(
            expected_field(90.0, 180.0, -1000.0, on).is_ok(),
            "the edges are inside"
        );
        let invalid = CalendarDate {
            year: 2025,
            month: 2,
            day: 29,
        };
        assert_eq!(
            expected_field(0.0, 0.0, 0.0, invalid),
            Err(WmmError::InvalidDate {
                year: 2025,
                month: 2,
                day: 29
            })
        );
        let message = WmmError::LatitudeOutOfRange { lat_deg: 120.1 }.to_string();
        assert!(message.contains("swapped") && message.contains("--declination DEG"));
    }

    #[test]
    fn near_the_magnetic_pole_the_answer_warns() {
        // WMM2025 TR Table 4: the north dip pole at 2025.0 is at 85.762 N, 139.298 E.
        let field = expected_field(85.762, 139.298, 0.0, date(2025, 1, 1)).expect("covered");
        assert!(
            matches!(field.warnings.as_slice(), [WmmWarning::BlackoutZone { .. }]),
            "{:?}",
            field.warnings
        );
        assert!(field.inclination_deg > 89.9);
        assert_eq!(field.declination_uncertainty_deg, 180.0);
    }

    #[test]
    fn unix_times_become_utc_dates() {
        let check = |unix_s: f64, expected: Option<CalendarDate>| {
            assert_eq!(date_of_unix_s(unix_s), expected, "{unix_s}");
        };
        check(0.0, Some(date(1970, 1, 1)));
        check(-1.0, Some(date(1969, 12, 31)));
        check(86_399.9, Some(date(1970, 1, 1)));
        check(951_782_400.0, Some(date(2000, 2, 29))); // a leap day of a century year
        check(1_574_000_000.0, Some(date(2019, 11, 17))); // msft-indoor-2020 era
        check(1_691_599_662.0, Some(date(2023, 8, 9))); // the vehicle drive
        check(4_107_542_399.0, Some(date(2100, 2, 28))); // 2100 is not a leap year
        check(-62_135_596_800.0, Some(date(1, 1, 1)));
        check(f64::NAN, None);
        check(f64::INFINITY, None);
        check(1e300, None);
    }

    #[test]
    fn day_counts_round_trip_over_four_centuries() {
        let start = date(1900, 1, 1).days_since_unix_epoch();
        for days in start..start + 146_097 + 400 {
            let (year, month, day) = crate::base::calendar::civil_from_days(days);
            let date =
                CalendarDate::new(year as i32, month as u8, day as u8).expect("a valid date");
            assert_eq!(date.days_since_unix_epoch(), days);
        }
    }

    #[test]
    fn dates_are_read_and_written_as_iso() {
        assert_eq!("2023-08-09".parse(), Ok(date(2023, 8, 9)));
        assert_eq!(" 2019-11-15 ".parse(), Ok(date(2019, 11, 15)));
        assert_eq!(date(2019, 1, 5).to_string(), "2019-01-05");
        assert_eq!(
            "2023-02-30".parse::<CalendarDate>(),
            Err(WmmError::InvalidDate {
                year: 2023,
                month: 2,
                day: 30
            })
        );
        for text in [
            "",
            "2023",
            "2023-08",
            "2023/08/09",
            "2023-+8-09",
            "2023-08-09T10:00",
        ] {
            assert!(
                matches!(
                    text.parse::<CalendarDate>(),
                    Err(WmmError::UnreadableDate { .. })
                ),
                "{text:?}"
            );
        }
    }

    // serde_json is a native-only dependency.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn the_answer_serialises_with_units_in_its_names() {
        let field = expected_field(30.3, 120.1, 0.0, date(2019, 11, 15)).expect("near enough");
        let json = serde_json::to_value(&field).expect("serialisable");
        for key in [
            "declination_deg",
            "inclination_deg",
            "total_ut",
            "horizontal_ut",
            "vertical_ut",
            "model_date",
        ] {
            assert!(json.get(key).is_some(), "{key} in {json}");
        }
        assert_eq!(json["warnings"][0]["kind"], "extrapolated");
    }
}
