//! Import throughput: `compass_pdr::io::import::import` on a ~100 MB canonical CSV
//! (the crate's own walk simulator) and a ~100 MB NMEA 0183 log (RMC, GGA, VTG and HDT
//! at 10 Hz), in MB/s. Run by `bench/run`, which records the figures in docs/BENCHMARKS.md
//! beside pandas, pynmea2 and the same import in WebAssembly.
//!
//! `cargo bench --bench import --profile bench-import` generates the inputs once under
//! `target/bench-data/` (reused while their recorded size matches) and writes
//! `decoded_sample_bytes.json` there, the in-memory size of one sample of each stream
//! kind, for the memory figure, and `native_cpu.json`, the CPU and wall time of three
//! imports of each input (the native importer may use several threads). (Plain `cargo bench` works too, but builds the library
//! twice into `target/release`: see the `bench-import` profile in Cargo.toml.)
//! Under `cargo test` (criterion's test mode) it runs each benchmark once on small
//! in-memory inputs and checks that they import without a diagnostic.

#[cfg(not(target_arch = "wasm32"))]
mod bench_data;

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::hint::black_box;
    use std::mem::size_of;
    use std::time::{Duration, Instant};

    use compass_pdr::io::import::{import, Inspection};
    use compass_pdr::io::recording::{Attitude, DeviceHeading, GnssFix};
    use criterion::{Criterion, SamplingMode, Throughput};
    use nalgebra::{Vector2, Vector3};

    use crate::bench_data::{self, data_dir, ensure_file, write_nmea, write_walk_csv};

    /// One benchmark input: the name it is imported under and its bytes.
    struct Input {
        bench_name: &'static str,
        file_name: &'static str,
        bytes: Vec<u8>,
    }

    /// Whether criterion measures (`cargo bench`) rather than tests (`cargo test`); the
    /// same rule criterion applies to its own arguments.
    fn is_measuring() -> bool {
        let args: Vec<String> = std::env::args().collect();
        args.iter().any(|arg| arg == "--bench") && !args.iter().any(|arg| arg == "--test")
    }

    fn full_size_inputs() -> Vec<Input> {
        let csv_path = ensure_file("walk.csv", |out| {
            write_walk_csv(bench_data::WALK_DURATION_S, out)
        })
        .expect("the canonical CSV can be written under target/bench-data");
        let nmea_path = ensure_file("track.nmea", |out| write_nmea(bench_data::NMEA_EPOCHS, out))
            .expect("the NMEA log can be written under target/bench-data");
        write_sample_sizes();
        vec![
            Input {
                bench_name: "canonical_csv",
                file_name: "walk.csv",
                bytes: std::fs::read(csv_path).expect("walk.csv is readable"),
            },
            Input {
                bench_name: "nmea",
                file_name: "track.nmea",
                bytes: std::fs::read(nmea_path).expect("track.nmea is readable"),
            },
        ]
    }

    fn small_inputs() -> Vec<Input> {
        let mut csv = Vec::new();
        write_walk_csv(60.0, &mut csv).expect("writing to memory cannot fail");
        let mut nmea = Vec::new();
        write_nmea(2_000, &mut nmea).expect("writing to memory cannot fail");
        vec![
            Input {
                bench_name: "canonical_csv",
                file_name: "walk.csv",
                bytes: csv,
            },
            Input {
                bench_name: "nmea",
                file_name: "track.nmea",
                bytes: nmea,
            },
        ]
    }

    /// The in-memory size of one sample (its time and its value) of each kind of stream,
    /// by the stream names `compass-pdr inspect --json` prints.
    fn write_sample_sizes() {
        let time = size_of::<f64>();
        let vector = time + size_of::<Vector3<f64>>();
        let scalar = time + size_of::<f64>();
        let position = time + size_of::<Vector2<f64>>();
        let json = format!(
            "{{\n  \"accelerometer\": {vector},\n  \"gyroscope\": {vector},\n  \
             \"magnetometer\": {vector},\n  \"magnetometer bias (device's own)\": {vector},\n  \
             \"temperature\": {scalar},\n  \"pressure\": {scalar},\n  \
             \"reference heading\": {scalar},\n  \"GNSS\": {},\n  \
             \"attitude (device's own)\": {},\n  \"heading (device's own)\": {},\n  \
             \"reference positions\": {position},\n  \
             \"reference positions (lat/lon)\": {position}\n}}\n",
            time + size_of::<GnssFix>(),
            time + size_of::<Attitude>(),
            time + size_of::<DeviceHeading>(),
        );
        std::fs::write(data_dir().join("decoded_sample_bytes.json"), json)
            .expect("decoded_sample_bytes.json can be written");
    }

    /// Imports once and says what was read, so that a broken input is seen before it
    /// is timed.
    fn check(input: &Input, require_clean: bool) {
        let report = import(input.file_name, &input.bytes)
            .unwrap_or_else(|error| panic!("{} does not import: {error}", input.file_name));
        let inspection = Inspection::of(&report);
        let streams: Vec<String> = inspection
            .streams
            .iter()
            .map(|stream| format!("{} {}", stream.stream, stream.n_samples))
            .collect();
        eprintln!(
            "{}: {} bytes, {} ({} data lines; {}), {} diagnostics",
            input.file_name,
            input.bytes.len(),
            inspection.format,
            inspection.n_data_lines,
            streams.join(", "),
            report.diagnostics.total()
        );
        if require_clean {
            assert!(
                report.diagnostics.is_empty(),
                "{}: {:?}",
                input.file_name,
                report.diagnostics.kept.first()
            );
        }
    }

    /// CPU seconds (user + system, all threads) this process has used, from
    /// `/proc/self/stat` in Linux's 100 Hz clock ticks; `None` where that is unreadable.
    fn process_cpu_s() -> Option<f64> {
        let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
        // Fields after the command name (which may hold spaces): state is field 3,
        // utime 14 and stime 15.
        let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
        let utime: f64 = fields.get(11)?.parse().ok()?;
        let stime: f64 = fields.get(12)?.parse().ok()?;
        Some((utime + stime) / 100.0)
    }

    /// CPU time over wall time of a few imports of each input (above 1 where the
    /// importer uses several threads), written to `native_cpu.json` for docs/BENCHMARKS.md.
    fn write_cpu_ratios(inputs: &[Input]) {
        const N_IMPORTS: usize = 3;
        let mut entries = Vec::new();
        for input in inputs {
            let (Some(cpu_start_s), wall_start) = (process_cpu_s(), Instant::now()) else {
                return;
            };
            for _ in 0..N_IMPORTS {
                let _ = black_box(import(input.file_name, black_box(&input.bytes)));
            }
            let wall_s = wall_start.elapsed().as_secs_f64();
            let Some(cpu_end_s) = process_cpu_s() else {
                return;
            };
            entries.push(format!(
                "  \"{}\": {{ \"wall_s\": {wall_s:.3}, \"cpu_s\": {:.3} }}",
                input.file_name,
                cpu_end_s - cpu_start_s
            ));
        }
        std::fs::write(
            data_dir().join("native_cpu.json"),
            format!("{{\n{}\n}}\n", entries.join(",\n")),
        )
        .expect("native_cpu.json can be written");
    }

    pub fn main() {
        let measuring = is_measuring();
        let inputs = if measuring {
            full_size_inputs()
        } else {
            small_inputs()
        };
        for input in &inputs {
            check(input, !measuring);
        }
        if measuring {
            write_cpu_ratios(&inputs);
        }

        let mut criterion = Criterion::default().configure_from_args();
        {
            let mut group = criterion.benchmark_group("import");
            // One import of 100 MB takes well under a second: ten flat samples of a few
            // iterations each, after a short warm-up, keep the whole run to a minute.
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_secs(2))
                .measurement_time(Duration::from_secs(10));
            for input in &inputs {
                group.throughput(Throughput::BytesDecimal(input.bytes.len() as u64));
                group.bench_function(input.bench_name, |bencher| {
                    bencher.iter(|| import(input.file_name, black_box(&input.bytes)));
                });
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
