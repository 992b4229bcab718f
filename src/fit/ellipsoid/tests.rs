//! Tests of the 3D fit with the tilt and priors ([`super`]).

use super::*;
use crate::attitude::compass_heading::heading_rad;
use crate::base::angle::heading_difference_rad;
use nalgebra::Rotation3;

/// A small test generator: xorshift, Box-Muller.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn between(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.uniform()
    }
    fn gaussian(&mut self) -> f64 {
        let (u1, u2) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

struct Case {
    mag_ut: Vec<Vector3<f64>>,
    tilt: Vec<Tilt>,
    heading_rad: Vec<f64>,
    hard_iron_ut: Vector3<f64>,
    distortion: Matrix3<f64>,
    field_total_ut: f64,
    inclination_deg: f64,
}

/// A device turned through `n_turns` of heading with sinusoidal tilt of
/// `tilt_amplitude_deg`, a general distortion (cross terms up to 0.1), hard iron
/// up to `hard_iron_max_ut` on each axis, 0.3 µT of noise, and the tilt seen by the
/// fit with `tilt_noise_deg` of error.
fn case(seed: u64, tilt_amplitude_deg: f64, hard_iron_max_ut: f64, tilt_noise_deg: f64) -> Case {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let field_total_ut = rng.between(30.0, 60.0);
    let inclination_deg = rng.between(40.0, 70.0);
    let (sin_i, cos_i) = inclination_deg.to_radians().sin_cos();
    let field_ned = Vector3::new(field_total_ut * cos_i, 0.0, field_total_ut * sin_i);
    let distortion = Matrix3::from_fn(|row, col| {
        if row == col {
            1.0 + rng.between(-0.1, 0.1)
        } else {
            rng.between(-0.1, 0.1)
        }
    });
    let hard_iron_ut = Vector3::from_fn(|_, _| rng.between(-hard_iron_max_ut, hard_iron_max_ut));
    let n = 4000;
    let (phase_roll, phase_pitch) = (
        rng.between(0.0, std::f64::consts::TAU),
        rng.between(0.0, std::f64::consts::TAU),
    );
    let mut case = Case {
        mag_ut: Vec::new(),
        tilt: Vec::new(),
        heading_rad: Vec::new(),
        hard_iron_ut,
        distortion,
        field_total_ut,
        inclination_deg,
    };
    for idx in 0..n {
        let t = idx as f64 / n as f64;
        let heading = std::f64::consts::TAU * 3.0 * t;
        let roll = tilt_amplitude_deg.to_radians() * (37.0 * t + phase_roll).sin();
        let pitch = tilt_amplitude_deg.to_radians() * (23.0 * t + phase_pitch).sin();
        let ned_from_body = Rotation3::from_euler_angles(roll, pitch, heading);
        let b_body = ned_from_body.inverse() * field_ned;
        let noise = Vector3::from_fn(|_, _| 0.3 * rng.gaussian());
        case.mag_ut.push(distortion * b_body + hard_iron_ut + noise);
        case.tilt.push(Tilt::new(
            roll + tilt_noise_deg.to_radians() * rng.gaussian(),
            pitch + tilt_noise_deg.to_radians() * rng.gaussian(),
        ));
        case.heading_rad.push(heading);
    }
    case
}

fn heading_rms_deg(case: &Case, calibration: &FieldCalibration) -> f64 {
    let sum: f64 = case
        .mag_ut
        .iter()
        .zip(&case.tilt)
        .zip(&case.heading_rad)
        .map(|((&m, tilt), &truth)| {
            let heading = heading_rad(tilt.level(calibration.apply(m)), 0.0);
            heading_difference_rad(heading, truth).powi(2)
        })
        .sum();
    (sum / case.mag_ut.len() as f64).sqrt().to_degrees()
}

fn truth_calibration(case: &Case) -> FieldCalibration {
    FieldCalibration {
        hard_iron_ut: case.hard_iron_ut,
        soft_iron: case.distortion.try_inverse().expect("invertible"),
        field_ut: case.field_total_ut,
    }
}

fn prior(case: &Case) -> InertialOptions {
    InertialOptions {
        field: Some(FieldPrior {
            total_ut: case.field_total_ut,
            inclination_deg: case.inclination_deg,
        }),
        gain_known: true,
    }
}

#[test]
fn a_yaw_only_turn_with_walking_tilt_is_as_good_as_the_truth() {
    for seed in 1..=12 {
        let case = case(seed, 8.0, 30.0, 1.0);
        let fit = fit_inertial(&case.mag_ut, Some(&case.tilt), &prior(&case)).expect("fits");
        let got = heading_rms_deg(&case, &fit.calibration);
        let floor = heading_rms_deg(&case, &truth_calibration(&case));
        let error_ut = fit.calibration.hard_iron_ut - case.hard_iron_ut;
        eprintln!(
            "seed {seed}: heading {got:.2}° (truth {floor:.2}°), hard iron error {:.2?} µT, stated ±{:.2?}, heading ±{:.2}°, {:?}",
            error_ut.as_slice(),
            fit.hard_iron_std_ut.as_slice(),
            fit.heading_std_deg,
            fit.unobserved.iter().map(|u| &u.parameter).collect::<Vec<_>>()
        );
        assert!(
            got <= 1.3 * floor + 0.1,
            "seed {seed}: {got:.2}° against the truth's {floor:.2}° {fit:?}"
        );
        // Each component within three of its stated standard deviations.
        for axis in 0..3 {
            assert!(
                error_ut[axis].abs() < 3.0 * fit.hard_iron_std_ut[axis] + 0.5,
                "seed {seed}: {error_ut:?} against ±{:?}",
                fit.hard_iron_std_ut
            );
        }
    }
}

#[test]
fn a_full_sphere_without_an_accelerometer_recovers_the_distortion() {
    let mut rng = Rng(77);
    let truth = Matrix3::new(1.05, 0.04, -0.03, 0.02, 0.97, 0.06, -0.05, 0.01, 1.08);
    let hard_iron_ut = Vector3::new(12.0, -30.0, 25.0);
    let field = Vector3::new(20.0, 0.0, 45.0);
    let mag_ut: Vec<Vector3<f64>> = (0..3000)
        .map(|_| {
            let rotation = Rotation3::from_euler_angles(
                rng.between(-3.1, 3.1),
                rng.between(-1.5, 1.5),
                rng.between(-3.1, 3.1),
            );
            truth * (rotation * field)
                + hard_iron_ut
                + Vector3::from_fn(|_, _| 0.3 * rng.gaussian())
        })
        .collect();
    let fit = fit_inertial(&mag_ut, None, &InertialOptions::default()).expect("fits");
    assert!(
        (fit.calibration.hard_iron_ut - hard_iron_ut).norm() < 0.2,
        "{fit:?}"
    );
    assert!(fit.field_spread_pct < 1.0, "{fit:?}");
    assert!(fit.unobserved.is_empty(), "{:?}", fit.unobserved);
}

#[test]
fn a_level_turn_says_the_vertical_parameters_were_not_seen_and_still_gives_headings() {
    // A symmetric distortion: a rotation about the vertical is not observable on a
    // level turn (it is a constant heading offset that only a reference can see).
    let mut case = case(5, 0.0, 30.0, 0.0);
    let symmetric = (case.distortion + case.distortion.transpose()) / 2.0;
    for m in &mut case.mag_ut {
        *m = symmetric
            * case.distortion.try_inverse().expect("invertible")
            * (*m - case.hard_iron_ut)
            + case.hard_iron_ut;
    }
    case.distortion = symmetric;
    let fit = fit_inertial(&case.mag_ut, Some(&case.tilt), &prior(&case)).expect("fits");
    let got = heading_rms_deg(&case, &fit.calibration);
    assert!(got < 1.0, "{got}° {fit:?}");
    assert!(
        fit.unobserved.iter().any(|u| u.parameter == "hard iron z"),
        "{:?}",
        fit.unobserved
    );
}

#[test]
fn moving_iron_is_set_aside() {
    let mut case = case(9, 8.0, 30.0, 1.0);
    // 8 % of the samples, in four bursts, carry a disturbance of up to 40 µT.
    let n = case.mag_ut.len();
    for burst in 0..4 {
        let start = n / 5 * (burst + 1);
        for idx in start..start + n / 50 {
            let bump = ((idx - start) as f64 / (n / 50) as f64 * std::f64::consts::PI).sin();
            case.mag_ut[idx] += Vector3::new(30.0, -20.0, 15.0) * bump;
        }
    }
    let fit = fit_inertial(&case.mag_ut, Some(&case.tilt), &prior(&case)).expect("fits");
    let error_ut = fit.calibration.hard_iron_ut - case.hard_iron_ut;
    assert!(error_ut.norm() < 3.0, "{error_ut:?} {fit:?}");
    assert!(fit.outlier_pct > 3.0, "{fit:?}");
    let floor = heading_rms_deg(&case, &truth_calibration(&case));
    let got = heading_rms_deg(&case, &fit.calibration);
    eprintln!("moving iron: heading {got:.2}° against the truth's {floor:.2}°, hard iron error {error_ut:?}");
    assert!(got <= 1.1 * floor, "{got}° against {floor}°");
}

#[test]
fn a_magnet_mount_hard_iron_of_four_times_the_field_is_no_problem() {
    let case = case(3, 6.0, 200.0, 1.0);
    let fit = fit_inertial(&case.mag_ut, Some(&case.tilt), &prior(&case)).expect("fits");
    let floor = heading_rms_deg(&case, &truth_calibration(&case));
    let got = heading_rms_deg(&case, &fit.calibration);
    assert!(got <= 1.3 * floor + 0.1, "{got}° against {floor}°");
}

#[test]
fn the_residuals_gradients_match_finite_differences() {
    let state = State {
        hard_iron_ut: Vector3::new(12.0, -30.0, 25.0),
        correction: Matrix3::new(1.05, 0.04, -0.03, 0.02, 0.97, 0.06, -0.05, 0.01, 1.08),
        vertical_ut: 40.0,
        field_ut: 50.0,
    };
    let m_ut = Vector3::new(40.0, -5.0, 60.0);
    let down = Vector3::new(0.1, -0.2, 0.97).normalize();
    let (magnitude, vertical) = sample_rows(&state, m_ut, Some(down), 0.7);
    let params = state.params();
    for (which, (rho, gradient)) in [("magnitude", magnitude), ("vertical", vertical)]
        .into_iter()
        .map(|(which, row)| (which, row.expect("a row")))
    {
        for idx in 0..N_MAX {
            let step = 1e-6 * params[idx].abs().max(1.0);
            let mut shifted = params;
            shifted[idx] += step;
            let (magnitude, vertical) =
                sample_rows(&state.with_params(&shifted), m_ut, Some(down), 0.7);
            let row = if which == "magnitude" {
                magnitude
            } else {
                vertical
            };
            let numerical = (row.expect("a row").0 - rho) / step;
            assert!(
                (numerical - gradient[idx]).abs() < 1e-4 * gradient[idx].abs().max(1e-2),
                "{which}, parameter {idx}: numerical {numerical}, analytic {}",
                gradient[idx]
            );
        }
    }
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let still = vec![Vector3::new(20.0, 0.0, 40.0); 100];
    assert!(matches!(
        fit_inertial(&still, None, &InertialOptions::default()),
        Err(InertialError::NoRotation { .. })
    ));
    let mut broken = case(1, 5.0, 10.0, 0.0).mag_ut;
    broken[7].x = f64::NAN;
    assert_eq!(
        fit_inertial(&broken, None, &InertialOptions::default()),
        Err(InertialError::BadSample { sample_idx: 7 })
    );
}
