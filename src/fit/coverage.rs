//! How much of the sphere of field directions a recording covers, as MotionCal
//! counts it, and where the largest hole is.
//!
//! Source: MotionCal (Paul Stoffregen, PJRC), `quality.c`: `sphere_region` and
//! `quality_surface_gap_error`. The sphere is cut into 100 regions of equal area by
//! latitude zones (a zonal equal-area partition, after Leopardi 2006, *A partition of
//! the unit sphere into regions of equal area and small diameter*, ETNA 25, 309-327):
//!
//! ```text
//! latitude above  78.52°   1 region  (polar cap,   sin = 0.98 … 1)
//!          42.84 … 78.52°  15 regions (temperate,   sin = 0.68 … 0.98)
//!           0    … 42.84°  34 regions (tropical,    sin = 0 … 0.68)
//! and the same below the equator: 1 + 15 + 34 + 34 + 15 + 1 = 100.
//! ```
//!
//! Each zone's area is `2π·Δ(sin latitude)`, so the boundaries are where the sine of
//! the latitude is ±0.68 and ±0.98, which makes every region exactly `4π/100` (MotionCal
//! writes the rounded angles); regions within a zone split its longitude evenly.
//! MotionCal's "gaps" figure adds 1 for every empty region, 0.2 for one with a single
//! sample and 0.01 for one with two, so that it reads as a percentage of the sphere
//! still to cover; MotionCal asks for under 15 %.
//!
//! Latitude and longitude follow MotionCal's `quality_update`: latitude is positive
//! towards body −z (up when the device is level), longitude is `atan2(y, x)`. Here they
//! are called elevation and azimuth and given in degrees at the edge.
//!
//! ## Limits
//!
//! The directions should be those of the *corrected* field (a raw ellipsoid off the
//! origin puts every sample on one side). Coverage says nothing about the order of the
//! samples or how long the device stayed in each attitude.

use std::f64::consts::{PI, TAU};

use nalgebra::Vector3;
use serde::Serialize;

/// The number of regions (MotionCal's `SPHERE_REGIONS`).
pub const N_REGIONS: usize = 100;

/// The latitude zones from north (body −z) to south: the sine of the latitude at
/// each zone's southern edge and the number of regions in it.
const ZONES: [(f64, usize); 6] = [
    (0.98, 1),
    (0.68, 15),
    (0.0, 34),
    (-0.68, 34),
    (-0.98, 15),
    (-1.0, 1),
];

/// Coverage of the sphere of directions.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SphereCoverage {
    pub n_regions: usize,
    /// Regions with at least one sample.
    pub n_covered: usize,
    /// Directions counted (zero and non-finite vectors are skipped).
    pub n_samples: usize,
    /// MotionCal's "gaps": 1 per empty region, 0.2 per region with one sample, 0.01
    /// per region with two, out of 100.
    pub gap_pct: f64,
    /// The largest group of adjacent empty regions; `None` when nothing or everything
    /// is covered.
    pub largest_gap: Option<SphereGap>,
    /// Directions counted in each region, in MotionCal's numbering (for a map).
    pub counts_per_region: Vec<usize>,
}

/// MotionCal's bar: a calibration is good only with "gaps" under this (percent of the
/// sphere). The one rule for the live panel's Send and for a log's coverage advice.
pub const MAX_GOOD_GAP_PCT: f64 = 15.0;

impl SphereCoverage {
    /// Whether too much of the sphere is missing for MotionCal to call the calibration
    /// good ([`MAX_GOOD_GAP_PCT`]).
    pub fn gaps_too_large(&self) -> bool {
        self.gap_pct >= MAX_GOOD_GAP_PCT
    }
}

/// Where a region lies on the sphere: a longitude range and a band of latitude, given
/// as the sine of the elevation (so that, drawn on those axes, every region has the
/// same area: Lambert's cylindrical equal-area projection).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionBounds {
    /// `atan2(y, x)` in degrees, from −180 (inclusive) to 180.
    pub azimuth_start_deg: f64,
    pub azimuth_end_deg: f64,
    /// Sine of the elevation (positive towards body −z) at the region's lower and upper
    /// edges.
    pub sin_elevation_low: f64,
    pub sin_elevation_high: f64,
}

/// The bounds of region `region_idx` (0-99), for drawing the coverage map.
pub fn region_bounds(region_idx: usize) -> RegionBounds {
    let (zone_idx, sector_idx, n_in_zone) = zone_of(region_idx);
    let floor_sin = ZONES.get(zone_idx).map_or(-1.0, |zone| zone.0);
    let ceiling_sin = match zone_idx.checked_sub(1).and_then(|idx| ZONES.get(idx)) {
        Some(zone_above) => zone_above.0,
        None => 1.0,
    };
    let width_deg = 360.0 / n_in_zone as f64;
    RegionBounds {
        azimuth_start_deg: sector_idx as f64 * width_deg - 180.0,
        azimuth_end_deg: (sector_idx + 1) as f64 * width_deg - 180.0,
        sin_elevation_low: floor_sin,
        sin_elevation_high: ceiling_sin,
    }
}

/// A group of adjacent empty regions and the direction of its centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SphereGap {
    pub n_regions: usize,
    /// Unit direction of the group's centre in the body frame (the mean of its
    /// regions' centres).
    pub centre_direction: Vector3<f64>,
    /// From the body x axis towards the body y axis, in `[0, 360)` (meaningless at
    /// ±90° of elevation).
    pub centre_azimuth_deg: f64,
    /// Above the body x-y plane, positive towards body −z.
    pub centre_elevation_deg: f64,
    /// The signed body axis nearest the centre, `"+x"` … `"-z"`, for messages.
    pub nearest_axis: &'static str,
}

impl SphereGap {
    /// A sentence for the user: which way the device never pointed, and what to do.
    /// The field points down in the northern hemisphere (up in the southern), so a
    /// direction of the field in the body frame is an axis of the device pointing
    /// down.
    pub fn advice(&self) -> String {
        let axis = self.nearest_axis;
        format!(
            "no data with the {axis} axis pointing along the field (down, north of the \
             magnetic equator): turn the device so that its {axis} axis points down, and \
             sweep around that attitude ({} of {N_REGIONS} regions are empty there)",
            self.n_regions
        )
    }
}

/// The region (0-99, MotionCal's numbering: north cap first) of a direction, or `None`
/// for a zero or non-finite vector.
pub fn sphere_region(direction: &Vector3<f64>) -> Option<usize> {
    let norm = direction.norm();
    if norm.is_nan() || norm <= 0.0 || norm.is_infinite() {
        return None;
    }
    let sin_elevation = -direction.z / norm;
    let longitude_rad = direction.y.atan2(direction.x) + PI;
    let mut first_region_idx = 0;
    for (zone_floor_sin, n_in_zone) in ZONES {
        if sin_elevation >= zone_floor_sin {
            let sector = (longitude_rad / TAU * n_in_zone as f64).floor() as usize;
            return Some(first_region_idx + sector.min(n_in_zone - 1));
        }
        first_region_idx += n_in_zone;
    }
    // Only rounding can bring the sine below −1: that is the south cap.
    Some(N_REGIONS - 1)
}

/// Which zone a region is in, its index there, and the zone's size.
fn zone_of(region_idx: usize) -> (usize, usize, usize) {
    let mut first_region_idx = 0;
    for (zone_idx, &(_, n_in_zone)) in ZONES.iter().enumerate() {
        if region_idx < first_region_idx + n_in_zone {
            return (zone_idx, region_idx - first_region_idx, n_in_zone);
        }
        first_region_idx += n_in_zone;
    }
    (ZONES.len() - 1, 0, 1)
}

/// The centre of a region: the middle of its longitude range, and the latitude that
/// halves its zone's area (the caps' centres are the poles).
fn region_centre(region_idx: usize) -> Vector3<f64> {
    let (zone_idx, sector_idx, n_in_zone) = zone_of(region_idx);
    let floor_sin = ZONES[zone_idx].0;
    let ceiling_sin = if zone_idx == 0 {
        1.0
    } else {
        ZONES[zone_idx - 1].0
    };
    // The caps (one region each) are centred on their poles.
    let sin_elevation = if n_in_zone == 1 {
        floor_sin.signum()
    } else {
        (floor_sin + ceiling_sin) / 2.0
    };
    let azimuth_rad = (sector_idx as f64 + 0.5) / n_in_zone as f64 * TAU - PI;
    direction_at(azimuth_rad, sin_elevation)
}

/// The unit direction (body axes) at `azimuth_rad` from +x toward +y and the sine of
/// the elevation (toward −z): the coordinates the regions are bounded in.
pub fn direction_at(azimuth_rad: f64, sin_elevation: f64) -> Vector3<f64> {
    let cos_elevation = (1.0 - sin_elevation * sin_elevation).max(0.0).sqrt();
    Vector3::new(
        cos_elevation * azimuth_rad.cos(),
        cos_elevation * azimuth_rad.sin(),
        -sin_elevation,
    )
}

/// Whether two regions share an edge: neighbours in a zone (round the circle), or in
/// adjacent zones with overlapping longitude ranges.
fn adjacent(a: usize, b: usize) -> bool {
    let (zone_a, sector_a, n_a) = zone_of(a);
    let (zone_b, sector_b, n_b) = zone_of(b);
    if zone_a == zone_b {
        return n_a > 1 && ((sector_a + 1) % n_a == sector_b || (sector_b + 1) % n_b == sector_a);
    }
    if zone_a.abs_diff(zone_b) != 1 {
        return false;
    }
    // Longitude ranges [k/n, (k+1)/n) overlap when each starts before the other ends.
    let (start_a, end_a) = (
        sector_a as f64 / n_a as f64,
        (sector_a + 1) as f64 / n_a as f64,
    );
    let (start_b, end_b) = (
        sector_b as f64 / n_b as f64,
        (sector_b + 1) as f64 / n_b as f64,
    );
    start_a < end_b && start_b < end_a
}

/// Counts the directions per region and finds the largest group of empty ones.
pub fn sphere_coverage(directions: impl Iterator<Item = Vector3<f64>>) -> SphereCoverage {
    let mut counts = [0usize; N_REGIONS];
    let mut n_samples = 0;
    for direction in directions {
        if let Some(count) = sphere_region(&direction).and_then(|idx| counts.get_mut(idx)) {
            *count += 1;
            n_samples += 1;
        }
    }
    let gap_pct = counts
        .iter()
        .map(|&count| match count {
            0 => 1.0,
            1 => 0.2,
            2 => 0.01,
            _ => 0.0,
        })
        .sum();
    let n_covered = counts.iter().filter(|&&count| count > 0).count();
    let largest_gap = if n_covered == 0 || n_covered == N_REGIONS {
        None
    } else {
        largest_empty_group(&counts)
    };
    SphereCoverage {
        n_regions: N_REGIONS,
        n_covered,
        n_samples,
        gap_pct,
        largest_gap,
        counts_per_region: counts.to_vec(),
    }
}

/// The largest connected group of empty regions, by a flood fill over [`adjacent`].
fn largest_empty_group(counts: &[usize; N_REGIONS]) -> Option<SphereGap> {
    let mut group_of = [usize::MAX; N_REGIONS];
    let mut best: Option<Vec<usize>> = None;
    for start_idx in 0..N_REGIONS {
        if counts[start_idx] > 0 || group_of[start_idx] != usize::MAX {
            continue;
        }
        group_of[start_idx] = start_idx;
        let (mut members, mut frontier) = (vec![start_idx], vec![start_idx]);
        while let Some(region_idx) = frontier.pop() {
            for other_idx in 0..N_REGIONS {
                if counts[other_idx] == 0
                    && group_of[other_idx] == usize::MAX
                    && adjacent(region_idx, other_idx)
                {
                    group_of[other_idx] = start_idx;
                    members.push(other_idx);
                    frontier.push(other_idx);
                }
            }
        }
        if best.as_ref().is_none_or(|best| members.len() > best.len()) {
            best = Some(members);
        }
    }
    let members = best?;
    let sum: Vector3<f64> = members.iter().map(|&idx| region_centre(idx)).sum();
    // A group that rings the sphere symmetrically has no mean direction; its first
    // region stands for it.
    let centre_direction = sum
        .try_normalize(1e-9)
        .or_else(|| members.first().map(|&idx| region_centre(idx)))?;
    Some(SphereGap {
        n_regions: members.len(),
        centre_direction,
        centre_azimuth_deg: centre_direction
            .y
            .atan2(centre_direction.x)
            .to_degrees()
            .rem_euclid(360.0),
        centre_elevation_deg: (-centre_direction.z).clamp(-1.0, 1.0).asin().to_degrees(),
        nearest_axis: nearest_signed_axis(&centre_direction),
    })
}

fn nearest_signed_axis(direction: &Vector3<f64>) -> &'static str {
    let abs = direction.abs();
    let (positive, negative, value) = if abs.x >= abs.y && abs.x >= abs.z {
        ("+x", "-x", direction.x)
    } else if abs.y >= abs.z {
        ("+y", "-y", direction.y)
    } else {
        ("+z", "-z", direction.z)
    };
    if value >= 0.0 {
        positive
    } else {
        negative
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn region_bounds_hold_their_regions_centres_and_have_equal_areas() {
        for region_idx in 0..N_REGIONS {
            let bounds = region_bounds(region_idx);
            let area = (bounds.azimuth_end_deg - bounds.azimuth_start_deg).to_radians()
                * (bounds.sin_elevation_high - bounds.sin_elevation_low);
            assert!(
                (area - 4.0 * PI / N_REGIONS as f64).abs() < 1e-12,
                "{region_idx}"
            );
            let centre = region_centre(region_idx);
            let azimuth_deg = centre.y.atan2(centre.x).to_degrees();
            let sin_elevation = -centre.z;
            assert!(
                (bounds.sin_elevation_low..=bounds.sin_elevation_high).contains(&sin_elevation),
                "{region_idx}"
            );
            if bounds.azimuth_end_deg - bounds.azimuth_start_deg < 360.0 {
                assert!(
                    (bounds.azimuth_start_deg..bounds.azimuth_end_deg).contains(&azimuth_deg),
                    "{region_idx}: {azimuth_deg} {bounds:?}"
                );
            }
            assert_eq!(sphere_region(&centre), Some(region_idx));
        }
    }
    use crate::base::rng::SplitMix64;

    fn random_directions(n: usize, seed: u64) -> Vec<Vector3<f64>> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                // Uniform on the sphere: uniform height, uniform longitude (Archimedes).
                let (height, angle_rad) = (rng.uniform_in(-1.0, 1.0), rng.uniform_in(0.0, TAU));
                let radius = (1.0 - height * height).sqrt();
                Vector3::new(radius * angle_rad.cos(), radius * angle_rad.sin(), height) * 48.0
            })
            .collect()
    }

    #[test]
    fn the_regions_have_equal_areas() {
        let n_samples = 200_000;
        let mut counts = [0usize; N_REGIONS];
        for direction in random_directions(n_samples, 1) {
            counts[sphere_region(&direction).expect("a direction")] += 1;
        }
        let expect = (n_samples / N_REGIONS) as f64;
        for (region_idx, &count) in counts.iter().enumerate() {
            // 2000 expected per region, binomial σ ≈ 44: 5 σ.
            assert!(
                (count as f64 - expect).abs() < 225.0,
                "region {region_idx}: {count}"
            );
        }
    }

    #[test]
    fn regions_follow_motioncal_numbering() {
        let check = |direction: Vector3<f64>, expect: usize| {
            assert_eq!(sphere_region(&direction), Some(expect), "{direction:?}");
        };
        check(Vector3::new(0.0, 0.0, -1.0), 0); // up: the north cap
        check(Vector3::new(0.0, 0.0, 1.0), 99); // down: the south cap
                                                // Longitude atan2(y, x) + π starts at −x.
        check(Vector3::new(-1.0, -1e-9, -1.5), 1);
        check(Vector3::new(-1.0, -1e-9, -0.1), 16);
        check(Vector3::new(-1.0, -1e-9, 0.1), 50);
        check(Vector3::new(-1.0, -1e-9, 1.5), 84);
        check(Vector3::new(1.0, 0.0, 0.1), 50 + 17);
        assert_eq!(sphere_region(&Vector3::zeros()), None);
        assert_eq!(sphere_region(&Vector3::new(f64::NAN, 0.0, 1.0)), None);
        for region_idx in 0..N_REGIONS {
            assert_eq!(sphere_region(&region_centre(region_idx)), Some(region_idx));
        }
    }

    #[test]
    fn adjacency_is_symmetric_and_connects_the_sphere() {
        let mut reached = [false; N_REGIONS];
        let mut frontier = vec![0];
        reached[0] = true;
        while let Some(region_idx) = frontier.pop() {
            for (other_idx, is_reached) in reached.iter_mut().enumerate() {
                assert_eq!(
                    adjacent(region_idx, other_idx),
                    adjacent(other_idx, region_idx)
                );
                if adjacent(region_idx, other_idx) && !*is_reached {
                    *is_reached = true;
                    frontier.push(other_idx);
                }
            }
        }
        assert!(reached.iter().all(|&is_reached| is_reached));
        // Each cap touches its whole temperate zone and nothing else.
        assert_eq!((0..N_REGIONS).filter(|&idx| adjacent(0, idx)).count(), 15);
    }

    #[test]
    fn a_full_sphere_has_no_gap() {
        let coverage = sphere_coverage(random_directions(5000, 2).into_iter());
        assert_eq!(coverage.n_covered, N_REGIONS);
        assert_eq!(coverage.gap_pct, 0.0);
        assert_eq!(coverage.largest_gap, None);
        assert_eq!(coverage.n_samples, 5000);
    }

    #[test]
    fn sparse_regions_count_as_motioncal_counts_them() {
        // One sample per region: 0.2 each.
        let one_each = (0..N_REGIONS).map(region_centre);
        let coverage = sphere_coverage(one_each);
        assert!(
            (coverage.gap_pct - 20.0).abs() < 1e-9,
            "{}",
            coverage.gap_pct
        );
        let empty = sphere_coverage(std::iter::empty());
        assert_eq!((empty.n_covered, empty.gap_pct), (0, 100.0));
        assert_eq!(empty.largest_gap, None);
        let skipped =
            sphere_coverage([Vector3::zeros(), Vector3::new(f64::INFINITY, 0.0, 0.0)].into_iter());
        assert_eq!(skipped.n_samples, 0);
    }

    #[test]
    fn the_largest_gap_points_where_data_are_missing() {
        // Never with the field along +x: every direction with x > −0.2 is missing.
        let no_plus_x = random_directions(5000, 3)
            .into_iter()
            .filter(|direction| direction.x / direction.norm() < -0.2);
        let coverage = sphere_coverage(no_plus_x);
        let gap = coverage.largest_gap.expect("a gap");
        assert_eq!(gap.nearest_axis, "+x");
        assert!(gap.centre_direction.x > 0.9, "{gap:?}");
        assert!(
            gap.centre_azimuth_deg < 20.0 || gap.centre_azimuth_deg > 340.0,
            "{gap:?}"
        );
        assert!(gap.centre_elevation_deg.abs() < 20.0, "{gap:?}");
        assert!(coverage.gap_pct > 50.0, "{}", coverage.gap_pct);
        assert!(gap.advice().contains("+x axis"), "{}", gap.advice());

        // Circle-only data: every heading, field dipping 65° (body +z is down), so the
        // directions stay in a band below the horizon and the gap is the upper side.
        let band = (0..720).map(|idx| {
            let heading_rad = (idx as f64 / 2.0).to_radians();
            let (inclination_rad, tilt_rad) =
                (65f64.to_radians(), ((idx % 7) as f64 - 3.0).to_radians());
            let elevation_rad = inclination_rad + tilt_rad;
            Vector3::new(
                elevation_rad.cos() * heading_rad.cos(),
                -elevation_rad.cos() * heading_rad.sin(),
                elevation_rad.sin(),
            )
        });
        let coverage = sphere_coverage(band);
        let gap = coverage.largest_gap.expect("a gap");
        assert_eq!(gap.nearest_axis, "-z");
        assert!(gap.centre_elevation_deg > 60.0, "{gap:?}");
        assert!(coverage.n_covered < 25, "{}", coverage.n_covered);
    }
}
