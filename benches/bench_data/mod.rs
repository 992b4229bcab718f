//! The benchmark inputs: a canonical CSV from the crate's own walk simulator and a
//! synthetic NMEA 0183 log. Both are deterministic, so every run measures the same
//! bytes. `bench/run` generates them once (through `cargo bench --bench import`) under
//! `target/bench-data/`, where `bench/peers.py` and the wasm benchmark read them too.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use compass_pdr::base::rng::SplitMix64;
use compass_pdr::io::canonical_csv;
use compass_pdr::sim::nmea::{ddmm, push_sentence};
use compass_pdr::sim::walk::{simulate, WalkConfig};

/// Bumped whenever a generator's output changes, so that stale files are rebuilt.
const GENERATOR_VERSION: u32 = 1;

/// Seconds of simulated walk at 50 Hz for the full-size CSV: about 103 MB.
pub const WALK_DURATION_S: f64 = 18_200.0;
/// Epochs (10 Hz) of the full-size NMEA log: about 100 MB.
pub const NMEA_EPOCHS: usize = 478_000;

/// Rows per piece when the CSV is written, so that the text is never whole in memory.
const CSV_ROWS_PER_PIECE: usize = 50_000;

pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data")
}

/// The canonical CSV of a simulated walk of `duration_s`, written piece by piece to `out`.
pub fn write_walk_csv(duration_s: f64, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let rows = simulate(&WalkConfig::from_seed(1, duration_s));
    for (piece_idx, piece) in rows.chunks(CSV_ROWS_PER_PIECE).enumerate() {
        let text = canonical_csv::write(piece);
        // Each piece starts with the header; only the first keeps it.
        let body = if piece_idx == 0 {
            text.as_str()
        } else {
            text.split_once('\n').map_or("", |(_, rest)| rest)
        };
        out.write_all(body.as_bytes())?;
    }
    Ok(())
}

/// A synthetic NMEA 0183 log of `n_epochs` epochs at 10 Hz: RMC, GGA, VTG and HDT per
/// epoch, CRLF line endings, correct `*hh` checksums. A vehicle drives a smooth track
/// (speed 0-25 m/s, gentle turns, stops) from Munich, starting 2026-06-01 20:00:00 UTC,
/// so that the log crosses midnight and the RMC date changes.
pub fn write_nmea(n_epochs: usize, out: &mut impl std::io::Write) -> std::io::Result<()> {
    const METRES_PER_DEG_LAT: f64 = 111_320.0;
    const KNOTS_PER_MPS: f64 = 3600.0 / 1852.0;
    let start_days = compass_pdr::base::calendar::days_from_civil(2026, 6, 1);
    let start_ds: u64 = 20 * 3600 * 10;
    let mut rng = SplitMix64::new(2007);
    let mut lat_deg = 48.137_154;
    let mut lon_deg = 11.576_124;
    let mut alt_m = 519.0;
    let mut speed_mps = 0.0f64;
    let mut target_speed_mps = 12.0f64;
    let mut course_deg = 84.0f64;
    let mut turn_rate_dps = 0.0f64;
    let mut text = String::with_capacity(256 * 1024);
    for epoch_idx in 0..n_epochs {
        let total_ds = start_ds + epoch_idx as u64;
        let days = start_days + (total_ds / 864_000) as i64;
        let ds_of_day = total_ds % 864_000;
        let (year, month, day) = compass_pdr::base::calendar::civil_from_days(days);
        let time = format!(
            "{:02}{:02}{:02}.{:02}",
            ds_of_day / 36_000,
            ds_of_day / 600 % 60,
            ds_of_day / 10 % 60,
            ds_of_day % 10 * 10
        );
        let date = format!("{:02}{:02}{:02}", day, month, year % 100);

        // Every 30 s a new target speed (sometimes a stop) and turn rate.
        if epoch_idx % 300 == 0 {
            target_speed_mps = if rng.uniform() < 0.1 {
                0.0
            } else {
                rng.uniform_in(5.0, 25.0)
            };
            turn_rate_dps = if rng.uniform() < 0.3 {
                rng.uniform_in(-6.0, 6.0)
            } else {
                0.0
            };
        }
        speed_mps += (target_speed_mps - speed_mps) * 0.01;
        if speed_mps > 0.5 {
            course_deg = (course_deg + turn_rate_dps * 0.1).rem_euclid(360.0);
        }
        let course_rad = course_deg.to_radians();
        lat_deg += speed_mps * 0.1 * course_rad.cos() / METRES_PER_DEG_LAT;
        lon_deg +=
            speed_mps * 0.1 * course_rad.sin() / (METRES_PER_DEG_LAT * lat_deg.to_radians().cos());
        alt_m += rng.uniform_in(-0.05, 0.05);
        let speed_knots = speed_mps * KNOTS_PER_MPS;
        let heading_deg = (course_deg + rng.uniform_in(-1.5, 1.5)).rem_euclid(360.0);
        let lat = ddmm(lat_deg, 2, 'N', 'S');
        let lon = ddmm(lon_deg, 3, 'E', 'W');
        let n_satellites = 7 + rng.next_u64() % 6;
        let hdop = rng.uniform_in(0.7, 1.4);

        push_sentence(
            &mut text,
            &format!("GPRMC,{time},A,{lat},{lon},{speed_knots:.3},{course_deg:.2},{date},,,A"),
        );
        push_sentence(
            &mut text,
            &format!(
                "GPGGA,{time},{lat},{lon},1,{n_satellites:02},{hdop:.1},{alt_m:.1},M,46.9,M,,"
            ),
        );
        push_sentence(
            &mut text,
            &format!(
                "GPVTG,{course_deg:.2},T,,M,{speed_knots:.3},N,{:.3},K,A",
                speed_mps * 3.6
            ),
        );
        push_sentence(&mut text, &format!("HEHDT,{heading_deg:.2},T"));
        if text.len() > 200 * 1024 {
            out.write_all(text.as_bytes())?;
            text.clear();
        }
    }
    out.write_all(text.as_bytes())
}

/// The file `name` under [`data_dir`], generated by `generate` unless a file from the
/// same generator version and of the size recorded beside it is already there. Written
/// to a temporary name and renamed, so an interrupted run leaves no half file behind.
pub fn ensure_file(
    name: &str,
    generate: impl FnOnce(&mut std::io::BufWriter<fs::File>) -> std::io::Result<()>,
) -> std::io::Result<PathBuf> {
    let dir = data_dir();
    fs::create_dir_all(&dir)?;
    let path = dir.join(name);
    let stamp_path = dir.join(format!("{name}.stamp"));
    let stamp_for = |size: u64| format!("generator {GENERATOR_VERSION}, {size} bytes\n");
    if let (Ok(metadata), Ok(stamp)) = (fs::metadata(&path), fs::read_to_string(&stamp_path)) {
        if stamp == stamp_for(metadata.len()) {
            eprintln!("reusing {} ({} bytes)", path.display(), metadata.len());
            return Ok(path);
        }
    }
    eprintln!("generating {} …", path.display());
    let partial_path = dir.join(format!("{name}.partial"));
    let mut out = std::io::BufWriter::new(fs::File::create(&partial_path)?);
    generate(&mut out)?;
    out.flush()?;
    drop(out);
    fs::rename(&partial_path, &path)?;
    let size = fs::metadata(&path)?.len();
    fs::write(&stamp_path, stamp_for(size))?;
    eprintln!("generated {} ({size} bytes)", path.display());
    Ok(path)
}
