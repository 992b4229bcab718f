//! The World Magnetic Model's answers against an independent model: IGRF-14 (as the
//! `ppigrf` package evaluates it, `tests/data/igrf14_field.py`) at 600 random places and
//! dates. 500 dates lie in 1990-2019, before the bundled WMM2020 epoch, where
//! `earth::wmm` extrapolates along the model's secular variation and states a wider
//! declination uncertainty; 100 lie in 2020-2024, where both models hold, for the
//! baseline. Distributions, not one place.

mod physics;

use compass_pdr::base::angle::wrap_to_pi;
use compass_pdr::earth::wmm::{expected_field, CalendarDate, WmmWarning};
use physics::scoring::quantile;

struct Point {
    date: CalendarDate,
    lat_deg: f64,
    lon_deg: f64,
    declination_deg: f64,
    inclination_deg: f64,
    total_ut: f64,
}

fn igrf_points() -> Vec<Point> {
    include_str!("data/igrf14_field.csv")
        .lines()
        .skip(1)
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            let number = |idx: usize| fields[idx].parse::<f64>().expect("a number");
            Point {
                date: fields[0].parse().expect("a date"),
                lat_deg: number(1),
                lon_deg: number(2),
                declination_deg: number(3),
                inclination_deg: number(4),
                total_ut: number(5),
            }
        })
        .collect()
}

/// One comparison: years outside the covered ones (0 inside), the declination error over
/// the stated 1σ, and the errors in D (°), I (°) and F (µT).
struct Compared {
    years: f64,
    declination_in_sigmas: f64,
    errors: [f64; 3],
}

/// Every point away from the magnetic poles (horizontal field over 6 µT, where the
/// declination means something), compared.
fn compared() -> Vec<Compared> {
    igrf_points()
        .iter()
        .filter_map(|point| {
            let field = expected_field(point.lat_deg, point.lon_deg, 0.0, point.date)
                .unwrap_or_else(|error| panic!("{}: {error}", point.date));
            if field.horizontal_ut < 6.0 {
                return None;
            }
            let years = field
                .warnings
                .iter()
                .find_map(|warning| match warning {
                    WmmWarning::Extrapolated { years, .. } => Some(*years),
                    _ => None,
                })
                .unwrap_or(0.0);
            let declination_error =
                wrap_to_pi((field.declination_deg - point.declination_deg).to_radians())
                    .to_degrees();
            Some(Compared {
                years,
                declination_in_sigmas: declination_error.abs() / field.declination_uncertainty_deg,
                errors: [
                    declination_error,
                    field.inclination_deg - point.inclination_deg,
                    field.total_ut - point.total_ut,
                ],
            })
        })
        .collect()
}

#[test]
fn extrapolated_declinations_are_within_their_stated_uncertainty() {
    let all = compared();
    for (what, range) in [
        ("2020-2024 (covered)", 0.0..0.001),
        ("0-10 years before", 0.001..10.0),
        ("10-20 years before", 10.0..20.0),
        ("20-30 years before", 20.0..30.01),
    ] {
        let mut part: Vec<&Compared> = all
            .iter()
            .filter(|compared| range.contains(&compared.years.abs()))
            .collect();
        part.sort_by(|a, b| a.years.total_cmp(&b.years));
        let d: Vec<f64> = part.iter().map(|c| c.errors[0].abs()).collect();
        let i: Vec<f64> = part.iter().map(|c| c.errors[1].abs()).collect();
        let f: Vec<f64> = part.iter().map(|c| c.errors[2].abs()).collect();
        let sigmas: Vec<f64> = part.iter().map(|c| c.declination_in_sigmas).collect();
        let within = |n_sigmas: f64| {
            sigmas.iter().filter(|&&s| s <= n_sigmas).count() as f64 / sigmas.len() as f64
        };
        let (within_1_sigma, within_2_sigma) = (within(1.0), within(2.0));
        eprintln!(
            "{what}: {} places; |ΔD| median {:.2}° p95 {:.2}° max {:.2}°; |ΔI| p95 {:.2}°; |ΔF| p95 {:.2} µT; \
             |ΔD| / σ p95 {:.2}, within 1σ {:.1} %, within 2σ {:.1} %",
            part.len(),
            quantile(&d, 0.5),
            quantile(&d, 0.95),
            quantile(&d, 1.0),
            quantile(&i, 0.95),
            quantile(&f, 0.95),
            quantile(&sigmas, 0.95),
            100.0 * within_1_sigma,
            100.0 * within_2_sigma,
        );
        assert!(part.len() >= 50, "{what}: {} places", part.len());
        // A stated 1σ means about 95 % within 2σ (the errors are not Gaussian: the
        // secular acceleration grows with the years), and no place far outside.
        assert!(
            within_2_sigma >= 0.93,
            "{what}: {:.1} % within 2σ",
            100.0 * within_2_sigma
        );
        assert!(quantile(&sigmas, 1.0) <= 4.0, "{what}");
    }
}
