//! WGS-84 latitude/longitude to a local east-north-up tangent plane, and back.
//!
//! Source: the WGS-84 ellipsoid (NIMA TR8350.2, a = 6 378 137 m, f = 1/298.257223563);
//! geodetic → ECEF in closed form, ECEF → geodetic by Bowring's iteration (converged to
//! below a micrometre within three steps at any height a walker or a car reaches).
//! The tangent plane is anchored at an origin (usually the first fix); `east_m`,
//! `north_m`, `up_m` are metres along the origin's local axes. Over the few kilometres
//! of a walk the plane is exact (this is a rotation of ECEF, not a flat-earth
//! approximation); `up_m` then also carries the Earth's curvature (about 8 cm at 1 km).

use nalgebra::{Matrix3, Vector2, Vector3};

const SEMI_MAJOR_M: f64 = 6_378_137.0;
const FLATTENING: f64 = 1.0 / 298.257_223_563;
const E2: f64 = FLATTENING * (2.0 - FLATTENING);

/// A position on the WGS-84 ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geodetic {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

/// The local east-north-up frame at an origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: Geodetic,
    origin_ecef_m: Vector3<f64>,
    /// Rows: east, north, up, in ECEF.
    enu_from_ecef: Matrix3<f64>,
}

fn ecef_of(position: Geodetic) -> Vector3<f64> {
    let (sin_lat, cos_lat) = position.lat_deg.to_radians().sin_cos();
    let (sin_lon, cos_lon) = position.lon_deg.to_radians().sin_cos();
    let prime_vertical_m = SEMI_MAJOR_M / (1.0 - E2 * sin_lat * sin_lat).sqrt();
    Vector3::new(
        (prime_vertical_m + position.alt_m) * cos_lat * cos_lon,
        (prime_vertical_m + position.alt_m) * cos_lat * sin_lon,
        (prime_vertical_m * (1.0 - E2) + position.alt_m) * sin_lat,
    )
}

fn geodetic_of(ecef_m: Vector3<f64>) -> Geodetic {
    let p_m = ecef_m.x.hypot(ecef_m.y);
    let lon_rad = ecef_m.y.atan2(ecef_m.x);
    // Bowring: start from the spherical latitude and iterate the parametric one.
    let mut lat_rad = ecef_m.z.atan2(p_m * (1.0 - E2));
    for _ in 0..4 {
        let sin_lat = lat_rad.sin();
        let prime_vertical_m = SEMI_MAJOR_M / (1.0 - E2 * sin_lat * sin_lat).sqrt();
        lat_rad = (ecef_m.z + E2 * prime_vertical_m * sin_lat).atan2(p_m);
    }
    let (sin_lat, cos_lat) = lat_rad.sin_cos();
    let prime_vertical_m = SEMI_MAJOR_M / (1.0 - E2 * sin_lat * sin_lat).sqrt();
    let alt_m = if cos_lat.abs() > 1e-9 {
        p_m / cos_lat - prime_vertical_m
    } else {
        ecef_m.z.abs() - prime_vertical_m * (1.0 - E2)
    };
    Geodetic {
        lat_deg: lat_rad.to_degrees(),
        lon_deg: lon_rad.to_degrees(),
        alt_m,
    }
}

impl LocalFrame {
    /// The tangent plane at `origin`.
    pub fn at(origin: Geodetic) -> LocalFrame {
        let (sin_lat, cos_lat) = origin.lat_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = origin.lon_deg.to_radians().sin_cos();
        let enu_from_ecef = Matrix3::new(
            -sin_lon,
            cos_lon,
            0.0,
            -sin_lat * cos_lon,
            -sin_lat * sin_lon,
            cos_lat,
            cos_lat * cos_lon,
            cos_lat * sin_lon,
            sin_lat,
        );
        LocalFrame {
            origin,
            origin_ecef_m: ecef_of(origin),
            enu_from_ecef,
        }
    }

    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// East, north, up (m) of a position.
    pub fn enu_of(&self, position: Geodetic) -> Vector3<f64> {
        self.enu_from_ecef * (ecef_of(position) - self.origin_ecef_m)
    }

    /// East and north (m) of a latitude and longitude at the origin's height.
    pub fn en_of(&self, lat_deg: f64, lon_deg: f64) -> Vector2<f64> {
        let enu = self.enu_of(Geodetic {
            lat_deg,
            lon_deg,
            alt_m: self.origin.alt_m,
        });
        Vector2::new(enu.x, enu.y)
    }

    /// The position at east, north, up (m).
    pub fn geodetic_of(&self, enu_m: Vector3<f64>) -> Geodetic {
        geodetic_of(self.origin_ecef_m + self.enu_from_ecef.transpose() * enu_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_round_trip_is_exact_to_a_millimetre() {
        let frame = LocalFrame::at(Geodetic {
            lat_deg: 48.137,
            lon_deg: 11.575,
            alt_m: 520.0,
        });
        for enu in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1234.5, -987.6, 12.0),
            Vector3::new(-5000.0, 5000.0, -30.0),
        ] {
            let back = frame.enu_of(frame.geodetic_of(enu));
            assert!((back - enu).norm() < 1e-3, "{enu} → {back}");
        }
    }

    #[test]
    fn a_degree_of_latitude_is_about_111_km_north() {
        let frame = LocalFrame::at(Geodetic {
            lat_deg: 45.0,
            lon_deg: 0.0,
            alt_m: 0.0,
        });
        let en = frame.en_of(45.01, 0.0);
        // 0.01° of latitude at 45° is 1111.3 m along the meridian (WGS-84: M = 6 367 382 m).
        assert!(en.x.abs() < 1e-6 && (en.y - 1111.33).abs() < 0.05, "{en}");
        let en = frame.en_of(45.0, 0.01);
        // 0.01° of longitude at 45° is 788.47 m along the parallel (N·cos 45°, N = 6 388 838 m).
        assert!((en.x - 788.47).abs() < 0.05, "{en}");
    }

    #[test]
    fn the_poles_and_nonsense_do_not_panic() {
        let frame = LocalFrame::at(Geodetic {
            lat_deg: 90.0,
            lon_deg: 0.0,
            alt_m: 0.0,
        });
        let _ = frame.geodetic_of(Vector3::new(10.0, 10.0, 0.0));
        let _ = frame.en_of(f64::NAN, 0.0);
    }
}
