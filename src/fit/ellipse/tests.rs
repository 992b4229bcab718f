use super::*;
use crate::base::angle::heading_difference_rad;
use crate::base::rng::SplitMix64;
use crate::fit::minmax::MinMaxCalibration;
use crate::sim::field::{circle_only, FieldSample, FieldTruth};

fn tilt_of(sample: &FieldSample) -> Tilt {
    Tilt::new(sample.roll_rad, sample.pitch_rad)
}

fn split(samples: &[FieldSample]) -> (Vec<Vector3<f64>>, Vec<Tilt>) {
    (
        samples.iter().map(|sample| sample.mag_ut).collect(),
        samples.iter().map(tilt_of).collect(),
    )
}

/// The RMS heading error (degrees) of `heading_of` over `samples`.
fn heading_rms_deg(samples: &[FieldSample], heading_of: impl Fn(&FieldSample) -> f64) -> f64 {
    let sum_squares: f64 = samples
        .iter()
        .map(|sample| heading_difference_rad(heading_of(sample), sample.heading_rad).powi(2))
        .sum();
    (sum_squares / samples.len() as f64).sqrt().to_degrees()
}

/// A level turn of every heading, noise-free: the check set.
fn level_check_set(truth: &FieldTruth, rng: &mut SplitMix64) -> Vec<FieldSample> {
    let check_truth = FieldTruth {
        noise_ut: 0.0,
        ..*truth
    };
    circle_only(&check_truth, 360, 0.0, rng)
}

#[test]
fn level_heading_is_accurate_on_circle_only_data_over_many_seeds() {
    const N_SEEDS: u64 = 100;
    // (mean, worst) of the heading RMS over the seeds, in degrees.
    let (mut plane, mut tilted) = ((0.0, 0.0f64), (0.0, 0.0f64));
    let (mut minmax_figure, mut naive_conic_figure) = ((0.0, 0.0f64), (0.0, 0.0f64));
    for seed in 0..N_SEEDS {
        let mut rng = SplitMix64::new(seed);
        let truth = FieldTruth {
            inclination_deg: 65.0,
            noise_ut: 0.3,
            ..FieldTruth::random(&mut rng, 60.0, 0.1, 0.1)
        };
        let train = circle_only(&truth, 720, 10.0, &mut rng);
        let check = level_check_set(&truth, &mut rng);
        let (mag_ut, tilt) = split(&train);

        let fit = fit_plane(&mag_ut, &tilt, &PlaneOptions::default())
            .unwrap_or_else(|error| panic!("seed {seed}: {error}"));
        let plane_rms_deg = heading_rms_deg(&check, |sample| {
            fit.heading_rad(sample.mag_ut, Tilt::LEVEL, 0.0)
        });
        // The level-plane form agrees with the full model at level; the two differ
        // only by how far the data's vertical field is from the fitted one.
        let plane_form_rms_deg = heading_rms_deg(&check, |sample| {
            compass_heading::heading_rad(
                fit.plane.apply((sample.mag_ut - fit.hard_iron_ut).xy()),
                0.0,
            )
        });
        assert!(
            (plane_rms_deg - plane_form_rms_deg).abs() < 0.05,
            "seed {seed}: {plane_rms_deg} vs {plane_form_rms_deg}"
        );

        // The same data through the tilt-aware model at the tilts of a fresh
        // circle-only set (noise-free): the full model is meant for tilted use too.
        let tilted_check = circle_only(
            &FieldTruth {
                noise_ut: 0.0,
                ..truth
            },
            360,
            10.0,
            &mut rng,
        );
        let tilted_rms_deg = heading_rms_deg(&tilted_check, |sample| {
            fit.heading_rad(sample.mag_ut, tilt_of(sample), 0.0)
        });

        // For comparison: min/max and the general conic on the levelled raw field.
        let level_raw: Vec<Vector2<f64>> = train
            .iter()
            .map(|sample| tilt_of(sample).level(sample.mag_ut))
            .collect();
        let minmax = MinMaxCalibration::fit(&level_raw).expect("min/max fits a full turn");
        let minmax_rms_deg = heading_rms_deg(&check, |sample| {
            compass_heading::heading_rad(minmax.apply(sample.mag_ut.xy()), 0.0)
        });
        let naive_conic = fit_ellipse(&level_raw).expect("the conic fits a full turn");
        let naive_conic_rms_deg = heading_rms_deg(&check, |sample| {
            compass_heading::heading_rad(naive_conic.apply(sample.mag_ut.xy()), 0.0)
        });

        assert!(
            plane_rms_deg < 0.5,
            "seed {seed}: level heading RMS {plane_rms_deg:.3}° (min/max {minmax_rms_deg:.2}°), fit {fit:?}"
        );
        assert!(
            tilted_rms_deg < 0.5,
            "seed {seed}: tilted heading RMS {tilted_rms_deg:.3}°"
        );
        for (figure, value) in [
            (&mut plane, plane_rms_deg),
            (&mut tilted, tilted_rms_deg),
            (&mut minmax_figure, minmax_rms_deg),
            (&mut naive_conic_figure, naive_conic_rms_deg),
        ] {
            figure.0 += value / N_SEEDS as f64;
            figure.1 = figure.1.max(value);
        }
    }
    eprintln!(
        "circle-only training (±10° tilt, 65° inclination, 0.3 µT noise, {N_SEEDS} seeds), \
         heading RMS on a noise-free check set, mean / worst over the seeds:\n  \
         tilt-aware plane fit, level check:   {:.3}° / {:.3}°\n  \
         tilt-aware plane fit, ±10° check:    {:.3}° / {:.3}°\n  \
         min/max on the levelled raw field:   {:.2}° / {:.2}°\n  \
         conic on the levelled raw field:     {:.2}° / {:.2}°",
        plane.0,
        plane.1,
        tilted.0,
        tilted.1,
        minmax_figure.0,
        minmax_figure.1,
        naive_conic_figure.0,
        naive_conic_figure.1,
    );
}

/// A truth with a known distortion and the given noise.
fn truth_with(hard_iron_ut: Vector3<f64>, soft_iron: Matrix3<f64>, noise_ut: f64) -> FieldTruth {
    FieldTruth {
        hard_iron_ut,
        soft_iron,
        field_total_ut: 50.0,
        inclination_deg: 65.0,
        noise_ut,
    }
}

fn cross_axis_soft_iron() -> Matrix3<f64> {
    Matrix3::new(1.08, 0.07, -0.05, 0.07, 0.93, 0.06, -0.05, 0.06, 1.04)
}

#[test]
fn the_ellipse_fit_recovers_a_tilted_ellipse_exactly() {
    // A level turn through cross-axis soft iron traces an ellipse whose axes are
    // not along x and y; the symmetric transform undoes it up to the scale.
    let center_ut = Vector2::new(12.0, -31.0);
    let distortion = Matrix2::new(1.15, 0.12, 0.12, 0.88);
    let radius_ut = 21.0;
    let points: Vec<Vector2<f64>> = (0..200)
        .map(|idx| {
            let heading_rad = std::f64::consts::TAU * idx as f64 / 200.0;
            center_ut
                + distortion
                    * Vector2::new(
                        radius_ut * heading_rad.cos(),
                        -radius_ut * heading_rad.sin(),
                    )
        })
        .collect();
    let calibration = fit_ellipse(&points).expect("a full ellipse fits");
    let area_scale = distortion.determinant().sqrt();
    assert!((calibration.center_ut - center_ut).norm() < 1e-9);
    assert!((calibration.radius_ut - radius_ut * area_scale).abs() < 1e-9);
    assert!((calibration.transform.determinant() - 1.0).abs() < 1e-12);
    let expect = distortion.try_inverse().expect("invertible") * area_scale;
    assert!(
        (calibration.transform - expect).norm() < 1e-9,
        "{} vs {expect}",
        calibration.transform
    );
}

#[test]
fn noise_free_circle_only_data_recovers_the_truth() {
    let truth = truth_with(Vector3::new(25.0, -40.0, 55.0), cross_axis_soft_iron(), 0.0);
    let train = circle_only(&truth, 400, 10.0, &mut SplitMix64::new(7));
    let (mag_ut, tilt) = split(&train);
    let fit = fit_plane(&mag_ut, &tilt, &PlaneOptions::default()).expect("fits");
    assert!(fit.vertical_estimated);
    assert!(
        (fit.hard_iron_ut - truth.hard_iron_ut).norm() < 1e-6,
        "hard iron {}",
        fit.hard_iron_ut
    );
    // The correction is S⁻¹ up to the scale gauge.
    let product = fit.soft_iron * truth.soft_iron;
    let scale = product[(0, 0)];
    assert!(
        (product - Matrix3::identity() * scale).norm() < 1e-8,
        "{product}"
    );
    assert!((fit.inclination_deg - 65.0).abs() < 1e-6);
    assert!(fit.residual_rms_ut < 1e-6 && fit.horizontal_magnitude_std_ut < 1e-6);
    let worst_deg = train
        .iter()
        .map(|sample| {
            heading_difference_rad(
                fit.heading_rad(sample.mag_ut, tilt_of(sample), 0.0),
                sample.heading_rad,
            )
            .abs()
            .to_degrees()
        })
        .fold(0.0, f64::max);
    assert!(worst_deg < 1e-6, "worst tilted heading error {worst_deg}°");
    assert_eq!(fit.coverage.largest_gap_deg, 0.0);
}

#[test]
fn levelling_the_raw_field_leaks_the_vertical_hard_iron() {
    // No soft iron and no noise: only the vertical hard iron, rotated by the tilt.
    let truth = truth_with(Vector3::new(0.0, 0.0, 50.0), Matrix3::identity(), 0.0);
    let mut rng = SplitMix64::new(11);
    let train = circle_only(&truth, 720, 10.0, &mut rng);
    let check = level_check_set(&truth, &mut rng);
    let level_raw: Vec<Vector2<f64>> = train
        .iter()
        .map(|sample| tilt_of(sample).level(sample.mag_ut))
        .collect();
    let naive = fit_ellipse(&level_raw).expect("the naive conic fits");
    let naive_rms_deg = heading_rms_deg(&check, |sample| {
        compass_heading::heading_rad(naive.apply(sample.mag_ut.xy()), 0.0)
    });
    let (mag_ut, tilt) = split(&train);
    let fit = fit_plane(&mag_ut, &tilt, &PlaneOptions::default()).expect("fits");
    let fit_rms_deg = heading_rms_deg(&check, |sample| {
        fit.heading_rad(sample.mag_ut, Tilt::LEVEL, 0.0)
    });
    // On the tilted training samples themselves the leak is plain to see.
    let naive_worst_tilted_deg = train
        .iter()
        .map(|sample| {
            let level_ut = naive.apply(tilt_of(sample).level(sample.mag_ut));
            heading_difference_rad(
                compass_heading::heading_rad(level_ut, 0.0),
                sample.heading_rad,
            )
            .abs()
            .to_degrees()
        })
        .fold(0.0, f64::max);
    assert!(
        naive_worst_tilted_deg > 10.0,
        "naive conic, tilted: {naive_worst_tilted_deg}°"
    );
    assert!(naive_rms_deg > 0.5, "naive conic, level: {naive_rms_deg}°");
    assert!(fit_rms_deg < 1e-6, "tilt-aware {fit_rms_deg}°");
    assert!((fit.hard_iron_ut.z - 50.0).abs() < 1e-6);
}

#[test]
fn a_known_inclination_is_used() {
    let mut rng = SplitMix64::new(21);
    let truth = FieldTruth {
        inclination_deg: 65.0,
        ..FieldTruth::random(&mut rng, 60.0, 0.1, 0.1)
    };
    let train = circle_only(&truth, 720, 10.0, &mut rng);
    let check = level_check_set(&truth, &mut rng);
    let (mag_ut, tilt) = split(&train);
    let options = PlaneOptions {
        inclination_deg: Some(65.0),
        ..PlaneOptions::default()
    };
    let fit = fit_plane(&mag_ut, &tilt, &options).expect("fits");
    assert!((fit.inclination_deg - 65.0).abs() < 1e-9);
    let rms_deg = heading_rms_deg(&check, |sample| {
        fit.heading_rad(sample.mag_ut, Tilt::LEVEL, 0.0)
    });
    assert!(rms_deg < 0.5, "{rms_deg}°");
}

#[test]
fn level_only_data_holds_the_vertical_fixed_and_still_calibrates() {
    // A vehicle without an accelerometer: tilt is zero throughout, so the vertical
    // hard iron cannot be told from the vertical field, and need not be.
    let truth = truth_with(Vector3::new(-20.0, 35.0, 45.0), cross_axis_soft_iron(), 0.3);
    let mut rng = SplitMix64::new(5);
    let train = circle_only(&truth, 720, 0.0, &mut rng);
    let check = level_check_set(&truth, &mut rng);
    let (mag_ut, tilt) = split(&train);
    let fit = fit_plane(&mag_ut, &tilt, &PlaneOptions::default()).expect("fits");
    assert!(!fit.vertical_estimated);
    assert_eq!(fit.hard_iron_ut.z, 0.0);
    let rms_deg = heading_rms_deg(&check, |sample| {
        fit.heading_rad(sample.mag_ut, Tilt::LEVEL, 0.0)
    });
    assert!(rms_deg < 0.5, "{rms_deg}°");
}

#[test]
fn a_partial_turn_names_the_missing_headings() {
    let truth = truth_with(Vector3::new(10.0, -15.0, 30.0), cross_axis_soft_iron(), 0.3);
    let full_turn = circle_only(&truth, 720, 10.0, &mut SplitMix64::new(3));
    // Headings 0° to 200° only.
    let partial: Vec<FieldSample> = full_turn
        .into_iter()
        .filter(|sample| sample.heading_rad.to_degrees() < 200.0)
        .collect();
    let (mag_ut, tilt) = split(&partial);
    match fit_plane(&mag_ut, &tilt, &PlaneOptions::default()) {
        Err(PlaneError::NoTurn {
            gap_from_deg,
            gap_to_deg,
        }) => {
            assert!((190.0..=220.0).contains(&gap_from_deg), "{gap_from_deg}");
            assert!(!(20.0..=340.0).contains(&gap_to_deg), "{gap_to_deg}");
            let message = PlaneError::NoTurn {
                gap_from_deg,
                gap_to_deg,
            }
            .to_string();
            assert!(message.contains("turn that way"), "{message}");
        }
        other => panic!("expected NoTurn, got {other:?}"),
    }
}

#[test]
fn degenerate_inputs_are_errors_not_panics() {
    let truth = truth_with(Vector3::new(10.0, -15.0, 30.0), cross_axis_soft_iron(), 0.3);
    let train = circle_only(&truth, 100, 10.0, &mut SplitMix64::new(3));
    let (mag_ut, tilt) = split(&train);
    let options = PlaneOptions::default();
    assert!(matches!(
        fit_plane(&mag_ut[..10], &tilt[..10], &options),
        Err(PlaneError::TooFewSamples { n_samples: 10, .. })
    ));
    assert!(matches!(
        fit_plane(&[], &[], &options),
        Err(PlaneError::TooFewSamples { n_samples: 0, .. })
    ));
    assert!(matches!(
        fit_plane(&mag_ut, &tilt[..50], &options),
        Err(PlaneError::LengthMismatch {
            n_mag: 100,
            n_tilt: 50
        })
    ));
    let mut with_nan = mag_ut.clone();
    with_nan[17].y = f64::NAN;
    assert!(matches!(
        fit_plane(&with_nan, &tilt, &options),
        Err(PlaneError::NonFinite { sample_idx: 17 })
    ));
    let mut tilt_with_infinity = tilt.clone();
    tilt_with_infinity[4] = Tilt::new(tilt_with_infinity[4].roll_rad(), f64::INFINITY);
    assert!(matches!(
        fit_plane(&mag_ut, &tilt_with_infinity, &options),
        Err(PlaneError::NonFinite { sample_idx: 4 })
    ));
    for inclination_deg in [f64::NAN, 90.0, -120.0] {
        let options = PlaneOptions {
            inclination_deg: Some(inclination_deg),
            ..PlaneOptions::default()
        };
        assert!(matches!(
            fit_plane(&mag_ut, &tilt, &options),
            Err(PlaneError::InvalidInclination { .. })
        ));
    }
    // A device that never turns: the same reading at every tilt (level), or a
    // reading that follows no field through the tilts.
    let point = vec![Vector3::new(3.0, 4.0, 40.0); 100];
    assert!(matches!(
        fit_plane(&point, &[Tilt::LEVEL; 100], &options),
        Err(PlaneError::DegenerateConic { .. })
    ));
    assert!(matches!(
        fit_plane(&point, &tilt, &options),
        Err(PlaneError::PoorFit { .. } | PlaneError::DegenerateConic { .. })
    ));
    let line: Vec<Vector2<f64>> = (0..100).map(|idx| Vector2::new(idx as f64, 5.0)).collect();
    assert!(matches!(
        fit_ellipse(&line),
        Err(PlaneError::DegenerateConic { .. })
    ));
    let level_nan = vec![Vector2::new(f64::NAN, 1.0); 40];
    assert!(matches!(
        fit_ellipse(&level_nan),
        Err(PlaneError::NonFinite { sample_idx: 0 })
    ));
}

#[test]
fn arbitrary_input_never_panics() {
    let mut rng = SplitMix64::new(99);
    for trial in 0..60 {
        let n_samples = 30 + trial % 50;
        let magnitude = [1e-9, 1.0, 50.0, 1e6, 1e150][trial % 5];
        let mag_ut: Vec<Vector3<f64>> = (0..n_samples)
            .map(|_| Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * magnitude)
            .collect();
        let tilt: Vec<Tilt> = (0..n_samples)
            .map(|_| Tilt::new(rng.uniform_in(-3.0, 3.0), rng.uniform_in(-1.5, 1.5)))
            .collect();
        if let Ok(fit) = fit_plane(&mag_ut, &tilt, &PlaneOptions::default()) {
            assert!(fit.residual_rms_ut.is_finite());
        }
    }
}

#[test]
fn the_jacobian_matches_numerical_differentiation() {
    let truth = truth_with(Vector3::new(10.0, -15.0, 30.0), cross_axis_soft_iron(), 0.3);
    let train = circle_only(&truth, 40, 10.0, &mut SplitMix64::new(8));
    let (mag_ut, tilt) = split(&train);
    let levelling: Vec<Matrix3<f64>> = tilt.iter().map(levelling_rotation).collect();
    let problem = TiltAwareProblem {
        mag_ut: &mag_ut,
        levelling: &levelling,
        horizontal_field_ut: 21.0,
    };
    let full = [1.05, 0.97, 1.02, 0.03, -0.04, 0.05, 9.0, -14.0, 28.0, 44.0];
    let rows_at = |full: &[f64; N_PARAMS], sample_idx: usize| {
        problem.sample_rows(
            full,
            &soft_iron_of(full),
            &mag_ut[sample_idx],
            &levelling[sample_idx],
        )
    };
    let (mut worst, mut largest) = (0.0_f64, 0.0_f64);
    for sample_idx in 0..mag_ut.len() {
        let analytic = rows_at(&full, sample_idx);
        for param_idx in 0..N_PARAMS {
            let step = 1e-6 * full[param_idx].abs().max(1.0);
            let (mut plus, mut minus) = (full, full);
            plus[param_idx] += step;
            minus[param_idx] -= step;
            let (plus, minus) = (rows_at(&plus, sample_idx), rows_at(&minus, sample_idx));
            for residual_idx in 0..2 {
                let numerical = (plus[residual_idx].0 - minus[residual_idx].0) / (2.0 * step);
                let analytic = analytic[residual_idx].1[param_idx];
                worst = worst.max((numerical - analytic).abs());
                largest = largest.max(analytic.abs());
            }
        }
    }
    assert!(worst < 1e-6 * largest, "worst difference {worst}");
    // The normal equations are the sums over those rows.
    let normal = problem.normal_equations(&full, 1).expect("finite");
    let mut jtr = [0.0; N_PARAMS];
    for sample_idx in 0..mag_ut.len() {
        for (residual, gradient) in rows_at(&full, sample_idx) {
            for param_idx in 0..N_PARAMS {
                jtr[param_idx] += gradient[param_idx] * residual;
            }
        }
    }
    for (accumulated, summed) in normal.jtr.iter().zip(jtr) {
        assert!((accumulated - summed).abs() < 1e-9 * normal.jtr.norm());
    }
}
