//! Tests of the 3D ellipsoid fit ([`super`]): the power sums, the Jacobian, recovery of
//! random distortions on full spheres, the models and the band fallback on circle-only
//! data, degenerate inputs, the streaming solve, and the `band_sweep` table behind
//! [`MIN_FULL_TILT_SPAN_DEG`] (slow, so ignored; it asserts what the threshold claims, and
//! a quicker test asserts the same on fewer distortions in every run).

use super::*;
use crate::attitude::compass_heading::heading_rad;
use crate::attitude::tilt::Tilt;
use crate::base::angle::heading_difference_rad;
use crate::base::rng::SplitMix64;
use crate::sim::field::{circle_only, full_sphere, FieldSample, FieldTruth};
use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::Matrix3;

/// The distortions: hard iron up to 60 µT, soft iron 1 ± 0.1 on the
/// diagonal and up to 0.1 off it, 0.3 µT of noise, a 50 µT field.
fn random_truth(seed: u64, inclination_deg: f64) -> (FieldTruth, SplitMix64) {
    let mut rng = SplitMix64::new(seed);
    let truth = FieldTruth {
        inclination_deg,
        ..FieldTruth::random(&mut rng, 60.0, 0.1, 0.1)
    };
    (truth, rng)
}

fn mags(samples: &[FieldSample]) -> Vec<Vector3<f64>> {
    samples.iter().map(|sample| sample.mag_ut).collect()
}

/// ‖A − S⁻¹‖_F / ‖S⁻¹‖_F, with `A` scaled to the truth's corrected radius first.
fn soft_iron_error(calibration: &FieldCalibration, truth: &FieldTruth) -> f64 {
    let ideal = truth.ideal_correction();
    let scaled = calibration.soft_iron * (truth.field_total_ut / calibration.field_ut);
    (scaled - ideal).norm() / ideal.norm()
}

/// RMS of the heading error after levelling the corrected field with the true tilt.
fn heading_rms_deg(samples: &[FieldSample], calibration: &FieldCalibration) -> f64 {
    let sum_squares: f64 = samples
        .iter()
        .map(|sample| {
            let tilt = Tilt::new(sample.roll_rad, sample.pitch_rad);
            let level_ut = tilt.level(calibration.apply(sample.mag_ut));
            heading_difference_rad(heading_rad(level_ut, 0.0), sample.heading_rad).powi(2)
        })
        .sum();
    (sum_squares / samples.len() as f64).sqrt().to_degrees()
}

/// A model's fit without the observability fallback: what a plain 3D fit gives.
fn forced_fit(mag_ut: &[Vector3<f64>], model: EllipsoidModel) -> FieldCalibration {
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(mag_ut);
    let geometry = accumulator.geometry().expect("geometry");
    let algebraic = geometry.algebraic_fit(model, None).expect("algebraic fit");
    refine(mag_ut, model, &geometry, &algebraic, None).unwrap_or(algebraic)
}

#[test]
fn monomials_follow_the_exponent_table() {
    let d = Vector3::new(1.3, -0.7, 2.1);
    for (term, [a, b, c]) in monomials(d).iter().zip(EXPONENTS) {
        let expect = d.x.powi(a as i32) * d.y.powi(b as i32) * d.z.powi(c as i32);
        assert!((term - expect).abs() < 1e-12, "{a} {b} {c}");
    }
    for (moment_idx, [a, b, c]) in EXPONENTS.iter().enumerate() {
        assert_eq!(MOMENT_INDEX[*a][*b][*c], moment_idx);
    }
}

#[test]
fn chunked_sums_equal_per_sample_sums() {
    let samples: Vec<Vector3<f64>> = (0..1000)
        .map(|idx| {
            let t = idx as f64 * 0.37;
            Vector3::new(
                30.0 * t.cos() + 5.0,
                -20.0 * t.sin(),
                10.0 * (0.3 * t).sin() - 40.0,
            )
        })
        .collect();
    let (mut one_by_one, mut chunked) = (EllipsoidAccumulator::new(), EllipsoidAccumulator::new());
    for &m_ut in &samples {
        one_by_one.add(m_ut);
    }
    chunked.add_all(&samples);
    assert_eq!(one_by_one.n_samples(), chunked.n_samples());
    for (a, b) in one_by_one.moments.iter().zip(chunked.moments) {
        assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} {b}");
    }
}

#[test]
fn the_sums_of_offsets_agree_on_every_path() {
    // On x86-64 `offset_sums` is the SSE2 code: it must give the scalar sums, for
    // odd and even lengths.
    for n_offsets in [1, 2, 3, 100, 255, CHUNK_LEN] {
        let offsets: Vec<[f64; 3]> = (0..n_offsets)
            .map(|idx| {
                let t = idx as f64 * 0.61;
                [
                    25.0 * t.cos() - 3.0,
                    18.0 * t.sin() + 2.0,
                    30.0 * (0.2 * t).cos(),
                ]
            })
            .collect();
        let mut expect = [0.0; N_MOMENTS];
        for &[x, y, z] in &offsets {
            for (sum, term) in expect.iter_mut().zip(monomials(Vector3::new(x, y, z))) {
                *sum += term;
            }
        }
        for sums in [offset_sums(&offsets), scalar_offset_sums(&offsets)] {
            for (got, want) in sums.iter().zip(expect) {
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "{n_offsets}: {got} {want}"
                );
            }
        }
    }
}

#[test]
fn moving_the_origin_is_exact() {
    let samples = [
        Vector3::new(1.0, 2.0, 3.0),
        Vector3::new(-4.0, 0.5, 2.0),
        Vector3::new(0.3, -1.0, -2.5),
    ];
    let shift = Vector3::new(0.7, -1.3, 2.2);
    let sums = |offset: Vector3<f64>, scale: f64| {
        let mut sums = [0.0; N_MOMENTS];
        for &m in &samples {
            for (sum, term) in sums.iter_mut().zip(monomials((m + offset) / scale)) {
                *sum += term;
            }
        }
        sums
    };
    let moved = shift_and_scale(&sums(Vector3::zeros(), 1.0), shift, 2.5);
    for (a, b) in moved.iter().zip(sums(shift, 2.5)) {
        assert!((a - b).abs() < 1e-12 * b.abs().max(1.0), "{a} {b}");
    }
}

#[test]
fn the_jacobian_matches_numerical_derivatives() {
    let (truth, mut rng) = random_truth(5, 60.0);
    let samples = mags(&full_sphere(&truth, 50, &mut rng));
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(&samples);
    let geometry = accumulator.geometry().expect("geometry");
    for model in [
        EllipsoidModel::Sphere,
        EllipsoidModel::Diagonal,
        EllipsoidModel::Full,
        EllipsoidModel::Band,
    ] {
        let generators = generators(model, &geometry);
        let start = geometry.algebraic_fit(model, None).expect("fit");
        // Away from the optimum, so that the residual terms of the derivative count.
        let perturbed = FieldCalibration {
            hard_iron_ut: start.hard_iron_ut + Vector3::new(1.0, -2.0, 0.5),
            field_ut: start.field_ut * 1.1,
            ..start
        };
        let mut problem = problem_at(&samples, &generators, &perturbed).expect("problem");
        let analytic = problem.jacobian().expect("jacobian");
        let numeric = levenberg_marquardt::differentiate_numerically(&mut problem)
            .expect("numerical jacobian");
        let error = (&analytic - &numeric).amax() / numeric.amax();
        assert!(error < 1e-6, "{model:?}: relative error {error}");
    }
}

#[test]
fn full_sphere_data_recover_random_distortions() {
    // Acceptance test of the issue. Over 3000 samples the noise leaves about
    // 0.3·√(3/3000) ≈ 0.01 µT of hard-iron error per axis, well inside 0.1 µT; 300
    // samples (0.03 µT per axis) would still pass, 30 would not.
    let n_seeds = 100;
    let (mut worst_hard_iron_ut, mut worst_soft_iron, mut worst_rms_ut) = (0.0f64, 0.0f64, 0.0f64);
    for seed in 0..n_seeds {
        let (truth, mut rng) = random_truth(seed, 60.0);
        let samples = mags(&full_sphere(&truth, 3000, &mut rng));
        let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
        let hard_iron_error_ut = (fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm();
        let soft_iron_error = soft_iron_error(&fit.calibration, &truth);
        assert!(
            hard_iron_error_ut < 0.1,
            "seed {seed}: hard iron off by {hard_iron_error_ut} µT"
        );
        assert!(
            soft_iron_error < 0.005,
            "seed {seed}: soft iron off by {soft_iron_error}"
        );
        assert_eq!(fit.model, EllipsoidModel::Full, "seed {seed}");
        assert_eq!(fit.fallback, None, "seed {seed}");
        assert!(fit.refined, "seed {seed}");
        assert!(
            fit.observability.tilt_span_deg > 35.0,
            "{:?}",
            fit.observability
        );
        worst_hard_iron_ut = worst_hard_iron_ut.max(hard_iron_error_ut);
        worst_soft_iron = worst_soft_iron.max(soft_iron_error);
        worst_rms_ut = worst_rms_ut.max(fit.residual_rms_ut);
    }
    // The residual is the noise along the radius (0.3 µT), no more.
    assert!(worst_rms_ut < 0.33, "{worst_rms_ut}");
    println!(
        "full sphere, {n_seeds} seeds, 3000 samples: worst hard-iron error \
         {worst_hard_iron_ut:.4} µT, worst soft-iron error {:.3} %, worst RMS \
         {worst_rms_ut:.3} µT",
        100.0 * worst_soft_iron
    );
}

#[test]
fn full_sphere_accuracy_by_sample_count() {
    for (n_samples, max_hard_iron_ut) in [(300, 0.15), (1000, 0.1), (10_000, 0.03)] {
        let mut worst_ut = 0.0f64;
        for seed in 0..30 {
            let (truth, mut rng) = random_truth(1000 + seed, 60.0);
            let samples = mags(&full_sphere(&truth, n_samples, &mut rng));
            let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
            worst_ut = worst_ut.max((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm());
        }
        println!("full sphere, {n_samples} samples: worst hard-iron error {worst_ut:.4} µT");
        assert!(worst_ut < max_hard_iron_ut, "{n_samples}: {worst_ut}");
    }
}

#[test]
fn the_expected_field_sets_the_corrected_magnitude() {
    for seed in 0..20 {
        let (truth, mut rng) = random_truth(200 + seed, 60.0);
        let samples = mags(&full_sphere(&truth, 3000, &mut rng));
        let options = EllipsoidOptions {
            expected_field_ut: Some(truth.field_total_ut),
            ..EllipsoidOptions::default()
        };
        let fit = fit_ellipsoid(&samples, &options).expect("fits");
        assert_eq!(fit.calibration.field_ut, truth.field_total_ut);
        // No rescaling needed: A is the truth's S⁻¹ itself.
        let error = (fit.calibration.soft_iron - truth.ideal_correction()).norm()
            / truth.ideal_correction().norm();
        assert!(error < 0.005, "seed {seed}: {error}");
        assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
    }
}

#[test]
fn noise_free_data_are_fitted_exactly() {
    let (truth, mut rng) = random_truth(9, 60.0);
    let truth = FieldTruth {
        noise_ut: 0.0,
        ..truth
    };
    let samples = mags(&full_sphere(&truth, 500, &mut rng));
    for refine in [false, true] {
        let options = EllipsoidOptions {
            refine,
            ..EllipsoidOptions::default()
        };
        let fit = fit_ellipsoid(&samples, &options).expect("fits");
        assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 1e-6);
        assert!(soft_iron_error(&fit.calibration, &truth) < 1e-8);
        assert!(fit.residual_rms_ut < 1e-6, "{}", fit.residual_rms_ut);
    }
}

#[test]
fn a_hard_iron_far_larger_than_the_field_is_well_conditioned() {
    // Raw counts of some sensors, or a magnet glued next to the sensor.
    let (truth, mut rng) = random_truth(11, 60.0);
    let truth = FieldTruth {
        hard_iron_ut: Vector3::new(5000.0, -3000.0, 8000.0),
        ..truth
    };
    let samples = mags(&full_sphere(&truth, 3000, &mut rng));
    let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
    assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
    assert!(soft_iron_error(&fit.calibration, &truth) < 0.005);
}

#[test]
fn auto_prefers_the_simplest_model_the_data_support() {
    let cases = [
        (Matrix3::identity(), EllipsoidModel::Sphere),
        (
            Matrix3::from_diagonal(&Vector3::new(1.08, 0.93, 1.0)),
            EllipsoidModel::Diagonal,
        ),
        (
            Matrix3::new(1.05, 0.06, -0.04, 0.06, 0.95, 0.03, -0.04, 0.03, 1.0),
            EllipsoidModel::Full,
        ),
    ];
    for (soft_iron, expect) in cases {
        let (truth, mut rng) = random_truth(21, 60.0);
        let truth = FieldTruth { soft_iron, ..truth };
        let samples = mags(&full_sphere(&truth, 3000, &mut rng));
        let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
        assert_eq!(fit.model, expect, "{soft_iron}");
        assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
    }
}

#[test]
fn each_model_can_be_asked_for() {
    let (truth, mut rng) = random_truth(23, 60.0);
    let samples = mags(&full_sphere(&truth, 2000, &mut rng));
    for model in [
        EllipsoidModel::Sphere,
        EllipsoidModel::Diagonal,
        EllipsoidModel::Full,
        EllipsoidModel::Band,
    ] {
        let options = EllipsoidOptions {
            model,
            ..EllipsoidOptions::default()
        };
        let fit = fit_ellipsoid(&samples, &options).expect("fits");
        assert_eq!(fit.model, model);
        let soft_iron = fit.calibration.soft_iron;
        assert!((soft_iron - soft_iron.transpose()).amax() < 1e-12);
        match model {
            EllipsoidModel::Sphere => {
                assert!(
                    (soft_iron - Matrix3::identity()).amax() < 1e-9,
                    "{soft_iron}"
                );
            }
            EllipsoidModel::Diagonal => {
                assert!((soft_iron - Matrix3::from_diagonal(&soft_iron.diagonal())).amax() == 0.0);
            }
            _ => {}
        }
        // det A = 1 without an expected field.
        assert!((soft_iron.determinant() - 1.0).abs() < 1e-9, "{model:?}");
    }
}

#[test]
fn circle_only_data_fall_back_and_keep_the_horizontal_hard_iron() {
    // Acceptance test of the issue: every heading, roll and pitch within ±10°,
    // inclination 65°. A plain 3D fit leaves the scale along z free against the
    // hard iron along z; the fallback ties it and says so.
    let n_seeds = 50;
    let (mut worst_horizontal_ut, mut worst_heading_deg, mut mean_heading_deg) =
        (0.0f64, 0.0f64, 0.0);
    let (mut worst_full_heading_deg, mut mean_full_heading_deg, mut worst_full_hard_iron_ut) =
        (0.0f64, 0.0, 0.0f64);
    let mut worst_vertical_ut = 0.0f64;
    for seed in 0..n_seeds {
        let (truth, mut rng) = random_truth(300 + seed, 65.0);
        let samples = circle_only(&truth, 3000, 10.0, &mut rng);
        let mag_ut = mags(&samples);
        let fit = fit_ellipsoid(&mag_ut, &EllipsoidOptions::default()).expect("fits");
        assert_eq!(fit.model, EllipsoidModel::Band, "seed {seed}");
        let fallback = fit.fallback.as_deref().unwrap_or_default();
        assert!(
            fallback.contains("about the body z axis") && fallback.contains("fell back"),
            "{fallback}"
        );
        let tilt_span_deg = fit.observability.tilt_span_deg;
        assert!(
            (6.0..15.0).contains(&tilt_span_deg),
            "seed {seed}: {tilt_span_deg}"
        );
        let error_ut = fit.calibration.hard_iron_ut - truth.hard_iron_ut;
        let heading_deg = heading_rms_deg(&samples, &fit.calibration);
        assert!(error_ut.xy().norm() < 6.0, "seed {seed}: {error_ut:?}");
        assert!(heading_deg < 5.0, "seed {seed}: {heading_deg}°");
        worst_horizontal_ut = worst_horizontal_ut.max(error_ut.xy().norm());
        worst_vertical_ut = worst_vertical_ut.max(error_ut.z.abs());
        worst_heading_deg = worst_heading_deg.max(heading_deg);
        mean_heading_deg += heading_deg / n_seeds as f64;

        let full = forced_fit(&mag_ut, EllipsoidModel::Full);
        let full_heading_deg = heading_rms_deg(&samples, &full);
        worst_full_heading_deg = worst_full_heading_deg.max(full_heading_deg);
        mean_full_heading_deg += full_heading_deg / n_seeds as f64;
        worst_full_hard_iron_ut =
            worst_full_hard_iron_ut.max((full.hard_iron_ut - truth.hard_iron_ut).norm());
    }
    println!(
        "circle only ±10°, {n_seeds} seeds, 3000 samples: band fallback heading RMS mean \
         {mean_heading_deg:.2}°, worst {worst_heading_deg:.2}°; hard-iron error worst \
         {worst_horizontal_ut:.2} µT horizontal, {worst_vertical_ut:.1} µT vertical. Full \
         3D fit without fallback: heading RMS mean {mean_full_heading_deg:.2}°, worst \
         {worst_full_heading_deg:.2}°, hard-iron error worst {worst_full_hard_iron_ut:.1} µT"
    );
}

#[test]
fn caps_of_the_sphere_do_not_blow_up() {
    // A device never turned upside down (a hemisphere of field directions), and one
    // kept within about 60° of one attitude.
    // The cap is a hard case: it looks narrow to the tilt span, and either model
    // leaves degrees of heading error on some distortions; the fit chooses per
    // distortion (see `prefers_band`) and stays within 3.2° RMS.
    for (label, min_cos, max_hard_iron_ut, max_heading_deg) in [
        ("hemisphere", 0.0, 0.3, 1.0),
        ("cap of ±60°", 0.5, 8.0, 4.0),
    ] {
        let (mut worst_ut, mut worst_soft_iron, mut worst_heading_deg) = (0.0f64, 0.0f64, 0.0f64);
        let mut models = Vec::new();
        for seed in 0..20 {
            let (truth, mut rng) = random_truth(400 + seed, 60.0);
            let samples: Vec<FieldSample> = full_sphere(&truth, 6000, &mut rng)
                .into_iter()
                .filter(|sample| {
                    let offset_ut = truth.ideal_correction() * (sample.mag_ut - truth.hard_iron_ut);
                    offset_ut.z / offset_ut.norm() >= min_cos
                })
                .collect();
            let fit = fit_ellipsoid(&mags(&samples), &EllipsoidOptions::default()).expect("fits");
            worst_ut = worst_ut.max((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm());
            worst_soft_iron = worst_soft_iron.max(soft_iron_error(&fit.calibration, &truth));
            worst_heading_deg = worst_heading_deg.max(heading_rms_deg(&samples, &fit.calibration));
            models.push(fit.model);
        }
        println!(
            "{label}: models {models:?}; worst hard-iron error {worst_ut:.2} µT, soft iron \
             {:.2} %, heading RMS {worst_heading_deg:.2}°",
            100.0 * worst_soft_iron
        );
        assert!(
            worst_ut < max_hard_iron_ut && worst_heading_deg < max_heading_deg,
            "{label}"
        );
    }
}

#[test]
fn a_sphere_asked_for_on_circle_only_data_is_kept() {
    let (truth, mut rng) = random_truth(40, 65.0);
    let samples = mags(&circle_only(&truth, 2000, 10.0, &mut rng));
    let options = EllipsoidOptions {
        model: EllipsoidModel::Sphere,
        ..EllipsoidOptions::default()
    };
    let fit = fit_ellipsoid(&samples, &options).expect("fits");
    assert_eq!((fit.model, fit.fallback), (EllipsoidModel::Sphere, None));
}

#[test]
fn degenerate_inputs_are_errors_not_panics() {
    let options = EllipsoidOptions::default();
    let point = vec![Vector3::new(20.0, -5.0, 40.0); 100];
    assert!(matches!(
        fit_ellipsoid(&point, &options),
        Err(EllipsoidError::NoRotation { .. })
    ));
    let line: Vec<Vector3<f64>> = (0..100)
        .map(|idx| Vector3::new(1.0, 2.0, -1.0) * (idx as f64 - 50.0) + Vector3::new(3.0, 0.0, 9.0))
        .collect();
    assert!(matches!(
        fit_ellipsoid(&line, &options),
        Err(EllipsoidError::Line { .. })
    ));
    // A ring in a tilted plane: a turn about one axis and nothing else.
    let (e1, e2) = (
        Vector3::new(1.0, 1.0, 0.0).normalize(),
        Vector3::new(0.0, 0.3, 1.0).normalize(),
    );
    let plane: Vec<Vector3<f64>> = (0..360)
        .map(|idx| {
            let angle = (idx as f64).to_radians();
            Vector3::new(10.0, 20.0, -30.0) + (e1 * angle.cos() + e2 * angle.sin()) * 25.0
        })
        .collect();
    assert!(matches!(
        fit_ellipsoid(&plane, &options),
        Err(EllipsoidError::Plane { .. })
    ));
    let (truth, mut rng) = random_truth(50, 60.0);
    let good = mags(&full_sphere(&truth, 100, &mut rng));
    for bad_value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut with_bad = good.clone();
        with_bad[7].y = bad_value;
        assert_eq!(
            fit_ellipsoid(&with_bad, &options).map(|fit| fit.model),
            Err(EllipsoidError::NonFinite { sample_idx: 7 })
        );
    }
    let mut with_huge = good.clone();
    with_huge[40].z = 1e200;
    assert!(matches!(
        fit_ellipsoid(&with_huge, &options),
        Err(EllipsoidError::OutOfRange { sample_idx: 40, .. })
    ));
    let huge: Vec<Vector3<f64>> = good.iter().map(|&m_ut| m_ut * 1e150).collect();
    assert!(matches!(
        fit_ellipsoid(&huge, &options),
        Err(EllipsoidError::OutOfRange { sample_idx: 0, .. })
    ));
    assert_eq!(
        fit_ellipsoid(&good[..5], &options).map(|fit| fit.model),
        Err(EllipsoidError::TooFewSamples {
            n_samples: 5,
            min: MIN_SAMPLES
        })
    );
    assert!(matches!(
        fit_ellipsoid(&[], &options),
        Err(EllipsoidError::TooFewSamples { n_samples: 0, .. })
    ));
    for field_ut in [0.0, -50.0, f64::NAN, f64::INFINITY] {
        let options = EllipsoidOptions {
            expected_field_ut: Some(field_ut),
            ..EllipsoidOptions::default()
        };
        assert!(matches!(
            fit_ellipsoid(&good, &options),
            Err(EllipsoidError::InvalidExpectedField { .. })
        ));
    }
    // A hyperboloid is no ellipsoid.
    let hyperboloid: Vec<Vector3<f64>> = (0..400)
        .map(|idx| {
            let (angle, height) = (
                (idx as f64 * 17.0).to_radians(),
                (idx % 20) as f64 * 3.0 - 30.0,
            );
            let radius = (400.0 + height * height).sqrt();
            Vector3::new(radius * angle.cos(), radius * angle.sin(), height)
        })
        .collect();
    let result = fit_ellipsoid(&hyperboloid, &options);
    assert!(
        matches!(
            result,
            Err(EllipsoidError::NotAnEllipsoid { .. } | EllipsoidError::PoorFit { .. })
        ),
        "{result:?}"
    );
    // The messages are sentences that say what to do.
    let message = EllipsoidError::Plane { tilt_span_deg: 1.2 }.to_string();
    assert!(
        message.contains("±1.2°") && message.contains("tilting"),
        "{message}"
    );
}

#[test]
fn random_clouds_never_panic() {
    let mut rng = SplitMix64::new(77);
    for n_samples in [10, 11, 12, 15, 20, 50, 200] {
        for _ in 0..50 {
            let cloud: Vec<Vector3<f64>> = (0..n_samples)
                .map(|_| {
                    Vector3::new(
                        rng.uniform_in(-60.0, 60.0),
                        rng.uniform_in(-60.0, 60.0),
                        rng.uniform_in(-60.0, 60.0),
                    )
                })
                .collect();
            for model in [EllipsoidModel::Auto, EllipsoidModel::Band] {
                let options = EllipsoidOptions {
                    model,
                    ..EllipsoidOptions::default()
                };
                if let Ok(fit) = fit_ellipsoid(&cloud, &options) {
                    assert!(fit.calibration.soft_iron.iter().all(|v| v.is_finite()));
                    assert!(fit.calibration.hard_iron_ut.iter().all(|v| v.is_finite()));
                    assert!(fit.observability.axis_ratio <= MAX_AXIS_RATIO);
                }
            }
        }
    }
}

#[test]
fn order_and_chunking_do_not_change_the_streaming_fit() {
    let (truth, mut rng) = random_truth(60, 60.0);
    let samples = mags(&full_sphere(&truth, 2000, &mut rng));
    let mut one_pass = EllipsoidAccumulator::new();
    for &m_ut in &samples {
        one_pass.add(m_ut);
    }
    let reference = one_pass.solve(EllipsoidModel::Full, None).expect("solves");
    let check = |accumulator: &EllipsoidAccumulator, label: &str| {
        let fit = accumulator
            .solve(EllipsoidModel::Full, None)
            .expect("solves");
        assert_eq!(fit.n_samples, samples.len(), "{label}");
        let hard_iron_ut =
            (fit.calibration.hard_iron_ut - reference.calibration.hard_iron_ut).norm();
        let soft_iron = (fit.calibration.soft_iron - reference.calibration.soft_iron).amax();
        let field_ut = (fit.calibration.field_ut - reference.calibration.field_ut).abs();
        assert!(
            hard_iron_ut < 1e-9 && soft_iron < 1e-11 && field_ut < 1e-9,
            "{label}: {hard_iron_ut} {soft_iron} {field_ut}"
        );
    };
    let mut reversed = EllipsoidAccumulator::new();
    samples.iter().rev().for_each(|&m_ut| reversed.add(m_ut));
    check(&reversed, "reversed");
    let mut slice = EllipsoidAccumulator::new();
    slice.add_all(&samples);
    check(&slice, "add_all");
    let (first_half, second_half) = samples.split_at(samples.len() / 2);
    let (mut first, mut second) = (EllipsoidAccumulator::new(), EllipsoidAccumulator::new());
    first.add_all(first_half);
    second.add_all(second_half);
    let mut merged = first.clone();
    merged.merge(&second);
    check(&merged, "merge of two halves");
    let mut merged_the_other_way = second.clone();
    merged_the_other_way.merge(&first);
    check(&merged_the_other_way, "halves merged in the other order");
    for chunk_len in [1, 7, 256, 999] {
        let mut total = EllipsoidAccumulator::new();
        total.merge(&EllipsoidAccumulator::new());
        for chunk in samples.chunks(chunk_len) {
            let mut part = EllipsoidAccumulator::new();
            part.add_all(chunk);
            total.merge(&part);
            total.merge(&EllipsoidAccumulator::new());
        }
        check(&total, &format!("chunks of {chunk_len}"));
    }
    // A non-finite sample keeps its place in the merged order.
    let mut with_nan = EllipsoidAccumulator::new();
    with_nan.add_all(&samples[..5]);
    with_nan.add(Vector3::new(f64::NAN, 0.0, 0.0));
    let mut merged = first.clone();
    merged.merge(&with_nan);
    assert_eq!(
        merged
            .solve(EllipsoidModel::Full, None)
            .map(|fit| fit.n_samples),
        Err(EllipsoidError::NonFinite {
            sample_idx: first_half.len() + 5
        })
    );
}

#[test]
fn the_streaming_solve_is_the_algebraic_fit() {
    let (truth, mut rng) = random_truth(70, 60.0);
    let samples = mags(&full_sphere(&truth, 3000, &mut rng));
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(&samples);
    let streamed = accumulator
        .solve(EllipsoidModel::Auto, None)
        .expect("solves");
    let options = EllipsoidOptions {
        model: EllipsoidModel::Full,
        refine: false,
        ..EllipsoidOptions::default()
    };
    let sliced = fit_ellipsoid(&samples, &options).expect("fits");
    assert_eq!(streamed.model, EllipsoidModel::Full);
    assert_eq!(streamed.calibration, sliced.calibration);
    assert!(!sliced.refined && !streamed.refined);
    // The first-order residual figures from the power sums are close to the exact ones.
    let relative =
        (streamed.residual_rms_ut - sliced.residual_rms_ut).abs() / sliced.residual_rms_ut;
    assert!(
        relative < 0.02,
        "{} vs {}",
        streamed.residual_rms_ut,
        sliced.residual_rms_ut
    );
    assert!(
        (streamed.field_spread_pct - sliced.field_spread_pct).abs()
            < 0.02 * sliced.field_spread_pct
    );
    assert!((sliced.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
    // And on circle-only data the streaming solve falls back too.
    let (truth, mut rng) = random_truth(71, 65.0);
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(&mags(&circle_only(&truth, 3000, 10.0, &mut rng)));
    let streamed = accumulator
        .solve(EllipsoidModel::Auto, None)
        .expect("solves");
    assert_eq!(streamed.model, EllipsoidModel::Band);
    assert!(streamed.fallback.is_some());
}

// serde_json is a native-only dependency.
#[cfg(not(target_arch = "wasm32"))]
#[test]
fn the_fit_serialises_with_units_in_its_names() {
    let (truth, mut rng) = random_truth(80, 60.0);
    let samples = mags(&full_sphere(&truth, 500, &mut rng));
    let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
    let json = serde_json::to_value(&fit).expect("serialisable");
    for key in [
        "calibration",
        "model",
        "residual_rms_ut",
        "field_spread_pct",
        "fallback",
        "observability",
    ] {
        assert!(json.get(key).is_some(), "{key} in {json}");
    }
    assert!(json["observability"]["tilt_span_deg"].is_number());
    assert_eq!(json["model"], "Full");
}

/// One row of the band sweep: a model fitted to bands of one tilt over many random
/// distortions.
#[derive(Debug, Clone, Copy)]
struct SweepRow {
    max_tilt_deg: f64,
    n_samples: usize,
    model: EllipsoidModel,
    mean_span_deg: f64,
    mean_heading_deg: f64,
    worst_heading_deg: f64,
    worst_ut: f64,
    worst_horizontal_ut: f64,
    n_refused: usize,
}

/// Each model fitted to `n_seeds` random distortions (inclination 65°) sampled on bands
/// of roll and pitch within ±`max_tilt_deg` (a full sphere at 90°).
fn sweep(cases: &[(f64, usize)], n_seeds: u64) -> Vec<SweepRow> {
    let mut rows = Vec::new();
    for &(max_tilt_deg, n_samples) in cases {
        for model in [
            EllipsoidModel::Full,
            EllipsoidModel::Band,
            EllipsoidModel::Sphere,
        ] {
            let mut row = SweepRow {
                max_tilt_deg,
                n_samples,
                model,
                mean_span_deg: 0.0,
                mean_heading_deg: 0.0,
                worst_heading_deg: 0.0,
                worst_ut: 0.0,
                worst_horizontal_ut: 0.0,
                n_refused: 0,
            };
            for seed in 0..n_seeds {
                let (truth, mut rng) = random_truth(1000 + seed, 65.0);
                let samples = if max_tilt_deg >= 90.0 {
                    full_sphere(&truth, n_samples, &mut rng)
                } else {
                    circle_only(&truth, n_samples, max_tilt_deg, &mut rng)
                };
                let mag_ut = mags(&samples);
                let mut accumulator = EllipsoidAccumulator::new();
                accumulator.add_all(&mag_ut);
                let Ok(geometry) = accumulator.geometry() else {
                    row.n_refused += 1;
                    continue;
                };
                row.mean_span_deg += geometry.tilt_span_deg / n_seeds as f64;
                let calibration = forced_fit(&mag_ut, model);
                let error_ut = calibration.hard_iron_ut - truth.hard_iron_ut;
                let heading_deg = heading_rms_deg(&samples, &calibration);
                row.worst_ut = row.worst_ut.max(error_ut.norm());
                row.worst_horizontal_ut = row.worst_horizontal_ut.max(error_ut.xy().norm());
                row.worst_heading_deg = row.worst_heading_deg.max(heading_deg);
                row.mean_heading_deg += heading_deg / n_seeds as f64;
            }
            rows.push(row);
        }
    }
    rows
}

/// The mean heading RMS of the full and the band model on each tilt of `rows`.
fn full_and_band(rows: &[SweepRow]) -> Vec<(f64, f64, f64)> {
    rows.iter()
        .filter(|row| row.model == EllipsoidModel::Full)
        .filter_map(|full| {
            let band = rows.iter().find(|row| {
                row.model == EllipsoidModel::Band
                    && row.max_tilt_deg == full.max_tilt_deg
                    && row.n_samples == full.n_samples
            })?;
            Some((
                full.mean_span_deg,
                full.mean_heading_deg,
                band.mean_heading_deg,
            ))
        })
        .collect()
}

/// What [`MIN_FULL_TILT_SPAN_DEG`] rests on, on fewer distortions than the table: on a
/// band of ±10° (a span near 10°) the band model's heading is better than the full
/// model's, and on a full sphere the full model's is.
#[test]
fn the_band_model_wins_on_a_narrow_band_and_the_full_model_on_a_sphere() {
    let rows = sweep(&[(10.0, 3000), (90.0, 3000)], 8);
    let pairs = full_and_band(&rows);
    let (narrow, sphere) = (pairs[0], pairs[1]);
    assert!(narrow.0 < MIN_FULL_TILT_SPAN_DEG, "{narrow:?}");
    assert!(
        narrow.2 < narrow.1,
        "band {narrow:?}: band model not better"
    );
    assert!(sphere.0 > MIN_FULL_TILT_SPAN_DEG, "{sphere:?}");
    assert!(
        sphere.1 < sphere.2,
        "sphere {sphere:?}: full model not better"
    );
    assert!(rows.iter().all(|row| row.n_refused == 0), "{rows:?}");
}

/// The table behind [`MIN_FULL_TILT_SPAN_DEG`] and [`MIN_TILT_SPAN_DEG`]: heading
/// and hard-iron errors of each model on bands of growing tilt, over 30 distortions.
/// Slow; run with `cargo test --lib band_sweep -- --ignored --nocapture` (it prints the
/// table, and fails where the thresholds' claims do not hold 3° from them).
#[test]
#[ignore]
fn band_sweep() {
    let cases = [
        (3.0, 3000),
        (5.0, 3000),
        (10.0, 3000),
        (15.0, 3000),
        (20.0, 3000),
        (25.0, 3000),
        (30.0, 3000),
        (35.0, 3000),
        (45.0, 3000),
        (90.0, 3000),
        (10.0, 300),
        (10.0, 20_000),
    ];
    let rows = sweep(&cases, 30);
    for row in &rows {
        println!(
            "tilt ±{:>2} (span {:4.1}°) N {:>5} {:?}: hard iron worst {:6.2} µT ({:5.2} horizontal), \
             heading RMS mean {:5.2}° worst {:5.2}°, {} refused",
            row.max_tilt_deg,
            row.mean_span_deg,
            row.n_samples,
            row.model,
            row.worst_ut,
            row.worst_horizontal_ut,
            row.mean_heading_deg,
            row.worst_heading_deg,
            row.n_refused
        );
    }
    // A band of ±3° is refused (below MIN_TILT_SPAN_DEG); just above it the models are
    // alike (about 3.5°); from a span near 10° the band model is better below the
    // threshold and the full model above it.
    assert!(rows
        .iter()
        .filter(|row| row.max_tilt_deg <= 3.0)
        .all(|row| row.n_refused == 30));
    for (span_deg, full_deg, band_deg) in full_and_band(&rows) {
        if span_deg == 0.0 {
            continue;
        }
        if span_deg < 8.0 {
            assert!(
                (band_deg - full_deg).abs() < 1.0,
                "span {span_deg:.1}°: {full_deg:.2}° / {band_deg:.2}°"
            );
        } else if span_deg < MIN_FULL_TILT_SPAN_DEG - 3.0 {
            assert!(
                band_deg < full_deg,
                "span {span_deg:.1}°: full {full_deg:.2}° beats band {band_deg:.2}°"
            );
        } else if span_deg > MIN_FULL_TILT_SPAN_DEG + 3.0 {
            assert!(
                full_deg < band_deg,
                "span {span_deg:.1}°: band {band_deg:.2}° beats full {full_deg:.2}°"
            );
        }
    }
}
