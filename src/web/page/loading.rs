//! A job's "loading" display (the Cancel button, the status line's "Reading …" and
//! "Analysing …", the progress bar), held back for the job's first [`SHOWN_AFTER_MS`]:
//! most drops are answered within that, and the display would only flash. Each change
//! of it costs the browser a frame (style, layout, paint, raster and compositing:
//! several milliseconds of CPU with software rendering), and on a 2-core machine those
//! frames took a core from the analysis worker and its pool.
//! Drop to the answer, the display held back against shown at once (four first drops
//! each, builds alternating, bench/drop_costs.mjs WARM=1 DROP=1, 2026-12-07): the
//! HMC5883L sphere 47-53 ms against 49-69, the HMC5883L lying still 67-72 against 71-83,
//! Microsoft F1 76-82 against 97-129, the Pixel 6a drive 106-123 against 119-140.
//! A job still running then shows the latest of what was held back. A drop with a file
//! over [`HELD_UP_TO_BYTES`] shows its display at once: it takes a second or more. The
//! body's `data-state` is not held back: it says at once that the page is loading, for
//! the tests and for whatever else watches it.

use std::cell::{Cell, RefCell};

/// How long a job runs before its loading display is shown (ms).
pub(super) const SHOWN_AFTER_MS: i32 = 200;

/// The largest file of a drop whose display is held back (bytes): a larger one is read
/// in chunks (`WHOLE_FILE_BYTES` in `www/analysis-worker.js`), and its analysis takes a
/// second or more (the 50 MB log of `tests/e2e/page.test.mjs`: 1.7-1.9 s, of which its
/// reading about 250 ms), so its progress is worth showing from the start. No file of
/// `../shared/data` is this large.
pub(super) const HELD_UP_TO_BYTES: f64 = 16.0 * 1024.0 * 1024.0;

/// What a job has held back of its loading display.
#[derive(Default)]
pub(super) struct Held {
    /// The running job's number: a timer of an earlier job shows nothing.
    job: Cell<u64>,
    /// Whether the running job's display is still held back.
    holding: Cell<bool>,
    /// The latest status line of the `loading` state held back.
    status: RefCell<Option<String>>,
    /// The latest progress held back: the fraction read and the file being read.
    progress: RefCell<Option<(f64, String)>>,
}

/// What to show once the holding ends: the status line and the progress.
pub(super) type Display = (Option<String>, Option<(f64, String)>);

impl Held {
    /// A job begins: its display is held back if `hold`; returns its number for the
    /// timer.
    pub(super) fn begin(&self, hold: bool) -> u64 {
        self.job.set(self.job.get() + 1);
        self.holding.set(hold);
        self.status.take();
        self.progress.take();
        self.job.get()
    }

    /// Keeps `status` for later when the display is held back (`true`).
    pub(super) fn hold_status(&self, status: &str) -> bool {
        if self.holding.get() {
            *self.status.borrow_mut() = Some(status.to_string());
        }
        self.holding.get()
    }

    /// Keeps the progress for later when the display is held back (`true`).
    pub(super) fn hold_progress(&self, fraction: f64, file_name: &str) -> bool {
        if self.holding.get() {
            *self.progress.borrow_mut() = Some((fraction, file_name.to_string()));
        }
        self.holding.get()
    }

    /// The progress bar is hidden: none is to be shown later either.
    pub(super) fn drop_progress(&self) {
        self.progress.take();
    }

    /// The job has an outcome (an answer, an error, a cancel): nothing held is shown.
    pub(super) fn end(&self) {
        self.holding.set(false);
        self.status.take();
        self.progress.take();
    }

    /// Job `job`'s time is up: what it held back, to be shown now (nothing when the job
    /// has ended or another has begun).
    pub(super) fn release(&self, job: u64) -> Option<Display> {
        if job != self.job.get() || !self.holding.get() {
            return None;
        }
        self.holding.set(false);
        Some((self.status.take(), self.progress.take()))
    }
}

#[cfg(test)]
mod tests {
    use wasm_bindgen_test::wasm_bindgen_test;

    use super::Held;

    #[wasm_bindgen_test]
    fn a_quick_job_shows_nothing_and_a_slow_one_its_latest_state() {
        let held = Held::default();
        let quick = held.begin(true);
        assert!(held.hold_status("Reading a.csv…"));
        assert!(held.hold_progress(0.5, "a.csv"));
        held.end();
        assert!(held.release(quick).is_none(), "the job ended first");

        let slow = held.begin(true);
        assert!(held.hold_progress(0.2, "b.csv"));
        assert!(held.hold_status("Analysing b.csv…"));
        assert!(held.hold_progress(0.7, "b.csv"));
        let (status, progress) = held.release(slow).expect("still running");
        assert_eq!(status.as_deref(), Some("Analysing b.csv…"));
        assert_eq!(progress, Some((0.7, "b.csv".to_string())));
        assert!(
            !held.hold_status("Analysing b.csv: headings…"),
            "shown at once now"
        );
        assert!(held.release(slow).is_none(), "released once");
    }

    #[wasm_bindgen_test]
    fn an_earlier_jobs_timer_shows_nothing_of_the_next() {
        let held = Held::default();
        let first = held.begin(true);
        let second = held.begin(true);
        assert!(held.hold_status("Reading c.csv…"));
        assert!(held.release(first).is_none());
        assert!(held.release(second).is_some());
    }

    #[wasm_bindgen_test]
    fn a_job_not_held_back_shows_everything_at_once() {
        let held = Held::default();
        let job = held.begin(false);
        assert!(!held.hold_status("Reading large.csv…"));
        assert!(!held.hold_progress(0.1, "large.csv"));
        assert!(held.release(job).is_none());
    }

    #[wasm_bindgen_test]
    fn a_hidden_progress_bar_is_not_shown_later() {
        let held = Held::default();
        let job = held.begin(true);
        assert!(held.hold_progress(1.0, "d.csv"));
        held.drop_progress();
        assert_eq!(held.release(job), Some((None, None)));
    }
}
