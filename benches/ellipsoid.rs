//! Ellipsoid-fit time: `compass_pdr::fit::streaming_ellipsoid::fit_ellipsoid` on
//! 10³, 10⁴, 10⁵ and 10⁶ full-sphere magnetometer samples from the crate's simulator
//! (`sim::field`, fixed seed), algebraic only (`refine: false`, what Magneto 1.2 and
//! `bench/ellipsoid_peer.py` do) and with the Levenberg-Marquardt refinement. Run by
//! `bench/run`, which records the figures in docs/BENCHMARKS.md beside numpy's Li-Griffiths
//! fit and the same fit in WebAssembly.
//!
//! `cargo bench --bench ellipsoid --profile bench-import` writes each sample set as
//! little-endian f64 `x, y, z` triples to `target/bench-data/sphere_<n>.f64` (for the
//! Python and wasm peers; rewritten when the size is wrong) and
//! `target/bench-data/sphere_fits.json`, the true hard iron and the one each native fit
//! found. Under `cargo test` (criterion's test mode) it fits small sets once and checks
//! the hard iron.

#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::fs;
    use std::hint::black_box;
    use std::io::Write as _;
    use std::path::{Path, PathBuf};
    use std::time::Duration;

    use compass_pdr::base::rng::SplitMix64;
    use compass_pdr::fit::streaming_ellipsoid::{fit_ellipsoid, EllipsoidOptions};
    use compass_pdr::sim::field::{full_sphere, FieldTruth};
    use criterion::{BenchmarkId, Criterion, SamplingMode};
    use nalgebra::Vector3;

    /// The sample counts measured; each set is the first `n` of the largest.
    const SIZES: [usize; 4] = [1_000, 10_000, 100_000, 1_000_000];
    /// Sizes fitted once under `cargo test`.
    const TEST_SIZES: [usize; 2] = [1_000, 10_000];
    const DISTORTION_SEED: u64 = 4;
    const SAMPLES_SEED: u64 = 2024;

    /// Whether criterion measures (`cargo bench`) rather than tests (`cargo test`); the
    /// same rule criterion applies to its own arguments.
    fn is_measuring() -> bool {
        let args: Vec<String> = std::env::args().collect();
        args.iter().any(|arg| arg == "--bench") && !args.iter().any(|arg| arg == "--test")
    }

    fn data_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data")
    }

    fn options(refine: bool) -> EllipsoidOptions {
        EllipsoidOptions {
            refine,
            ..Default::default()
        }
    }

    /// The distortion (hard iron up to 30 µT, scale errors up to 15 %, cross terms up to
    /// 0.08) and `n_max` samples over the whole sphere (0.3 µT noise).
    fn samples(n_max: usize) -> (FieldTruth, Vec<Vector3<f64>>) {
        let truth = FieldTruth::random(&mut SplitMix64::new(DISTORTION_SEED), 30.0, 0.15, 0.08);
        let mut rng = SplitMix64::new(SAMPLES_SEED);
        let mag_ut = full_sphere(&truth, n_max, &mut rng)
            .into_iter()
            .map(|sample| sample.mag_ut)
            .collect();
        (truth, mag_ut)
    }

    /// `sphere_<n>.f64`: little-endian f64 triples, written unless a file of the right
    /// size is there (the data are deterministic). Written to a temporary name and
    /// renamed, so an interrupted run leaves no half file behind.
    fn write_f64_file(mag_ut: &[Vector3<f64>]) -> std::io::Result<()> {
        let dir = data_dir();
        fs::create_dir_all(&dir)?;
        let path = dir.join(format!("sphere_{}.f64", mag_ut.len()));
        let size = (mag_ut.len() * 3 * std::mem::size_of::<f64>()) as u64;
        if fs::metadata(&path).is_ok_and(|metadata| metadata.len() == size) {
            return Ok(());
        }
        let partial = dir.join(format!("sphere_{}.f64.partial", mag_ut.len()));
        let mut out = std::io::BufWriter::new(fs::File::create(&partial)?);
        for sample in mag_ut {
            for value in sample.iter() {
                out.write_all(&value.to_le_bytes())?;
            }
        }
        out.flush()?;
        drop(out);
        fs::rename(&partial, &path)?;
        eprintln!("wrote {} ({size} bytes)", path.display());
        Ok(())
    }

    fn json_vector(v: &Vector3<f64>) -> String {
        format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z)
    }

    /// Fits each set once each way, checks the hard iron against the truth and
    /// returns the JSON lines of `sphere_fits.json`.
    fn check(truth: &FieldTruth, sets: &[&[Vector3<f64>]]) -> Vec<String> {
        let mut entries = Vec::new();
        for set in sets {
            let mut found = Vec::new();
            for refine in [false, true] {
                let fit = fit_ellipsoid(set, &options(refine))
                    .unwrap_or_else(|error| panic!("{} samples do not fit: {error}", set.len()));
                let error_ut = (fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm();
                eprintln!(
                    "{} samples, refine {refine}: model {:?}, hard iron {} (off by {error_ut:.3} µT), residual {:.3} µT",
                    set.len(),
                    fit.model,
                    json_vector(&fit.calibration.hard_iron_ut),
                    fit.residual_rms_ut
                );
                assert!(
                    error_ut < 1.0,
                    "{} samples: hard iron off by {error_ut} µT",
                    set.len()
                );
                found.push(format!(
                    "\"{}\": {{ \"model\": \"{:?}\", \"hard_iron_ut\": {}, \"residual_rms_ut\": {:.4} }}",
                    if refine { "refined" } else { "algebraic" },
                    fit.model,
                    json_vector(&fit.calibration.hard_iron_ut),
                    fit.residual_rms_ut
                ));
            }
            entries.push(format!("    \"{}\": {{ {} }}", set.len(), found.join(", ")));
        }
        entries
    }

    pub fn main() {
        let measuring = is_measuring();
        let sizes: &[usize] = if measuring { &SIZES } else { &TEST_SIZES };
        let n_max = sizes.iter().copied().max().unwrap_or(0);
        let (truth, all) = samples(n_max);
        let sets: Vec<&[Vector3<f64>]> = sizes.iter().map(|&n| &all[..n]).collect();
        let fits = check(&truth, &sets);
        if measuring {
            for set in &sets {
                write_f64_file(set)
                    .expect("the sphere files can be written under target/bench-data");
            }
            let json = format!(
                "{{\n  \"true_hard_iron_ut\": {},\n  \"fits\": {{\n{}\n  }}\n}}\n",
                json_vector(&truth.hard_iron_ut),
                fits.join(",\n")
            );
            fs::write(data_dir().join("sphere_fits.json"), json)
                .expect("sphere_fits.json can be written");
        }

        let mut criterion = Criterion::default().configure_from_args();
        {
            let mut group = criterion.benchmark_group("ellipsoid");
            // Ten flat samples after a short warm-up: 8 benchmarks in well under a minute
            // and a half.
            group
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(2));
            for set in &sets {
                for (name, refine) in [("algebraic", false), ("refined", true)] {
                    let options = options(refine);
                    group.bench_with_input(
                        BenchmarkId::new(name, set.len()),
                        set,
                        |bencher, set| bencher.iter(|| fit_ellipsoid(black_box(set), &options)),
                    );
                }
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
