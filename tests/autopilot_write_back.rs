//! The rule every autopilot write-back follows, held on flights this test writes itself
//! ([`flights`]: DataFlash byte by byte from the physics, not `src/sim`): across 240
//! random flights from one heading to a tumble, with the parameters in force near the
//! truth, stale, with a wrong iron or absent, what `calibrate --param-out` writes for a
//! compass is never worse than the parameters in force on the held-back second half of
//! the flight, judged against the true field through the true attitude; never outside
//! ArduPilot's (MAGFit's) bounds; and a one-heading flight never gets an iron matrix.
//! The file is applied as its own text says, by this test's own reading of ArduPilot's
//! correction. The distributions are printed; `SEED=n` draws other flights.

#![cfg(not(target_arch = "wasm32"))]

mod flights;
mod physics;

use compass_pdr::analysis::calibration::{calibrate, CalibrationOptions, Method};
use compass_pdr::earth::wmm::{expected_field, CalendarDate};
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
    place_on(lat, lon, (year, month, day))
}

/// The model's field at a place and date, and the GPS fix that says so.
fn place_on(
    lat: f64,
    lon: f64,
    (year, month, day): (i32, u8, u8),
) -> (Vector3<f64>, (f64, f64, u16, u32)) {
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

fn lookup(params: &[(String, f64)]) -> impl Fn(&str) -> Option<f64> + '_ {
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

/// `compass-pdr calibrate LOG --param-out FILE --json`, the console of `calibrate LOG`,
/// the file and the page's answer (the verdict's figures) say the same of every compass
/// of a flight where one compass is written and the other kept: the one sentence, and
/// the written lines exactly where the JSON says the compass is written.
#[test]
fn the_file_the_console_the_json_and_the_page_agree_on_each_compass() {
    use compass_pdr::analysis::headings::HeadingOptions;
    use std::process::Command;
    let mut rng = Rng::stream(7, "agreement");
    // The first full-turn flight with one compass written and one kept.
    let (flight, analysis, headings) = (0..40)
        .find_map(|_| {
            let (model_ned_mg, gps) = place(&mut rng);
            let flight = flights::flight(&mut rng, Coverage::FullTurns, model_ned_mg, gps);
            let report = compass_pdr::io::import::import("flight.bin", &flight.log).ok()?;
            let (analysis, headings) =
                compass_pdr::pipeline::headings(&report, &HeadingOptions::default()).ok()?;
            let autopilot = analysis.report.autopilot.as_ref()?;
            (autopilot.written().count() == 1).then_some((flight, analysis, headings))
        })
        .expect("a flight with one compass written and one kept");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("autopilot-agreement");
    std::fs::create_dir_all(&dir).unwrap();
    let (log_path, param_path) = (dir.join("flight.bin"), dir.join("flight.param"));
    std::fs::write(&log_path, &flight.log).unwrap();
    let run = |args: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_compass-pdr"))
            .args(args)
            .output()
            .expect("the CLI runs");
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        String::from_utf8(output.stdout).unwrap()
    };
    let (log_arg, param_arg) = (log_path.to_str().unwrap(), param_path.to_str().unwrap());
    let json: serde_json::Value = serde_json::from_str(&run(&[
        "calibrate",
        log_arg,
        "--param-out",
        param_arg,
        "--json",
    ]))
    .unwrap();
    let console = run(&["calibrate", log_arg]);
    let file = std::fs::read_to_string(&param_path).unwrap();
    let file_params = read_param_file(&file);
    let verdict = compass_pdr::present::verdict::verdict(&analysis, &headings.report, None);
    let compasses = json["autopilot"]["compasses"].as_array().unwrap();
    assert_eq!(compasses.len(), 2);
    for compass in compasses {
        let sentence = compass["sentence"].as_str().unwrap();
        let label = sentence.split(": ").next().unwrap();
        assert!(console.contains(sentence), "console: {sentence}");
        assert!(
            file.lines().any(|line| line == format!("# {sentence}")),
            "file: {sentence}"
        );
        let figure = verdict
            .figures
            .iter()
            .find(|figure| figure.label == label)
            .unwrap_or_else(|| panic!("page: no figure for {label}"));
        assert_eq!(
            format!("{}: {}", figure.label, figure.value),
            sentence,
            "page"
        );
        let params = compass["params"].as_array().unwrap();
        let instance = compass["instance"].as_u64().unwrap();
        let suffix = if instance == 0 {
            "_".to_string()
        } else {
            format!("{}_", instance + 1)
        };
        let in_file: Vec<&(String, f64)> = file_params
            .iter()
            .filter(|(name, _)| {
                ["OFS", "DIA", "ODI", "MOT"]
                    .iter()
                    .any(|base| name.starts_with(&format!("COMPASS_{base}{suffix}")))
            })
            .collect();
        match compass["kept_because"].as_str() {
            None => {
                assert_eq!(in_file.len(), params.len(), "{sentence}");
                for (pair, (name, value)) in params.iter().zip(&in_file) {
                    assert_eq!(pair[0].as_str().unwrap(), name);
                    let json_value = pair[1].as_f64().unwrap();
                    assert!((json_value - value).abs() <= 1e-6 * json_value.abs().max(1.0));
                }
            }
            Some(reason) => {
                assert!(params.is_empty() && in_file.is_empty(), "{sentence}");
                assert!(sentence.contains(reason));
            }
        }
    }
}

/// The golden case `calibrate-flight-trim` (`tests/data/cases.txt`) replays
/// `tests/data/flight-trim.bin`, a 60 s flight of full turns over Zurich on 2024-06-15
/// from this generator, with its board 1-2° off the vehicle (`AHRS_TRIM`): the committed
/// file is what the generator writes (`UPDATE_EXPECT=1` rewrites it).
#[test]
fn the_committed_golden_flight_is_what_the_generator_writes() {
    let mut rng = Rng::stream(44, "golden flight");
    let (model_ned_mg, gps) = place_on(47.4, 8.5, (2024, 6, 15));
    let flight =
        flights::flight_lasting(&mut rng, Coverage::FullTurns, model_ned_mg, gps, Some(60.0));
    let trim = |name: &str| flight.params.iter().find(|(p, _)| p == name).unwrap().1;
    assert!(trim("AHRS_TRIM_X").abs().max(trim("AHRS_TRIM_Y").abs()) > 1f64.to_radians());
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/flight-trim.bin");
    if std::env::var_os("UPDATE_EXPECT").is_some() {
        std::fs::write(&path, &flight.log).unwrap();
    }
    let committed = std::fs::read(&path).expect("tests/data/flight-trim.bin");
    assert!(
        committed == flight.log,
        "tests/data/flight-trim.bin is stale: UPDATE_EXPECT=1 cargo test --test autopilot_write_back"
    );
}
