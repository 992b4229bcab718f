//! HDG, HDM and HDT, a compass's heading ([`super`]): HDG the magnetic sensor's heading
//! with the deviation and variation it knows, HDM the heading from magnetic north, HDT
//! from true north.
//!
//! ```text
//! $--HDG,x.x,x.x,a,x.x,a*hh
//!        1   2   3 4   5
//!  1 magnetic sensor heading, degrees   2-3 deviation, degrees, E/W
//!  4-5 variation, degrees, E/W (sensor + deviation = magnetic; magnetic + variation = true)
//!
//! $--HDM,x.x,M*hh          $--HDT,x.x,T*hh
//!        1   2                    1   2
//!  1 heading, degrees magnetic (HDM) or true (HDT)
//! ```
//!
//! Sources: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>); Kongsberg's description of the HDG
//! datagram (deviation and variation).

use super::values::{east_positive_rad, heading_rad};
use super::SentenceError;
use crate::base::angle::wrap_to_2pi;

/// HDG, a magnetic sensor's heading with the deviation and variation it knows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hdg {
    pub sensor_heading_rad: f64,
    /// East positive.
    pub deviation_rad: Option<f64>,
    /// East positive.
    pub variation_rad: Option<f64>,
}

impl Hdg {
    /// The sensor heading corrected for deviation: the heading from magnetic north.
    pub fn magnetic_heading_rad(&self) -> f64 {
        wrap_to_2pi(self.sensor_heading_rad + self.deviation_rad.unwrap_or(0.0))
    }
}

/// HDM or HDT: one heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingOnly {
    pub heading_rad: f64,
}

pub(super) fn parse_hdg(fields: [&[u8]; 5]) -> Result<Hdg, SentenceError> {
    const S: &str = "HDG";
    let [heading, deviation, deviation_direction, variation, variation_direction] = fields;
    let sensor_heading_rad =
        heading_rad(S, "heading", heading)?.ok_or(SentenceError::MissingField {
            sentence: S,
            field: "heading",
        })?;
    Ok(Hdg {
        sensor_heading_rad,
        deviation_rad: east_positive_rad(S, "deviation", deviation, deviation_direction)?,
        variation_rad: east_positive_rad(S, "variation", variation, variation_direction)?,
    })
}

#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_heading_only(
    fields: [&[u8]; 2],
    sentence: &'static str,
    letter: u8,
) -> Result<HeadingOnly, SentenceError> {
    let [heading, reference] = fields;
    if !(reference.is_empty() || reference == [letter]) {
        return Err(SentenceError::bad_value(
            sentence,
            "reference letter",
            reference,
            if letter == b'M' { "M" } else { "T" },
        ));
    }
    let heading_rad =
        heading_rad(sentence, "heading", heading)?.ok_or(SentenceError::MissingField {
            sentence,
            field: "heading",
        })?;
    Ok(HeadingOnly { heading_rad })
}
