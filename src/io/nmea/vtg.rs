//! VTG, course and speed over ground ([`super`]), in the NMEA 2.3 form with unit letters
//! and the NMEA 1.x form without them.
//!
//! ```text
//! $--VTG,x.x,T,x.x,M,x.x,N,x.x,K,m*hh     (NMEA 1.x: $--VTG,x.x,x.x,x.x,x.x*hh)
//!        1   2 3   4 5   6 7   8 9
//!  1 course over ground, degrees true   3 course over ground, degrees magnetic
//!  5 speed over ground, knots           7 speed over ground, km/h   9 mode, as in RMC
//! ```
//!
//! Sources: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>); Garmin, "GPS 19x HVS Technical
//! Specifications", §4.2.

use super::values::{first_char, heading_rad, number};
use super::{SentenceError, MPS_PER_KNOT};

/// VTG, course and speed over ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vtg {
    /// Clockwise from true north.
    pub course_true_rad: Option<f64>,
    /// Clockwise from magnetic north.
    pub course_magnetic_rad: Option<f64>,
    /// From the knots field, or from the km/h field where knots are null.
    pub speed_mps: Option<f64>,
    pub mode: Option<char>,
}

#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_vtg(fields: [&[u8]; 9]) -> Result<Vtg, SentenceError> {
    const S: &str = "VTG";
    let [course_true, t_letter, course_magnetic, m_letter, knots, n_letter, kmph, k_letter, mode] =
        fields;
    // NMEA 1.x receivers send the four values without their unit letters, so the
    // second field is a number and nothing follows the fourth.
    let is_legacy = !matches!(t_letter, b"T" | b"")
        && [knots, n_letter, kmph, k_letter, mode]
            .iter()
            .all(|field| field.is_empty());
    let no_mode: &[u8] = b"";
    let (course_true, course_magnetic, knots, kmph, mode) = if is_legacy {
        (course_true, t_letter, course_magnetic, m_letter, no_mode)
    } else {
        (course_true, course_magnetic, knots, kmph, mode)
    };
    let speed_mps = match number(S, "speed over ground (knots)", knots)? {
        Some(knots) => Some(knots * MPS_PER_KNOT),
        None => number(S, "speed over ground (km/h)", kmph)?.map(|kmph| kmph / 3.6),
    };
    Ok(Vtg {
        course_true_rad: heading_rad(S, "true course", course_true)?,
        course_magnetic_rad: heading_rad(S, "magnetic course", course_magnetic)?,
        speed_mps,
        mode: first_char(mode),
    })
}
