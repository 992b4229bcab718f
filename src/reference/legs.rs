//! The map-direction constraint: the bearing of each straight leg between reference
//! positions is the true walking direction during that leg.
//!
//! Source: the heading-model issue's "map-direction constraint", as indoor PDR uses
//! corridor directions (and the IPIN competitions' `POSI` landmarks, Microsoft's
//! `TYPE_WAYPOINT` lines). Between two reference positions passed at t₀ and t₁, a
//! walker on a straight leg faces `atan2(ΔE, ΔN)` (clockwise from the map's north). Near
//! each end the walker is still turning, so a fraction of the leg's time at each end is
//! left out; legs shorter than `min_leg_m` say little about direction and are merged
//! into the next one (the next waypoint far enough away closes the leg).

use nalgebra::Vector2;
use serde::Serialize;

use crate::io::recording::Stream;

/// The choices.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LegOptions {
    /// Shortest leg (m).
    pub min_leg_m: f64,
    /// Fraction of each leg's duration left out at each end (turning).
    pub trim_fraction: f64,
    /// Spacing (s) of the reference samples written along a leg.
    pub sample_spacing_s: f64,
}

impl Default for LegOptions {
    fn default() -> Self {
        LegOptions {
            min_leg_m: 2.0,
            trim_fraction: 0.15,
            sample_spacing_s: 0.1,
        }
    }
}

/// One leg.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Leg {
    pub start_s: f64,
    pub end_s: f64,
    pub length_m: f64,
    /// Clockwise from the map's north.
    pub bearing_deg: f64,
}

/// The legs between reference positions (east, north in metres), and a reference
/// heading sampled along each leg's trimmed span.
pub fn leg_reference(
    positions_en_m: &Stream<Vector2<f64>>,
    options: &LegOptions,
) -> (Stream<f64>, Vec<Leg>) {
    let mut legs = Vec::new();
    let points: Vec<(f64, Vector2<f64>)> = positions_en_m
        .t_s
        .iter()
        .zip(&positions_en_m.values)
        .filter(|(t_s, en)| t_s.is_finite() && en.x.is_finite() && en.y.is_finite())
        .map(|(&t_s, &en)| (t_s, en))
        .collect();
    let mut start: Option<(f64, Vector2<f64>)> = points.first().copied();
    for &(t_s, en) in points.iter().skip(1) {
        let Some((start_s, start_en)) = start else {
            break;
        };
        let delta = en - start_en;
        let length_m = delta.norm();
        if t_s <= start_s {
            continue;
        }
        if length_m >= options.min_leg_m {
            legs.push(Leg {
                start_s,
                end_s: t_s,
                length_m,
                bearing_deg: crate::base::angle::wrap_to_2pi(delta.x.atan2(delta.y)).to_degrees(),
            });
            start = Some((t_s, en));
        }
    }
    let mut reference = Stream::default();
    for leg in &legs {
        let trim_s = (leg.end_s - leg.start_s) * options.trim_fraction;
        let (from_s, to_s) = (leg.start_s + trim_s, leg.end_s - trim_s);
        let n = ((to_s - from_s) / options.sample_spacing_s)
            .floor()
            .max(0.0) as usize;
        for idx in 0..=n {
            reference.push(
                from_s + idx as f64 * options.sample_spacing_s,
                leg.bearing_deg.to_radians(),
            );
        }
    }
    (reference, legs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_gives_four_legs_and_nothing_at_the_corners() {
        let mut positions = Stream::default();
        for (t_s, e, n) in [
            (0.0, 0.0, 0.0),
            (10.0, 0.0, 10.0),
            (10.5, 0.5, 10.0), // too short: merged into the next leg
            (20.0, 10.0, 10.0),
            (30.0, 10.0, 0.0),
            (40.0, 0.0, 0.0),
        ] {
            positions.push(t_s, Vector2::new(e, n));
        }
        let (reference, legs) = leg_reference(&positions, &LegOptions::default());
        let bearings: Vec<f64> = legs.iter().map(|leg| leg.bearing_deg.round()).collect();
        assert_eq!(bearings, vec![0.0, 90.0, 180.0, 270.0]);
        assert_eq!(legs[1].start_s, 10.0);
        // 15 % of each leg is left out at either end: no sample within 1.5 s of a corner.
        for &t_s in &reference.t_s {
            for corner_s in [10.0, 20.0, 30.0] {
                assert!((t_s - corner_s).abs() >= 1.4, "{t_s}");
            }
        }
        // A single position, or none, gives no leg.
        let mut one = Stream::default();
        one.push(0.0, Vector2::new(1.0, 1.0));
        assert!(leg_reference(&one, &LegOptions::default()).1.is_empty());
    }
}
