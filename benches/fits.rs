//! Fit time on real logs: `fit::ellipse::fit_plane` (the "ellipse" method, tilt-aware
//! level-plane fit) and `fit::ellipsoid::fit_inertial` (the "ellipsoid" method) on 10⁴
//! samples of each recording in `../shared/data` that the tool reads, of the simulator's
//! demo walk (`WalkConfig::demo(1, 240 s, 50 Hz)`, the committed demo) and of the
//! independent generator's circle walk (`tests/physics`, seed 1).
//!
//! The samples are made as `analysis::calibration::calibrate` makes them: the import,
//! `analysis::levelled::tilted_samples` (tilt from the accelerometer and gyroscope,
//! 1 s), then evenly thinned or repeated to exactly 10⁴ (sample `i·n/10⁴` of `n`), with
//! the priors `calibrate` gives the fits (the WMM's inclination and intensity at the
//! log's place and date, when it has them; the tilt for the 3D fit only when it came
//! from an accelerometer). A recording that is absent is skipped with a message.
//!
//!   cargo bench --bench fits --profile bench-import
//!
//! (`FITS_CASE=tyrex` keeps only the cases whose name contains `tyrex`.)
//!
//! fits each case once, prints the time and the outcome and writes the outcomes to
//! `target/bench-results/fits.json` (the hard iron, the soft iron and the residual in full
//! precision, to compare runs) and each case's samples to
//! `target/bench-data/fits_<case>.f64` (for the peers, `bench/fits_peer.py`), then measures; criterion's figures go to
//! `target/criterion/fits/`, and `bench/fits.sh` (which `bench/run` calls) turns both into
//! docs/BENCHMARKS.md's "Fits on real logs". Under `cargo test` (criterion's test mode) it stops after the outcomes.

#[cfg(not(target_arch = "wasm32"))]
#[path = "../tests/common/mod.rs"]
mod common;

#[cfg(not(target_arch = "wasm32"))]
#[path = "../tests/physics/mod.rs"]
mod physics;

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::hint::black_box;
    use std::path::{Path, PathBuf};
    use std::time::{Duration, Instant};

    use compass_pdr::analysis::calibration::{
        expected_field_of, inertial_options, plane_options, CalibrationOptions,
    };
    use compass_pdr::analysis::levelled::{tilted_samples, Levelling};
    use compass_pdr::attitude::tilt::Tilt;
    use compass_pdr::fit::ellipse::{fit_plane, PlaneOptions};
    use compass_pdr::fit::ellipsoid::{fit_inertial, InertialOptions};
    use compass_pdr::io::canonical_csv;
    use compass_pdr::io::import::import_files;
    use compass_pdr::sim::walk::{simulate, WalkConfig};
    use criterion::{BenchmarkId, Criterion, SamplingMode};
    use nalgebra::{Matrix3, Vector3};

    use super::{common, physics};

    /// The samples each fit sees.
    const N_SAMPLES: usize = 10_000;

    /// One log's samples and the options `calibrate` would give the fits.
    struct Case {
        name: String,
        /// Levelled samples in the log, before thinning or repeating.
        n_source: usize,
        mag_ut: Vec<Vector3<f64>>,
        tilt: Vec<Tilt>,
        tilt_from_accelerometer: bool,
        plane_options: PlaneOptions,
        inertial_options: InertialOptions,
    }

    impl Case {
        /// The ellipse fit's outcome as JSON (full precision, to compare runs) and in words.
        fn fit_plane(&self) -> (String, String) {
            match fit_plane(&self.mag_ut, &self.tilt, &self.plane_options) {
                Ok(fit) => outcome(
                    &format!("{:?}", fit.soft_iron_model),
                    &fit.hard_iron_ut,
                    &fit.soft_iron,
                    fit.residual_rms_ut,
                ),
                Err(error) => refused(&error.to_string()),
            }
        }

        /// The ellipsoid fit's outcome, as [`Case::fit_plane`].
        fn fit_inertial(&self) -> (String, String) {
            let tilt = self.tilt_from_accelerometer.then_some(self.tilt.as_slice());
            match fit_inertial(&self.mag_ut, tilt, &self.inertial_options) {
                Ok(fit) => outcome(
                    &format!("{:?}", fit.model),
                    &fit.calibration.hard_iron_ut,
                    &fit.calibration.soft_iron,
                    fit.residual_rms_ut,
                ),
                Err(error) => refused(&error.to_string()),
            }
        }
    }

    fn outcome(
        model: &str,
        hard_iron_ut: &Vector3<f64>,
        soft_iron: &Matrix3<f64>,
        residual_rms_ut: f64,
    ) -> (String, String) {
        let list = |values: &[f64]| {
            values
                .iter()
                .map(|value| format!("{value:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        (
            format!(
                "{{ \"model\": {}, \"hard_iron_ut\": [{}], \"soft_iron_rows\": [{}], \"residual_rms_ut\": {residual_rms_ut:?} }}",
                json_string(model),
                list(hard_iron_ut.as_slice()),
                list(soft_iron.transpose().as_slice()),
            ),
            format!(
                "{model}, hard iron {}, residual {residual_rms_ut:.3} µT",
                vector(hard_iron_ut)
            ),
        )
    }

    fn refused(error: &str) -> (String, String) {
        (
            format!("{{ \"refused\": {} }}", json_string(error)),
            format!("refused: {error}"),
        )
    }

    fn vector(v: &Vector3<f64>) -> String {
        format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z)
    }

    /// Whether criterion measures (`cargo bench`) rather than tests (`cargo test`); the
    /// same rule criterion applies to its own arguments.
    fn is_measuring() -> bool {
        let args: Vec<String> = std::env::args().collect();
        args.iter().any(|arg| arg == "--bench") && !args.iter().any(|arg| arg == "--test")
    }

    /// The case of one imported recording, or why there is none.
    fn case_of(name: String, files: &[(String, Vec<u8>)]) -> Result<Case, String> {
        let slices: Vec<(&str, &[u8])> = files
            .iter()
            .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
            .collect();
        let report = import_files(&slices).map_err(|error| error.to_string())?;
        let options = CalibrationOptions::default();
        let samples = tilted_samples(
            &report.file_name,
            &report.recording,
            report.header.as_ref(),
            &report.diagnostics,
            report.n_data_lines,
            &compass_pdr::attitude::down::gravity_of(&report.recording, options.gravity_window_s),
        )
        .map_err(|error| error.to_string())?;
        let expected = expected_field_of(&report.recording, options.position_deg, &mut Vec::new());
        let n_source = samples.mag_ut.len();
        let pick = |idx: usize| idx * n_source / N_SAMPLES;
        Ok(Case {
            name,
            n_source,
            mag_ut: (0..N_SAMPLES)
                .map(|idx| samples.mag_ut[pick(idx)])
                .collect(),
            tilt: (0..N_SAMPLES).map(|idx| samples.tilt[pick(idx)]).collect(),
            tilt_from_accelerometer: matches!(samples.levelling, Levelling::Accelerometer { .. }),
            plane_options: plane_options(expected.as_ref()),
            inertial_options: inertial_options(expected.as_ref(), report.mag_frame.as_ref()),
        })
    }

    /// The real recordings: a name and the files of each, as a user drops them.
    fn real_recordings(data: &Path) -> Vec<(String, Vec<PathBuf>)> {
        let hmc = |run: &str| -> Vec<PathBuf> {
            ["hmc5883l_compass.csv", "mpu6050_accelerometer.csv"]
                .iter()
                .map(|file| data.join("hmc5883l-sphere").join(run).join(file))
                .collect()
        };
        let all_in = |dir: &str, ext: &str| -> Vec<PathBuf> {
            let dir = data.join(dir);
            if dir.is_dir() {
                common::files_in(&dir, ext)
            } else {
                vec![dir]
            }
        };
        let mut recordings: Vec<(&str, Vec<PathBuf>)> = vec![
            (
                "vehicle-pixel6a",
                vec![data.join("vehicle-pixel6a/2023-08-09_12-47-42.csv")],
            ),
            (
                "phyphox-hallway-loop",
                all_in("phyphox-hallway-loop", "csv"),
            ),
            ("hmc5883l-full-sphere", hmc("full-sphere")),
            (
                "hmc5883l-rotate-ccw-around-z",
                hmc("rotate-ccw-around-z-pointing-up"),
            ),
            ("msft-indoor-F1", all_in("msft-indoor-2020/site1/F1", "txt")),
            ("msft-indoor-F4", all_in("msft-indoor-2020/site1/F4", "txt")),
            (
                "qmc5883l-filtered",
                vec![data.join("qmc5883l-calibration/filtered_raw_data.csv")],
            ),
            (
                "qmc5883l-noisy",
                vec![data.join("qmc5883l-calibration/noisy_raw_data.csv")],
            ),
            (
                "sensorlogger-walk-ethz",
                all_in("sensorlogger-walk-ethz", "csv"),
            ),
        ];
        let mut recordings: Vec<(String, Vec<PathBuf>)> = recordings
            .drain(..)
            .map(|(name, paths)| (name.to_string(), paths))
            .collect();
        // The TYREX trials: one folder of headerless per-sensor files each.
        for (name, paths) in common::tyrex_trials(data) {
            recordings.push((format!("tyrex-{name}"), paths));
        }
        recordings
    }

    fn cases() -> Vec<Case> {
        let mut cases = Vec::new();
        let mut add =
            |name: String, files: Vec<(String, Vec<u8>)>| match case_of(name.clone(), &files) {
                Ok(case) => cases.push(case),
                Err(error) => eprintln!("skipped {name}: {error}"),
            };
        if let Some(data) = common::shared_data() {
            for (name, paths) in real_recordings(&data) {
                if let Some(missing) = paths.iter().find(|path| !path.is_file()) {
                    eprintln!("skipped {name}: {} not found", missing.display());
                    continue;
                }
                add(name, common::read_named(&paths));
            }
        }
        let demo = canonical_csv::write(&simulate(&WalkConfig::demo(1, 240.0, 50.0)));
        add(
            "simulator-demo-walk".to_string(),
            vec![("demo-walk.csv".to_string(), demo.into_bytes())],
        );
        let circle_walk = physics::circle_walk(1);
        add(
            "independent-circle_walk-1".to_string(),
            vec![("circle_walk.csv".to_string(), circle_walk.csv.into_bytes())],
        );
        cases
    }

    fn json_string(text: &str) -> String {
        format!("{text:?}")
    }

    pub fn main() {
        let measuring = is_measuring();
        let mut cases = cases();
        if let Ok(only) = std::env::var("FITS_CASE") {
            cases.retain(|c| c.name.contains(&only));
        }
        let mut entries = Vec::new();
        for case in &cases {
            let mut outcomes = Vec::new();
            for (fit, run) in [
                ("ellipse", Case::fit_plane as fn(&Case) -> (String, String)),
                ("ellipsoid", Case::fit_inertial),
            ] {
                let started = Instant::now();
                let (json, words) = run(case);
                let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
                eprintln!(
                    "{} ({} samples → {N_SAMPLES}), {fit}: {elapsed_ms:.1} ms once; {words}",
                    case.name, case.n_source,
                );
                outcomes.push(format!("\"{fit}\": {json}"));
            }
            entries.push(format!(
                "    {}: {{ \"n_source\": {}, \"tilt_from_accelerometer\": {}, {} }}",
                json_string(&case.name),
                case.n_source,
                case.tilt_from_accelerometer,
                outcomes.join(", ")
            ));
        }
        // Each case's samples for the peers (bench/fits_peer.py): little-endian f64
        // x, y, z triples, in the log's unit.
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
        std::fs::create_dir_all(&data).expect("target/bench-data can be made");
        for case in &cases {
            let bytes: Vec<u8> = case
                .mag_ut
                .iter()
                .flat_map(|m| m.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>())
                .collect();
            std::fs::write(data.join(format!("fits_{}.f64", case.name)), bytes)
                .expect("the samples can be written");
        }
        let results = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-results");
        std::fs::create_dir_all(&results).expect("target/bench-results can be made");
        std::fs::write(
            results.join("fits.json"),
            format!(
                "{{\n  \"n_samples\": {N_SAMPLES},\n  \"cases\": {{\n{}\n  }}\n}}\n",
                entries.join(",\n")
            ),
        )
        .expect("fits.json can be written");
        if !measuring {
            return;
        }

        let mut criterion = Criterion::default().configure_from_args();
        {
            let mut group = criterion.benchmark_group("fits");
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(300))
                .measurement_time(Duration::from_secs(1));
            for case in &cases {
                group.bench_with_input(
                    BenchmarkId::new("ellipse", &case.name),
                    case,
                    |bencher, case| {
                        bencher.iter(|| {
                            fit_plane(
                                black_box(&case.mag_ut),
                                black_box(&case.tilt),
                                &case.plane_options,
                            )
                        });
                    },
                );
                group.bench_with_input(
                    BenchmarkId::new("ellipsoid", &case.name),
                    case,
                    |bencher, case| {
                        let tilt = case.tilt_from_accelerometer.then_some(case.tilt.as_slice());
                        bencher.iter(|| {
                            fit_inertial(black_box(&case.mag_ut), tilt, &case.inertial_options)
                        });
                    },
                );
            }
            group.finish();
        }
        criterion.final_summary();
    }
}

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    native::main();
}

#[cfg(target_arch = "wasm32")]
fn main() {}
