//! The rule every autopilot write-back follows, held on flights this test writes itself
//! ([`flights`]: DataFlash byte by byte from the physics, not `src/sim`): across 240
//! random flights from one heading to a tumble, with the parameters in force near the
//! truth, stale, with a wrong iron or absent, what `calibrate --param-out` writes for a
//! compass is never worse than the parameters in force on the held-back second half of
//! the flight, judged against the true field through the true attitude; never outside
//! ArduPilot's (MAGFit's) bounds; and a one-heading flight never gets an iron matrix.
//! The file is applied as its own text says, by this test's own reading of ArduPilot's
//! correction. The distributions are printed; `SEED=n` draws other flights.

mod flights;
mod physics;

use compass_pdr::calib::wmm::{expected_field, CalendarDate};
use compass_pdr::calibration::{calibrate, CalibrationOptions, Method};
use flights::{ardupilot_correct, Coverage, Flight, InForceKind};
use nalgebra::Vector3;
use physics::Rng;

/// Days from 1970-01-01 to a date (Hinnant's `days_from_civil`).
fn days_from_civil(year: i32, month: u8, day: u8) -> i64 {
    let y = i64::from(year) - i64::from(month <= 2);
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(month);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Days from the Unix epoch to the GPS epoch (1980-01-06).
const GPS_EPOCH_DAYS_SINCE_UNIX: i64 = 3657;

/// A random place and date: latitude within ±60°, any longitude, 2020-2029; the model's
/// field there (north-east-down, mG) and the GPS fix that says so.
fn place(rng: &mut Rng) -> (Vector3<f64>, (f64, f64, u16, u32)) {
    let lat = rng.range(-60.0, 60.0);
    let lon = rng.range(-180.0, 180.0);
    let year = 2020 + rng.index(10) as i32;
    let month = 1 + rng.index(12) as u8;
    let day = 1 + rng.index(28) as u8;
    let date = CalendarDate::new(year, month, day).unwrap();
    let field = expected_field(lat, lon, 100.0, date).unwrap();
    let declination = field.declination_deg.to_radians();
    let ned_mg = Vector3::new(
        field.horizontal_ut * declination.cos(),
        field.horizontal_ut * declination.sin(),
        field.vertical_ut,
    ) * 10.0;
    // Noon UTC of that day, in GPS weeks and milliseconds (18 leap seconds).
    let days = days_from_civil(year, month, day) - GPS_EPOCH_DAYS_SINCE_UNIX;
    let week = (days / 7) as u16;
    let week_ms = ((days % 7) * 86_400 + 43_200 + 18) as u32 * 1000;
    (ned_mg, (lat, lon, week, week_ms))
}

/// RMS of the corrected field against the true field through the true attitude, on the
/// second half of the flight (mG).
fn truth_check_rms(flight: &Flight, instance: usize, params: &dyn Fn(&str) -> Option<f64>) -> f64 {
    let compass = &flight.compasses[instance];
    let n = compass.raw_mg.len();
    let mut sum = 0.0;
    for i in n / 2..n {
        let corrected = ardupilot_correct(params, instance, compass.raw_mg[i], flight.current_a[i]);
        let truth = flight.board_to_ned[i].inverse() * flight.earth_ned_mg;
        sum += (corrected - truth).norm_squared();
    }
    (sum / (n - n / 2) as f64).sqrt()
}

/// The parameters of a `.param` text, read as Mission Planner reads it.
fn read_param_file(text: &str) -> Vec<(String, f64)> {
    text.lines()
        .filter(|line| !line.trim_start().starts_with('#') && !line.trim().is_empty())
        .filter_map(|line| {
            let (name, value) = line.split_once(',')?;
            Some((name.trim().to_string(), value.trim().parse().ok()?))
        })
        .collect()
}

fn lookup<'a>(params: &'a [(String, f64)]) -> impl Fn(&str) -> Option<f64> + 'a {
    move |name: &str| {
        params
            .iter()
            .rev()
            .find(|(param, _)| param == name)
            .map(|&(_, value)| value)
    }
}

fn percentile(values: &mut [f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn what_is_written_is_never_worse_than_in_force_nor_outside_the_autopilot_s_bounds() {
    let mut rng = Rng::stream(
        std::env::var("SEED")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(41),
        "autopilot write-back",
    );
    let options = CalibrationOptions {
        methods: vec![Method::MinMax],
        ..CalibrationOptions::default()
    };
    let mut failures = Vec::new();
    for coverage in Coverage::ALL {
        let (mut ratios, mut n_written, mut n_compasses) = (Vec::new(), 0, 0);
        let mut kept_by_kind = [(0, 0); 4];
        for case in 0..60 {
            let (model_ned_mg, gps) = place(&mut rng);
            let flight = flights::flight(&mut rng, coverage, model_ned_mg, gps);
            let report = compass_pdr::io::import::import("flight.bin", &flight.log).unwrap();
            let analysis = calibrate(report, &options).unwrap();
            let calibration = analysis
                .report
                .autopilot
                .as_ref()
                .unwrap_or_else(|| panic!("{coverage:?} {case}: no calibration"));
            let mut written = flight.params.clone();
            written.extend(read_param_file(&calibration.param_file));
            let (in_force, after) = (lookup(&flight.params), lookup(&written));
            for compass in &flight.compasses {
                let instance = compass.instance;
                n_compasses += 1;
                let result = calibration
                    .compasses
                    .iter()
                    .find(|result| result.instance == instance)
                    .expect("every compass assessed");
                let before_mg = truth_check_rms(&flight, instance, &in_force);
                let after_mg = truth_check_rms(&flight, instance, &after);
                let kind_idx = compass.kind as usize;
                kept_by_kind[kind_idx].1 += 1;
                if !result.is_written() {
                    kept_by_kind[kind_idx].0 += 1;
                    assert_eq!(before_mg, after_mg, "{coverage:?} {case}: kept but changed");
                    continue;
                }
                n_written += 1;
                ratios.push(after_mg / before_mg);
                let what = format!(
                    "{coverage:?} case {case} compass {instance} ({:?} in force): {} written, \
                     {after_mg:.1} mG against {before_mg:.1} mG in force on the held-back half \
                     (measured against the model's field: {:.1} against {:.1} mG)",
                    compass.kind,
                    result.model.as_deref().unwrap_or("?"),
                    result.check.new.map_or(f64::NAN, |s| s.vector_rms_mg),
                    result.check.in_force.map_or(f64::NAN, |s| s.vector_rms_mg),
                );
                // Never worse than in force, within half a mG of rounding.
                if after_mg > before_mg + 0.5 {
                    failures.push(what.clone());
                }
                // Never outside ArduPilot's (MAGFit's) bounds.
                for (name, value) in &result.params {
                    let within = if name.contains("_OFS") {
                        value.abs() < 1500.0
                    } else if name.contains("_DIA") {
                        (0.8..1.2).contains(value)
                    } else if name.contains("_ODI") {
                        value.abs() < 0.2
                    } else if name.contains("SCALE") {
                        (0.8..1.2).contains(value)
                    } else {
                        value.is_finite()
                    };
                    assert!(within, "{what}: {name} {value}");
                }
                // One heading: the offsets (and motor) only, the iron in force held.
                if coverage == Coverage::OneHeading {
                    let model = result.model.as_deref().unwrap_or_default();
                    assert!(
                        model.starts_with("offsets") && !model.contains(" and "),
                        "{what}"
                    );
                    for base in ["DIA", "ODI"] {
                        for axis in ["X", "Y", "Z"] {
                            let number = if instance == 0 {
                                String::new()
                            } else {
                                (instance + 1).to_string()
                            };
                            let name = format!("COMPASS_{base}{number}_{axis}");
                            let held =
                                in_force(&name).unwrap_or(if base == "DIA" { 1.0 } else { 0.0 });
                            let now = after(&name).unwrap_or(held);
                            assert!(
                                (now - held).abs() < 1e-6
                                    || (compass.kind == InForceKind::None
                                        && (now - if base == "DIA" { 1.0 } else { 0.0 }).abs()
                                            < 1e-6),
                                "{what}: {name} {now} against {held} in force"
                            );
                        }
                    }
                }
            }
        }
        eprintln!(
            "{coverage:?}: 60 flights, {n_written} of {n_compasses} compasses written; truth \
             vector error on the held-back half written/in force p50 {:.2} p90 {:.2} max {:.2}; \
             kept (of assessed) with in force good {}/{}, stale {}/{}, wrong iron {}/{}, none {}/{}",
            percentile(&mut ratios.clone(), 0.5),
            percentile(&mut ratios.clone(), 0.9),
            percentile(&mut ratios, 1.0),
            kept_by_kind[0].0,
            kept_by_kind[0].1,
            kept_by_kind[1].0,
            kept_by_kind[1].1,
            kept_by_kind[2].0,
            kept_by_kind[2].1,
            kept_by_kind[3].0,
            kept_by_kind[3].1,
        );
    }
    assert!(
        failures.is_empty(),
        "{} worse than in force:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
