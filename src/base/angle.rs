//! Angle helpers: wrapping and the degree/radian boundary.
//!
//! Angles are radians inside the core. Degrees appear only at the edges (CSV columns,
//! JSON, the page), and these helpers are where the conversion happens.

use std::f64::consts::{PI, TAU};

/// Wraps an angle to `[0, 2π)`, as headings are reported.
pub fn wrap_to_2pi(angle_rad: f64) -> f64 {
    // Within one turn of the range, `rem_euclid` is the identity or one addition (its
    // remainder is exact there): the same value without its `fmod`, which costs more
    // than the rest of a heading's arithmetic (a software routine, in wasm too).
    let wrapped = if (0.0..TAU).contains(&angle_rad) {
        angle_rad
    } else if angle_rad > -TAU && angle_rad < 0.0 {
        angle_rad + TAU
    } else {
        rem_euclid_tau(angle_rad)
    };
    // rem_euclid can return exactly TAU for tiny negative inputs through rounding.
    if wrapped >= TAU {
        0.0
    } else {
        wrapped
    }
}

/// `rem_euclid(TAU)` out of line: were it inlined, the compiler could compute the
/// remainder before the range tests (a remainder has no side effects) and the fast
/// paths above would save nothing.
#[cold]
#[inline(never)]
fn rem_euclid_tau(angle_rad: f64) -> f64 {
    angle_rad.rem_euclid(TAU)
}

/// Wraps an angle to `(−π, π]`, as heading differences are reported.
pub fn wrap_to_pi(angle_rad: f64) -> f64 {
    let wrapped = wrap_to_2pi(angle_rad);
    if wrapped > PI {
        wrapped - TAU
    } else {
        wrapped
    }
}

/// The signed difference `a − b` of two headings, in `(−π, π]`.
pub fn heading_difference_rad(a_rad: f64, b_rad: f64) -> f64 {
    wrap_to_pi(a_rad - b_rad)
}

/// The arc from `from_deg` clockwise to `to_deg`, in degrees, in `(0, 360]`: a gap
/// in headings that starts and ends at the same heading is the whole circle.
pub fn clockwise_arc_deg(from_deg: f64, to_deg: f64) -> f64 {
    let arc_deg = (to_deg - from_deg).rem_euclid(360.0);
    if arc_deg == 0.0 {
        360.0
    } else {
        arc_deg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clockwise_arcs_wrap_through_north() {
        assert_eq!(clockwise_arc_deg(20.0, 0.0), 340.0);
        assert_eq!(clockwise_arc_deg(350.0, 10.0), 20.0);
        assert_eq!(clockwise_arc_deg(90.0, 90.0), 360.0);
    }

    #[test]
    fn the_fast_paths_give_rem_euclid_bit_for_bit() {
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let edges = [
            0.0,
            -0.0,
            TAU,
            -TAU,
            PI,
            -PI,
            1e-300,
            -1e-300,
            TAU - 1e-15,
            -TAU + 1e-15,
        ];
        let random = (0..100_000).map(|_| (next() as f64 / u64::MAX as f64 - 0.5) * 8.0 * TAU);
        for angle in edges.into_iter().chain(random) {
            let slow = angle.rem_euclid(TAU);
            let slow = if slow >= TAU { 0.0 } else { slow };
            assert_eq!(wrap_to_2pi(angle).to_bits(), slow.to_bits(), "{angle}");
        }
    }

    fn check(input_deg: f64, expect_deg: f64) {
        let got_deg = wrap_to_pi(input_deg.to_radians()).to_degrees();
        assert!(
            (got_deg - expect_deg).abs() < 1e-9,
            "{input_deg} → {got_deg}, expected {expect_deg}"
        );
    }

    #[test]
    fn wrap_to_pi_keeps_the_half_open_interval() {
        check(0.0, 0.0);
        check(180.0, 180.0);
        check(-180.0, 180.0);
        check(190.0, -170.0);
        check(-190.0, 170.0);
        check(720.0 + 10.0, 10.0);
    }

    #[test]
    fn heading_difference_crosses_north() {
        let diff_deg = heading_difference_rad(2f64.to_radians(), 358f64.to_radians()).to_degrees();
        assert!((diff_deg - 4.0).abs() < 1e-9);
    }

    #[test]
    fn wrap_to_2pi_never_returns_tau() {
        assert!(wrap_to_2pi(-1e-18) < TAU);
        assert!((wrap_to_2pi(-PI / 2.0) - 1.5 * PI).abs() < 1e-12);
    }
}
