//! The attitude filter's speed (`attitude::estimate_attitude`) on the same samples as
//! its peers in `bench/attitude_peers.py` (imufusion's Fusion AHRS, the `ahrs` package's
//! Madgwick): each TYREX trial in `../shared/data/tyrex-attitude` and `tyrex-attitude-more`, imported as a user
//! drops the folder, its field corrected by the phone's own hard-iron estimate (one
//! filter run; `attitude_of` runs one per candidate correction). A trial that is
//! absent is skipped with a message.
//!
//!   cargo bench --bench attitude --profile bench-import
//!
//! writes `target/bench-results/attitude_ours.json` (per trial: the samples the filter
//! read, gyroscope + accelerometer + magnetometer, and the median seconds of 20 runs)
//! for `bench/attitude.sh`; criterion's figures go to `target/criterion/attitude/`.
//! Under `cargo test` (criterion's test mode) it runs each trial once.

#[cfg(not(target_arch = "wasm32"))]
#[path = "../tests/common/mod.rs"]
mod common;

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::hint::black_box;
    use std::time::{Duration, Instant};

    use compass_pdr::attitude::{estimate_attitude, AttitudeOptions, Sensors};
    use criterion::{Criterion, SamplingMode, Throughput};

    use super::common;

    pub fn main() {
        let measuring = std::env::args().any(|arg| arg == "--bench");
        let Some(data) = common::shared_data() else {
            return;
        };
        let mut trials = common::tyrex_trials(&data);
        trials.extend(common::tyrex_trials_in(&data, "tyrex-attitude-more"));
        if trials.is_empty() {
            eprintln!("skipped: no TYREX trials under {}", data.display());
            return;
        }
        let mut criterion = Criterion::default().configure_from_args();
        let mut results = serde_json::Map::new();
        for (name, paths) in &trials {
            let recording = common::import_paths(paths).recording;
            let options = AttitudeOptions::for_gyro(recording.gyro_bias);
            let (field, reference) = common::field_by_device_estimate(&recording);
            let sensors = Sensors {
                acc_in_body_mps2: &recording.acc_in_body_mps2,
                gyro_in_body_radps: &recording.gyro_in_body_radps,
                field_in_body_ut: &field,
            };
            let n_samples =
                sensors.acc_in_body_mps2.len() + sensors.gyro_in_body_radps.len() + field.len();
            let run = || {
                estimate_attitude(black_box(sensors), reference, &options)
                    .expect("a gyroscope and an accelerometer")
            };
            // An attitude per gyroscope sample from the first one after a force and a field.
            let n_out = run().attitude.len();
            assert!(
                n_out + 100 >= sensors.gyro_in_body_radps.len() && n_out > 0,
                "{name}: {n_out}"
            );
            if !measuring {
                continue;
            }
            let mut seconds: Vec<f64> = (0..20)
                .map(|_| {
                    let start = Instant::now();
                    black_box(run());
                    start.elapsed().as_secs_f64()
                })
                .collect();
            seconds.sort_by(f64::total_cmp);
            let median_s = seconds[seconds.len() / 2];
            results.insert(
                name.clone(),
                serde_json::json!({ "samples": n_samples, "median_s": median_s, "samples_per_s": n_samples as f64 / median_s }),
            );
            let mut group = criterion.benchmark_group("attitude");
            group
                .sample_size(20)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(300))
                .measurement_time(Duration::from_secs(2))
                .throughput(Throughput::Elements(n_samples as u64));
            group.bench_function(name.as_str(), |bencher| bencher.iter(run));
            group.finish();
        }
        if measuring {
            let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-results");
            std::fs::create_dir_all(&dir).expect("target/bench-results can be made");
            let text = serde_json::to_string_pretty(&serde_json::Value::Object(results))
                .expect("JSON of numbers")
                + "\n";
            std::fs::write(dir.join("attitude_ours.json"), text)
                .expect("attitude_ours.json can be written");
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
