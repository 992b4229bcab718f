//! Heading from levelled field components.
//!
//! Source: Moafipoor et al. (2007), Eq. 1, `α = tan⁻¹(Hy / Hx)` with the quadrant from
//! the signs, i.e. `atan2`.
//!
//! In this crate's body frame (x forward, y right, z down) a device facing heading ψ
//! clockwise from magnetic north sees the horizontal field `(H·cosψ, −H·sinψ)`, so
//! `ψ = atan2(−Yh, Xh)`. The paper's sensor has its y axis the other way, hence its
//! sign. Declination (true minus magnetic north) is added to get a true heading.

use nalgebra::Vector2;

use crate::base::angle::wrap_to_2pi;

/// Heading clockwise from north, in `[0, 2π)`, of levelled components (Xh, Yh), plus
/// the declination (true north from magnetic north, east positive).
pub fn heading_rad(level_ut: Vector2<f64>, declination_rad: f64) -> f64 {
    wrap_to_2pi((-level_ut.y).atan2(level_ut.x) + declination_rad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(level_ut: (f64, f64), expect_deg: f64) {
        let got_deg = heading_rad(Vector2::new(level_ut.0, level_ut.1), 0.0).to_degrees();
        assert!(
            (got_deg - expect_deg).abs() < 1e-9,
            "{level_ut:?} → {got_deg}"
        );
    }

    #[test]
    fn cardinal_directions() {
        check((20.0, 0.0), 0.0); // facing north: all of the field ahead
        check((0.0, -20.0), 90.0); // facing east: north is to the left
        check((-20.0, 0.0), 180.0);
        check((0.0, 20.0), 270.0);
    }

    #[test]
    fn declination_is_added() {
        let got_deg = heading_rad(Vector2::new(20.0, 0.0), (-11.5f64).to_radians()).to_degrees();
        assert!((got_deg - 348.5).abs() < 1e-9);
    }
}
