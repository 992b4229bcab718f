//! Drone compass calibration on logs this test writes itself, byte by byte, from the
//! physics rather than from the fit's model: a general (not symmetric) soft iron, hard
//! iron, motor interference in proportion to the battery current, noise and the
//! DataFlash log's integer milligauss; a stale calibration in force that the autopilot
//! applied before logging. Random draws (the independent generator's own `Rng`), 40
//! flights; every flight's written `.param` is read back and applied as ArduPilot
//! applies it to the true raw field, and the distribution of the heading errors against
//! the true Earth field is printed. Flights with an IMU whose accelerometer reads the
//! thrust, as a multirotor's does, check that the analysis levels with the autopilot's
//! attitude.

mod flights;
mod physics;

use compass_pdr::analysis::calibration::autopilot::{autopilot_calibration, EarthField, Truth};
use compass_pdr::io::autopilot::ardupilot::{parse_param_file, ArduPilotCompass};
use compass_pdr::io::autopilot::param_in;
use flights::{fmt, message, parm};
use nalgebra::{Matrix3, Rotation3, Vector3};
use physics::Rng;

/// One flight: its log's bytes and, per sample, the truth to score against.
struct Flight {
    log: Vec<u8>,
    raw_mg: Vec<Vector3<f64>>,
    current_a: Vec<f64>,
    body_to_ned: Vec<Rotation3<f64>>,
    earth_ned_mg: Vector3<f64>,
}

fn flight(rng: &mut Rng) -> Flight {
    flight_with(rng, false)
}

/// A flight, with an IMU logged when `imu`: the gyroscope's body rates, and the
/// accelerometer as a multirotor's reads in flight, its thrust along its own −z (what
/// holds it up at its tilt) with vibration, whatever its roll and pitch.
fn flight_with(rng: &mut Rng, imu: bool) -> Flight {
    // The Earth's field at some place: 250-650 mG, inclination -70° to 70°.
    let inclination = rng.range(-70.0, 70.0).to_radians();
    let declination = rng.range(-20.0, 20.0).to_radians();
    let strength = rng.range(250.0, 650.0);
    let earth_ned_mg = strength
        * Vector3::new(
            inclination.cos() * declination.cos(),
            inclination.cos() * declination.sin(),
            inclination.sin(),
        );
    // The vehicle's iron: m = S·(field in body) + h + k·current + noise.
    let soft = Matrix3::from_fn(|row, col| {
        if row == col {
            1.0 + rng.symmetric(0.08)
        } else {
            rng.symmetric(0.04)
        }
    });
    let hard = Vector3::new(
        rng.symmetric(300.0),
        rng.symmetric(300.0),
        rng.symmetric(300.0),
    );
    let motor = Vector3::new(rng.symmetric(6.0), rng.symmetric(6.0), rng.symmetric(6.0));
    let noise = rng.range(1.0, 3.0);
    // The calibration in force: stale offsets (up to 60 mG off per axis), no soft iron.
    let stale = -hard
        + Vector3::new(
            rng.symmetric(60.0),
            rng.symmetric(60.0),
            rng.symmetric(60.0),
        );
    let stale = stale.map(f64::round);

    let yaw0 = rng.range(0.0, std::f64::consts::TAU);
    let yaw_span = rng.range(90.0, 360.0).to_radians();
    let tilt = rng.range(5.0, 25.0).to_radians();
    let n = 1500;
    let mut log = fmt(128, 89, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns");
    log.extend(fmt(129, 23, "PARM", "Nf", "Name,Value"));
    log.extend(fmt(
        130,
        29,
        "MAG",
        "Qhhhhhhhhh",
        "TimeUS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOX,MOY,MOZ",
    ));
    log.extend(fmt(131, 23, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw"));
    log.extend(fmt(132, 15, "CURR", "Qf", "TimeUS,Curr"));
    if imu {
        log.extend(fmt(
            133,
            35,
            "IMU",
            "Qffffff",
            "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ",
        ));
    }
    for (axis, value) in ["X", "Y", "Z"].iter().zip(stale.iter()) {
        log.extend(parm(&format!("COMPASS_OFS_{axis}"), *value as f32));
    }
    log.extend(parm("COMPASS_MOTCT", 0.0));
    let mut flight = Flight {
        log: Vec::new(),
        raw_mg: Vec::new(),
        current_a: Vec::new(),
        body_to_ned: Vec::new(),
        earth_ned_mg,
    };
    let phase = rng.range(0.0, 6.0);
    for i in 0..n {
        let t = i as f64 * 0.1;
        let flying = i >= 300;
        let (roll, pitch, yaw, current) = if flying {
            (
                tilt * (0.31 * t + phase).sin(),
                tilt * (0.23 * t).cos(),
                yaw0 + 0.5 * yaw_span * (1.0 - (0.02 * (t - 30.0)).cos()),
                14.0 + 5.0 * (0.05 * t + phase).sin() + rng.symmetric(1.0),
            )
        } else {
            (0.01 * rng.gaussian(), 0.01 * rng.gaussian(), yaw0, 0.5)
        };
        let body_to_ned = Rotation3::from_euler_angles(roll, pitch, yaw);
        let field_body = body_to_ned.inverse() * earth_ned_mg;
        let n3 = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * noise;
        let raw = soft * field_body + hard + motor * current + n3;
        let logged = raw + stale;
        let t_us = 10_000_000u64 + (t * 1e6) as u64;
        let mut mag = t_us.to_le_bytes().to_vec();
        for value in logged.iter().chain(stale.iter()).chain(&[0.0; 3]) {
            mag.extend_from_slice(&(value.round() as i16).to_le_bytes());
        }
        log.extend(message(130, &mag));
        let mut att = t_us.to_le_bytes().to_vec();
        for degrees in [roll, pitch, yaw.rem_euclid(std::f64::consts::TAU)].map(f64::to_degrees) {
            att.extend_from_slice(&(degrees as f32).to_le_bytes());
        }
        log.extend(message(131, &att));
        let mut curr = t_us.to_le_bytes().to_vec();
        curr.extend_from_slice(&(current as f32).to_le_bytes());
        log.extend(message(132, &curr));
        if imu {
            let rate = flight
                .body_to_ned
                .last()
                .map_or(Vector3::zeros(), |before: &Rotation3<f64>| {
                    (before.inverse() * body_to_ned).scaled_axis() / 0.1
                });
            let g = 9.80665;
            let thrust = Vector3::new(0.0, 0.0, -g / (roll.cos() * pitch.cos()));
            let vibration = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * 1.5;
            let mut imu_message = t_us.to_le_bytes().to_vec();
            for value in rate.iter().chain((thrust + vibration).iter()) {
                imu_message.extend_from_slice(&(*value as f32).to_le_bytes());
            }
            log.extend(message(133, &imu_message));
        }
        // The raw field as the log gives it back: whole mG logged, offsets undone.
        flight.raw_mg.push(logged.map(f64::round) - stale);
        flight.current_a.push(current as f32 as f64);
        flight.body_to_ned.push(body_to_ned);
    }
    flight.log = log;
    flight
}

/// Heading error (degrees) of a correction at every sample, against the true field's
/// azimuth: its RMS about its mean (a constant offset is a declination no compass can
/// tell) and the |B| spread (%).
fn score(flight: &Flight, correct: impl Fn(Vector3<f64>, f64) -> Vector3<f64>) -> (f64, f64) {
    let truth = flight.earth_ned_mg.y.atan2(flight.earth_ned_mg.x);
    let mut errors = Vec::new();
    let mut magnitudes = Vec::new();
    for ((raw, current), body_to_ned) in flight
        .raw_mg
        .iter()
        .zip(&flight.current_a)
        .zip(&flight.body_to_ned)
    {
        let corrected = correct(*raw, *current);
        let ned = body_to_ned * corrected;
        let error = ned.y.atan2(ned.x) - truth;
        errors.push(error.sin().atan2(error.cos()));
        magnitudes.push(corrected.norm());
    }
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let rms = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n)
        .sqrt()
        .to_degrees();
    let mean_m = magnitudes.iter().sum::<f64>() / n;
    let spread =
        (magnitudes.iter().map(|m| (m - mean_m).powi(2)).sum::<f64>() / n).sqrt() / mean_m * 100.0;
    (rms, spread)
}

fn percentile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    values[((values.len() - 1) as f64 * q).round() as usize]
}

#[test]
fn random_vehicles_are_calibrated_from_their_own_flight_logs() {
    let mut rng = Rng::stream(19, "autopilot flights");
    let (mut new_deg, mut old_deg, mut spread_ratio) = (Vec::new(), Vec::new(), Vec::new());
    let mut n_kept = 0;
    for case in 0..40 {
        let flight = flight(&mut rng);
        let report = compass_pdr::io::import::import("flight.bin", &flight.log).unwrap();
        let log = report.autopilot.as_ref().unwrap();
        // No GPS in these logs: the field is fitted with the offsets.
        let truth = Truth {
            earth: EarthField::Fitted,
            declination_rad: None,
        };
        let calibration = autopilot_calibration(log, &report.recording.attitude, &truth)
            .unwrap_or_else(|| panic!("case {case}: no calibration"));
        if !calibration.compasses[0].is_written() {
            // Kept: the file leaves the compass as it is, and says why.
            n_kept += 1;
            assert!(calibration.param_file.is_empty());
            continue;
        }
        let written = parse_param_file(&calibration.param_file);
        let lookup = |name: &str| param_in(&written, name).or_else(|| log.param(name));
        let new = ArduPilotCompass::from_params(&lookup, 0).unwrap();
        let in_force_lookup = |name: &str| log.param(name);
        let in_force = ArduPilotCompass::from_params(&in_force_lookup, 0).unwrap();
        let (new_rms, new_spread) = score(&flight, |raw, current| new.apply(raw, current));
        let (old_rms, old_spread) = score(&flight, |raw, current| in_force.apply(raw, current));
        assert!(
            new_rms <= (0.6 * old_rms).max(1.5),
            "case {case}: heading {new_rms:.2}° against {old_rms:.2}° in force ({:?})",
            calibration.compasses[0].model
        );
        assert!(
            new_spread <= old_spread + 0.05,
            "case {case}: |B| spread {new_spread:.2} % against {old_spread:.2} %"
        );
        new_deg.push(new_rms);
        old_deg.push(old_rms);
        spread_ratio.push(new_spread / old_spread);
    }
    eprintln!(
        "40 random flights, {n_kept} kept: heading RMS written p50 {:.2}° p90 {:.2}° max {:.2}°; in force p50 {:.1}° p90 {:.1}°; |B| spread written/in force p50 {:.2} max {:.2}",
        percentile(&mut new_deg, 0.5),
        percentile(&mut new_deg, 0.9),
        percentile(&mut new_deg, 1.0),
        percentile(&mut old_deg, 0.5),
        percentile(&mut old_deg, 0.9),
        percentile(&mut spread_ratio, 0.5),
        percentile(&mut spread_ratio, 1.0),
    );
    // Stale offsets (up to 60 mG off) on flights that turn: most are worth replacing.
    assert!(n_kept <= 8, "{n_kept} of 40 kept");
}

/// A multirotor's accelerometer reads its thrust, not gravity: levelled with it, the
/// flights' fields would be tilted by up to 25°. The analysis levels an autopilot log
/// with the autopilot's own roll and pitch instead; here, on 10 random flights, every
/// magnetometer sample's tilt is the true one.
#[test]
fn a_multirotor_log_is_levelled_with_the_autopilot_s_attitude_not_its_thrust() {
    use compass_pdr::analysis::calibration::{calibrate, CalibrationOptions};
    let mut rng = Rng::stream(23, "thrust flights");
    let (mut analysis_deg, mut accelerometer_deg) = (Vec::new(), Vec::new());
    for case in 0..10 {
        let flight = flight_with(&mut rng, true);
        let report = compass_pdr::io::import::import("flight.bin", &flight.log).unwrap();
        assert!(
            !report.recording.acc_in_body_mps2.is_empty(),
            "case {case}: IMU read"
        );
        let accelerometer = compass_pdr::attitude::down::gravity_of(&report.recording, 2.0);
        let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
        let truth = |t_s: f64| {
            let idx = ((t_s - 10.0) / 0.1).round() as usize;
            let (roll, pitch, _) = flight.body_to_ned[idx].euler_angles();
            (roll, pitch)
        };
        for (&t_s, tilt) in analysis.t_s.iter().zip(&analysis.tilt) {
            let (roll, pitch) = truth(t_s);
            let error = (tilt.roll_rad() - roll)
                .abs()
                .max((tilt.pitch_rad() - pitch).abs());
            analysis_deg.push(error.to_degrees());
            if let Some(force) = accelerometer.specific_force_mps2.interpolate_at(t_s, 0.5) {
                let thrust_tilt =
                    compass_pdr::attitude::tilt::Tilt::from_specific_force(force).unwrap();
                let error = (thrust_tilt.roll_rad() - roll)
                    .abs()
                    .max((thrust_tilt.pitch_rad() - pitch).abs());
                accelerometer_deg.push(error.to_degrees());
            }
        }
    }
    let (analysis_max, accelerometer_p90) = (
        percentile(&mut analysis_deg, 1.0),
        percentile(&mut accelerometer_deg, 0.9),
    );
    eprintln!(
        "10 random flights: tilt error of the analysis max {analysis_max:.3}°; levelled by the \
         accelerometer (thrust) it would be p90 {accelerometer_p90:.1}°"
    );
    assert!(analysis_max < 0.01, "{analysis_max}°");
    assert!(accelerometer_p90 > 5.0, "{accelerometer_p90}°");
}
