//! MLP training time: `compass_pdr::deviation::network::train` with L-BFGS on 10,000 samples of
//! 5 inputs, 15 logistic hidden neurons, one linear output, beside scikit-learn's
//! `MLPRegressor(solver="lbfgs")` (`bench/mlp_peer.py`) and the same training in
//! WebAssembly (`bench/wasm/mlp.html`); `bench/mlp.sh` runs all three and prints a table.
//!
//! The data imitate the heading correction of Noureldin et al. (2007): inputs raw
//! compass heading (degrees), |H| (µT), gyro heading (degrees), dip (degrees) and
//! temperature (°C); the target is the compass deviation (degrees): Fourier terms of the
//! heading, a temperature term, a heading-temperature cross term and 0.3° noise. 12,500
//! samples from SplitMix64 (seed 5): the first 10,000 train, the last 2,500 are the test
//! set.
//!
//! `cargo bench --bench mlp --profile bench-import` writes the samples as little-endian
//! f64 rows `heading, |H|, gyro heading, dip, temperature, deviation` to
//! `target/bench-data/mlp_samples.f64` (rewritten when the size is wrong), the settings to
//! `target/bench-data/mlp_settings.json` (the peers read both) and one native training's
//! report with its test MSE to `target/bench-data/mlp_native.json`. Under `cargo test`
//! (criterion's test mode) it trains on a smaller set once and checks the test MSE.

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::fs;
    use std::hint::black_box;
    use std::io::Write as _;
    use std::path::{Path, PathBuf};
    use std::time::{Duration, Instant};

    use compass_pdr::base::rng::SplitMix64;
    use compass_pdr::deviation::network::{train, Dataset, TrainOptions};
    use criterion::{Criterion, SamplingMode};

    const N_INPUTS: usize = 5;
    const N_TRAIN: usize = 10_000;
    const N_TEST: usize = 2_500;
    const DATA_SEED: u64 = 5;
    /// scikit-learn's default `max_iter`; both stop at it or at the same tolerances.
    const MAX_ITERATIONS: usize = 200;

    /// Whether criterion measures (`cargo bench`) rather than tests (`cargo test`); the
    /// same rule criterion applies to its own arguments.
    fn is_measuring() -> bool {
        let args: Vec<String> = std::env::args().collect();
        args.iter().any(|arg| arg == "--bench") && !args.iter().any(|arg| arg == "--test")
    }

    fn data_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data")
    }

    /// The options of every run (native, wasm: `src/web/nn_bench.rs`; scikit-learn gets
    /// the same through `mlp_settings.json`): 15 logistic neurons, L-BFGS with 10 pairs,
    /// α = 10⁻⁴, gradient tolerance 10⁻⁴ (scikit-learn's `tol`), SciPy's `ftol`, no
    /// validation split (scikit-learn's `lbfgs` has no early stopping), seed 0.
    fn options() -> TrainOptions {
        TrainOptions {
            validation_fraction: 0.0,
            max_iterations: MAX_ITERATIONS,
            ..TrainOptions::default()
        }
    }

    /// Rows of `N_INPUTS` inputs and the target.
    fn samples(n: usize) -> Vec<[f64; N_INPUTS + 1]> {
        let mut rng = SplitMix64::new(DATA_SEED);
        (0..n)
            .map(|_| {
                let heading_deg = rng.uniform_in(0.0, 360.0);
                let temperature_c = rng.uniform_in(5.0, 35.0);
                let psi = heading_deg.to_radians();
                let warm = temperature_c - 20.0;
                let deviation_deg = 4.0 * psi.sin() + 2.5 * psi.cos() + 1.2 * (2.0 * psi).sin()
                    - 0.8 * (2.0 * psi).cos()
                    + 0.06 * warm
                    + 0.004 * warm * warm * psi.sin()
                    + 0.3 * rng.gaussian();
                let field_ut = 48.0 + 1.5 * (psi - 0.3).cos() + 0.02 * warm + 0.2 * rng.gaussian();
                let gyro_bias_deg = rng.uniform_in(-3.0, 3.0);
                let gyro_heading_deg =
                    (heading_deg + deviation_deg + gyro_bias_deg + rng.gaussian())
                        .rem_euclid(360.0);
                let dip_deg = 66.0 + 0.8 * (psi + 1.0).sin() + 0.3 * rng.gaussian();
                [
                    heading_deg,
                    field_ut,
                    gyro_heading_deg,
                    dip_deg,
                    temperature_c,
                    deviation_deg,
                ]
            })
            .collect()
    }

    fn dataset(rows: &[[f64; N_INPUTS + 1]]) -> Dataset {
        let inputs: Vec<f64> = rows
            .iter()
            .flat_map(|row| row[..N_INPUTS].to_vec())
            .collect();
        let targets: Vec<f64> = rows.iter().map(|row| row[N_INPUTS]).collect();
        Dataset::new(&inputs, N_INPUTS, &targets, 1).expect("the simulated samples are finite")
    }

    /// `mlp_samples.f64`, unless a file of the right size is there (the data are
    /// deterministic); written to a temporary name and renamed.
    fn write_samples(rows: &[[f64; N_INPUTS + 1]]) -> std::io::Result<()> {
        let dir = data_dir();
        fs::create_dir_all(&dir)?;
        let path = dir.join("mlp_samples.f64");
        let size = std::mem::size_of_val(rows) as u64;
        if fs::metadata(&path).is_ok_and(|metadata| metadata.len() == size) {
            return Ok(());
        }
        let partial = dir.join("mlp_samples.f64.partial");
        let mut out = std::io::BufWriter::new(fs::File::create(&partial)?);
        for value in rows.iter().flatten() {
            out.write_all(&value.to_le_bytes())?;
        }
        out.flush()?;
        drop(out);
        fs::rename(&partial, &path)?;
        eprintln!("wrote {} ({size} bytes)", path.display());
        Ok(())
    }

    /// Trains once on the first `n_train` rows, scores the rest, and returns the JSON of
    /// `mlp_native.json`.
    fn check(rows: &[[f64; N_INPUTS + 1]], n_train: usize) -> String {
        let (train_rows, test_rows) = rows.split_at(n_train);
        let (train_data, test_data) = (dataset(train_rows), dataset(test_rows));
        let start = Instant::now();
        let (model, report) = train(&train_data, &options()).expect("the benchmark data train");
        let seconds = start.elapsed().as_secs_f64();
        let test_mse = model.mean_squared_error(&test_data).expect("same widths");
        let variance = {
            let mean = test_data.targets().iter().sum::<f64>() / test_rows.len() as f64;
            test_data
                .targets()
                .iter()
                .map(|t| (t - mean) * (t - mean))
                .sum::<f64>()
                / test_rows.len() as f64
        };
        eprintln!(
            "{n_train} samples: {} iterations, {} evaluations, stop {:?}, train MSE {:.5}, test MSE {:.5} (target variance {:.3}), {:.1} ms once",
            report.iterations, report.evaluations, report.stop, report.train_mse, test_mse, variance, seconds * 1e3
        );
        assert!(
            test_mse < 0.05 * variance,
            "test MSE {test_mse} against variance {variance}"
        );
        format!(
            "{{\n  \"n_train\": {n_train},\n  \"n_test\": {},\n  \"iterations\": {},\n  \"evaluations\": {},\n  \"stop\": \"{:?}\",\n  \"train_mse\": {},\n  \"test_mse\": {},\n  \"once_s\": {}\n}}\n",
            test_rows.len(), report.iterations, report.evaluations, report.stop, report.train_mse, test_mse, seconds
        )
    }

    pub fn main() {
        let measuring = is_measuring();
        let (n_train, n_test) = if measuring {
            (N_TRAIN, N_TEST)
        } else {
            (2_000, 500)
        };
        let rows = samples(n_train + n_test);
        let native_json = check(&rows, n_train);
        if measuring {
            write_samples(&rows).expect("mlp_samples.f64 can be written under target/bench-data");
            let settings = format!(
                "{{\n  \"n_inputs\": {N_INPUTS},\n  \"n_train\": {n_train},\n  \"n_test\": {n_test},\n  \"hidden\": {},\n  \"activation\": \"logistic\",\n  \"alpha\": {},\n  \"max_iter\": {},\n  \"tol\": {},\n  \"random_state\": 0\n}}\n",
                options().n_hidden, options().l2_penalty, options().max_iterations, options().gradient_tolerance
            );
            fs::write(data_dir().join("mlp_settings.json"), settings)
                .expect("mlp_settings.json can be written");
            fs::write(data_dir().join("mlp_native.json"), native_json)
                .expect("mlp_native.json can be written");
        }

        let train_data = dataset(&rows[..n_train]);
        let options = options();
        let mut criterion = Criterion::default().configure_from_args();
        {
            let mut group = criterion.benchmark_group("mlp");
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(3));
            group.bench_function(format!("lbfgs/{n_train}"), |bencher| {
                bencher.iter(|| train(black_box(&train_data), &options));
            });
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
