//! The foundations every layer stands on, none of them about compasses: angles,
//! the calendar, English words, sorting by a float key, statistics, random numbers,
//! geodesy and the thread pool.

pub mod angle;
pub mod calendar;
pub mod geodesy;
pub mod par;
pub mod rng;
pub mod sort;
pub mod stats;
pub mod words;

/// `√(x² + y²)` of two components far from overflow and underflow (a sensor's
/// readings, their sums, angles): what `f64::hypot` gives, within an ulp, without its
/// guard against overflow, which in WebAssembly (no fused multiply-add instruction)
/// calls a software `fma` three times. On the page's per-sample paths (a tilt from each
/// specific force, the attitude filter's field updates) that guard took about 1.5 ms of
/// a 45 ms analysis (the HMC5883L sphere, perf on Chromium, 2026-12-06).
#[inline]
pub fn norm2d(x: f64, y: f64) -> f64 {
    (x * x + y * y).sqrt()
}
