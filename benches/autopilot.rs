//! Autopilot log import time: `io::import::import` (the one door, detection included)
//! on the DataFlash and ULog logs in `../shared/data`, and on log171 repeated ten times
//! (a 30 MB log), each read `AUTOPILOT_RUNS` times (default 15) after one warm-up; the
//! median and the samples read are printed as one JSON object per file, for
//! `bench/autopilot.sh`, which runs pymavlink and pyulog on the same files.
//!
//!   cargo bench --bench autopilot --profile bench-import
//!
//! Under `cargo test` (no `--bench` argument) each file is read once.

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    use std::hint::black_box;
    use std::path::Path;
    use std::time::Instant;

    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if !data.is_dir() {
        eprintln!("skipped: {} not found", data.display());
        return;
    }
    let benching = std::env::args().any(|arg| arg == "--bench");
    let runs: usize = if benching {
        std::env::var("AUTOPILOT_RUNS")
            .ok()
            .and_then(|runs| runs.parse().ok())
            .unwrap_or(15)
    } else {
        1
    };
    let mut inputs: Vec<(String, Vec<u8>)> = [
        "ardupilot-copter-log171/log171.bin",
        "ardupilot-text-log/nan.log",
        "px4-ulog/sample.ulg",
        "px4-ulog/sample_log_small.ulg",
    ]
    .iter()
    .filter_map(|name| Some((name.to_string(), std::fs::read(data.join(name)).ok()?)))
    .collect();
    if let Some((_, log171)) = inputs.first() {
        let repeated = log171.repeat(10);
        // Written for the peers, which read files.
        let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
        let _ = std::fs::create_dir_all(&out);
        let _ = std::fs::write(out.join("log171x10.bin"), &repeated);
        inputs.push(("log171.bin × 10".to_string(), repeated));
    }
    for (name, bytes) in &inputs {
        let file_name = name.rsplit('/').next().unwrap_or(name);
        let mut seconds = Vec::with_capacity(runs);
        let mut n_samples = 0;
        for run in 0..=runs {
            let start = Instant::now();
            let report = match compass_pdr::io::import::import(file_name, black_box(bytes)) {
                Ok(report) => report,
                Err(error) => {
                    eprintln!("{name}: {error}");
                    break;
                }
            };
            if run > 0 {
                seconds.push(start.elapsed().as_secs_f64());
            }
            let recording = &report.recording;
            n_samples = recording.mag_in_body_ut.len()
                + recording.acc_in_body_mps2.len()
                + recording.gnss.len()
                + recording.attitude.len();
        }
        seconds.sort_by(f64::total_cmp);
        let median_s = seconds.get(seconds.len() / 2).copied().unwrap_or(f64::NAN);
        println!(
            "{{\"file\": \"{name}\", \"bytes\": {}, \"runs\": {}, \"median_s\": {median_s:.6}, \"samples\": {n_samples}}}",
            bytes.len(),
            seconds.len()
        );
    }
}

#[cfg(target_arch = "wasm32")]
fn main() {}
