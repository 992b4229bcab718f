//! PDR speed: the `[E, N, l, a]` EKF's steps per second and the whole pipeline
//! on a simulated hour, beside filterpy and a numpy loop (`bench/pdr_peer.py`) and the
//! same work in WebAssembly (`bench/wasm/pdr.html`); `bench/pdr.sh` runs all of them and
//! prints a table.
//!
//! - **EKF**: 1,000,000 steps from SplitMix64 (seed 6): lengths uniform in 0.6-0.8 m,
//!   a true heading that turns at a rate redrawn every 200 steps (within ±0.02 rad a
//!   step, so it crosses north many times) and is measured with 3° of noise, wrapped to
//!   `[0, 2π)`. The filter starts at the origin with 1 m of position uncertainty and the
//!   first step's length and heading, `EkfNoise::default()`, and takes every step with
//!   `PdrEkf::step` (the measurement update of `l` and `a` with the wrapped heading
//!   innovation, then Eq. 13's prediction). The inputs are prepared before timing.
//! - **Pipeline**: a 1-hour walk at 100 Hz with GNSS from the crate's simulator (seed 6),
//!   as canonical CSV bytes in memory: `io::import::import` then
//!   `pipeline::dead_reckoning(&report, &PdrOptions::default())` (calibrations and heading models, steps,
//!   step model, EKF, metrics).
//!
//! `cargo bench --bench pdr --profile bench-import` writes, under `target/bench-data/`:
//! `pdr_steps.f64` (little-endian f64 pairs `length_m, heading_rad`; the peers read it),
//! `pdr_settings.json` (the filter's start and noise), `pdr_hour.csv` (the simulated hour,
//! for the wasm page; each rewritten only when its content changed) and `pdr_native.json`
//! (the filter's state after several step counts, for the peers to compare with, and the
//! pipeline's time per stage). Under `cargo test` (criterion's test mode) it checks the
//! filter on fewer steps and the pipeline on a 5-minute walk, once.

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::fs;
    use std::hint::black_box;
    use std::path::{Path, PathBuf};
    use std::time::{Duration, Instant};

    use compass_pdr::analysis::calibration::calibrate;
    use compass_pdr::analysis::headings::{compare, HeadingOptions};
    use compass_pdr::base::angle::wrap_to_2pi;
    use compass_pdr::base::rng::SplitMix64;
    use compass_pdr::io::canonical_csv;
    use compass_pdr::io::import::import;
    use compass_pdr::pdr::ekf::{EkfNoise, PdrEkf};
    use compass_pdr::pdr::fusion::{fuse, FixInput, StepInput};
    use compass_pdr::pdr::steps::detect_steps;
    use compass_pdr::pdr::PdrOptions;
    use compass_pdr::pipeline::dead_reckoning;
    use compass_pdr::sim::walk::{simulate, WalkConfig};
    use criterion::{Criterion, SamplingMode, Throughput};
    use serde_json::json;

    /// The seed of the simulated PDR walk.
    const SEED: u64 = 6;
    const N_STEPS: usize = 1_000_000;
    /// Step counts after which the native state is recorded, for the peers (which run
    /// fewer steps) to compare with.
    const CHECKPOINTS: [usize; 6] = [1_000, 10_000, 20_000, 50_000, 100_000, 1_000_000];
    const START_EN_M: [f64; 2] = [0.0, 0.0];
    const START_SIGMA_M: f64 = 1.0;
    const HOUR_S: f64 = 3600.0;
    const HOUR_NAME: &str = "pdr_hour.csv";
    /// Repetitions of each stage in the stage profile (the median is kept).
    const STAGE_RUNS: usize = 3;

    /// Whether criterion measures (`cargo bench`) rather than tests (`cargo test`); the
    /// same rule criterion applies to its own arguments.
    fn is_measuring() -> bool {
        let args: Vec<String> = std::env::args().collect();
        args.iter().any(|arg| arg == "--bench") && !args.iter().any(|arg| arg == "--test")
    }

    fn data_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data")
    }

    /// `n` steps as `[length_m, heading_rad]`.
    fn step_inputs(n: usize) -> Vec<[f64; 2]> {
        let mut rng = SplitMix64::new(SEED);
        let mut true_heading_rad = 0.3;
        let mut turn_rad_per_step = 0.0;
        let heading_noise_rad = 3f64.to_radians();
        (0..n)
            .map(|step_idx| {
                if step_idx % 200 == 0 {
                    turn_rad_per_step = rng.uniform_in(-0.02, 0.02);
                }
                true_heading_rad = wrap_to_2pi(true_heading_rad + turn_rad_per_step);
                let length_m = rng.uniform_in(0.6, 0.8);
                let heading_rad =
                    wrap_to_2pi(true_heading_rad + heading_noise_rad * rng.gaussian());
                [length_m, heading_rad]
            })
            .collect()
    }

    fn start_filter(inputs: &[[f64; 2]]) -> PdrEkf {
        PdrEkf::new(
            START_EN_M,
            START_SIGMA_M,
            inputs[0][0],
            inputs[0][1],
            EkfNoise::default(),
        )
    }

    /// The filter after every input: what is timed.
    fn run_filter(start: PdrEkf, inputs: &[[f64; 2]]) -> PdrEkf {
        let mut ekf = start;
        for &[length_m, heading_rad] in inputs {
            ekf.step(length_m, heading_rad, None);
        }
        ekf
    }

    /// This thread's CPU time (s) from `/proc/thread-self/schedstat` (Linux), which,
    /// unlike wall time, does not count the time other processes held the core.
    fn thread_cpu_s() -> Option<f64> {
        let text = fs::read_to_string("/proc/thread-self/schedstat").ok()?;
        let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
        Some(ns / 1e9)
    }

    /// Steps per second of wall time and of this thread's CPU time, each the median of
    /// `runs` runs over all `inputs`.
    fn filter_rates(start: PdrEkf, inputs: &[[f64; 2]], runs: usize) -> serde_json::Value {
        let (mut wall_s, mut cpu_s) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            let cpu_start = thread_cpu_s();
            let wall_start = Instant::now();
            black_box(run_filter(black_box(start), black_box(inputs)));
            wall_s.push(wall_start.elapsed().as_secs_f64());
            if let (Some(before), Some(after)) = (cpu_start, thread_cpu_s()) {
                cpu_s.push(after - before);
            }
        }
        let n = inputs.len() as f64;
        let cpu_rate = (cpu_s.len() == runs).then(|| n / median_s(cpu_s));
        let wall_rate = n / median_s(wall_s);
        eprintln!(
            "EKF, {} steps, median of {runs}: {:.2} M steps/s of wall time, {} of CPU time",
            inputs.len(),
            wall_rate / 1e6,
            cpu_rate.map_or("unknown".to_string(), |rate| format!(
                "{:.2} M steps/s",
                rate / 1e6
            ))
        );
        json!({ "runs": runs, "steps_per_wall_s": wall_rate, "steps_per_cpu_s": cpu_rate })
    }

    fn state_json(ekf: &PdrEkf) -> serde_json::Value {
        json!({ "x": ekf.x, "p": ekf.p })
    }

    /// The simulated walk: the PDR scenario (varied gait, the unified heading
    /// error, 3 m GNSS) for `duration_s` at 100 Hz, as canonical CSV.
    fn walk_csv(duration_s: f64) -> Vec<u8> {
        canonical_csv::write(&simulate(&WalkConfig::pdr_walk(SEED, duration_s, 100.0))).into_bytes()
    }

    /// Writes `bytes` to `name` under `target/bench-data/` unless the file already holds
    /// them (through a temporary name, renamed).
    fn write_if_changed(name: &str, bytes: &[u8]) -> std::io::Result<()> {
        let dir = data_dir();
        fs::create_dir_all(&dir)?;
        let path = dir.join(name);
        if fs::read(&path).is_ok_and(|old| old == bytes) {
            return Ok(());
        }
        let partial = dir.join(format!("{name}.partial"));
        fs::write(&partial, bytes)?;
        fs::rename(&partial, &path)?;
        eprintln!("wrote {} ({} bytes)", path.display(), bytes.len());
        Ok(())
    }

    fn median_s(mut times_s: Vec<f64>) -> f64 {
        times_s.sort_by(f64::total_cmp);
        let mid = times_s.len() / 2;
        if times_s.len() % 2 == 1 {
            times_s[mid]
        } else {
            0.5 * (times_s[mid - 1] + times_s[mid])
        }
    }

    /// Median wall time of `STAGE_RUNS` calls, and the last call's value.
    fn time_stage<T>(mut stage: impl FnMut() -> T) -> (f64, T) {
        let mut times_s = Vec::with_capacity(STAGE_RUNS);
        let mut value = None;
        for _ in 0..STAGE_RUNS {
            let start = Instant::now();
            let result = black_box(stage());
            times_s.push(start.elapsed().as_secs_f64());
            value = Some(result);
        }
        (median_s(times_s), value.expect("STAGE_RUNS is positive"))
    }

    /// Times the pipeline's stages one by one, as `pipeline::dead_reckoning` chains them
    /// (the calibration and the heading comparison once, then the dead reckoning, which
    /// fits the chosen model again on the GNSS course), and the whole of it; "other" is
    /// the whole minus the timed stages (the refit, step headings, local frame, step
    /// model training, metrics, copies).
    fn stage_profile(name: &str, bytes: &[u8]) -> serde_json::Value {
        let options = PdrOptions::default();
        let (import_s, report) =
            time_stage(|| import(name, bytes).expect("the simulated log imports"));
        let heading_options: HeadingOptions = options.heading_options.clone();
        let (calibrate_s, calibration) = time_stage(|| {
            calibrate(report.clone(), &heading_options.calibration)
                .expect("the simulated log calibrates")
        });
        let (compare_s, _) = time_stage(|| compare(&calibration, &heading_options));
        let (steps_s, detection) =
            time_stage(|| detect_steps(&report.recording.acc_in_body_mps2, &options.steps));
        let (run_s, analysis) = time_stage(|| {
            dead_reckoning(&report, &options).expect("the simulated log dead-reckons")
        });
        let inputs: Vec<StepInput> = analysis
            .steps
            .iter()
            .zip(&analysis.step_lengths_m)
            .zip(&analysis.step_headings_rad)
            .map(|((step, &length_m), &heading_rad)| StepInput {
                t_start_s: step.t_start_s,
                t_s: step.t_end_s,
                length_m,
                heading_rad,
                heading_sigma_rad: None,
            })
            .collect();
        let fixes: Vec<FixInput> = analysis.fixes.iter().map(|(fix, _)| *fix).collect();
        let start = analysis.track[0];
        let (ekf_s, _) = time_stage(|| {
            fuse(
                &inputs,
                &fixes,
                [start.east_m, start.north_m],
                start.position_sigma_m / std::f64::consts::SQRT_2,
                options.noise,
                &options.gnss,
            )
        });
        // The report clone the calibration takes (it owns the report).
        let (clone_s, _) = time_stage(|| report.clone());
        let other_s = run_s - calibrate_s - compare_s - steps_s - ekf_s - clone_s;
        let n_samples = report.recording.acc_in_body_mps2.t_s.len();
        eprintln!(
            "{name}: {} bytes, {n_samples} accelerometer samples, {} steps detected ({} in the analysis), {} fixes, {:.1} m",
            bytes.len(),
            detection.steps.len(),
            analysis.report.n_steps,
            fixes.len(),
            analysis.report.pdr_distance_m
        );
        eprintln!(
            "stages (median of {STAGE_RUNS}, s): import {import_s:.3}, calibrate {calibrate_s:.3}, compare {compare_s:.3}, steps {steps_s:.3}, ekf {ekf_s:.4}, other {other_s:.3}; dead_reckoning {run_s:.3}; import + run {:.3}",
            import_s + run_s
        );
        json!({
            "file": name,
            "bytes": bytes.len(),
            "n_samples": n_samples,
            "n_steps": analysis.report.n_steps,
            "n_fixes": fixes.len(),
            "distance_m": analysis.report.pdr_distance_m,
            "heading_key": analysis.report.heading_key,
            "runs": STAGE_RUNS,
            "stages_s": {
                "import": import_s,
                "calibrate": calibrate_s,
                "compare": compare_s,
                "steps": steps_s,
                "ekf": ekf_s,
                "report_clone": clone_s,
                "other": other_s,
            },
            "run_s": run_s,
            "import_and_run_s": import_s + run_s,
        })
    }

    pub fn main() {
        let measuring = is_measuring();
        let (n_steps, walk_s) = if measuring {
            (N_STEPS, HOUR_S)
        } else {
            (20_000, 300.0)
        };
        let inputs = step_inputs(n_steps);
        let start = start_filter(&inputs);
        let mut checkpoints = serde_json::Map::new();
        for n in CHECKPOINTS.into_iter().filter(|&n| n <= n_steps) {
            let ekf = run_filter(start, &inputs[..n]);
            assert!(
                ekf.x.iter().all(|value| value.is_finite()),
                "{n} steps: {:?}",
                ekf.x
            );
            checkpoints.insert(n.to_string(), state_json(&ekf));
        }
        let rates = filter_rates(start, &inputs, 5);
        let bytes = walk_csv(walk_s);
        let profile = stage_profile(HOUR_NAME, &bytes);
        if measuring {
            let flat: Vec<u8> = inputs
                .iter()
                .flatten()
                .flat_map(|value| value.to_le_bytes())
                .collect();
            write_if_changed("pdr_steps.f64", &flat).expect("pdr_steps.f64 can be written");
            write_if_changed(HOUR_NAME, &bytes).expect("pdr_hour.csv can be written");
            let noise = EkfNoise::default();
            let settings = json!({
                "seed": SEED,
                "n_steps": n_steps,
                "start_en_m": START_EN_M,
                "start_sigma_m": START_SIGMA_M,
                "noise": noise,
                "checkpoints": CHECKPOINTS,
                "hour_file": HOUR_NAME,
                "hour_duration_s": walk_s,
                "hour_rate_hz": 100.0,
            });
            let native =
                json!({ "checkpoints": checkpoints, "ekf_rates": rates, "pipeline": profile });
            let pretty = |value: &serde_json::Value| {
                serde_json::to_string_pretty(value).expect("JSON of numbers") + "\n"
            };
            fs::write(data_dir().join("pdr_settings.json"), pretty(&settings))
                .expect("pdr_settings.json can be written");
            fs::write(data_dir().join("pdr_native.json"), pretty(&native))
                .expect("pdr_native.json can be written");
        }

        let mut criterion = Criterion::default().configure_from_args();
        {
            let mut group = criterion.benchmark_group("pdr");
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(3))
                .throughput(Throughput::Elements(n_steps as u64));
            group.bench_function(format!("ekf/{n_steps}"), |bencher| {
                bencher.iter(|| run_filter(black_box(start), black_box(&inputs)).x);
            });
            group.finish();
        }
        {
            let mut group = criterion.benchmark_group("pdr");
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(10));
            let options = PdrOptions::default();
            group.bench_function("pipeline/hour_100hz", |bencher| {
                bencher.iter(|| {
                    let report = import(HOUR_NAME, black_box(&bytes)).expect("imports");
                    dead_reckoning(&report, &options)
                        .expect("dead-reckons")
                        .report
                        .n_steps
                });
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
