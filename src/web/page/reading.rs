//! Reading what was dropped or chosen: each file in chunks through a [`ChunkedImport`],
//! the progress bar, the browser's turns between chunks, a remembered column mapping
//! for a header seen before, and the hand-off to the mapping dialog when a single
//! file's columns are not understood. The reading and the analysis run on the analysis
//! worker where the page has one (`web::worker`), else here, a chunk or a step per task.

use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use wasm_bindgen_futures::spawn_local;

use super::analysis::Request;
use super::{loading, now_ms, yield_to_browser, Outcome, Page, CHUNK_BYTES};
use crate::analysis::levelled::AnalysisError;
use crate::io::delimited::{preview, ColumnMapping, Preview};
use crate::io::import::{header_signature, merge, ChunkedImport, FileImport};
use crate::io::ImportError;
use crate::pipeline::Stage;
use crate::web::chunks::ChunkReader;
use crate::web::controls;
use crate::web::mapping;

/// The progress bar's id (see `www/index.html`).
const PROGRESS_ID: &str = "progress";

/// While a file is read, the browser gets a turn at least this often. (A chunk read
/// ahead is often ready when it is wanted, and awaiting it then gives the browser none.)
const YIELD_EVERY_MS: f64 = 40.0;

/// How much of a file's start is kept for the mapping dialog's preview.
const PREVIEW_BYTES: usize = 64 * 1024;

/// The preview of delimited text from its first bytes.
fn preview_of(first_chunk: &[u8]) -> Option<Preview> {
    let mut lines = Vec::new();
    crate::io::lines::decode_all(first_chunk, 4096, |line| {
        if lines.len() < 20 {
            lines.push(line.text.into_owned());
        }
    });
    let sample: Vec<&str> = lines.iter().map(String::as_str).collect();
    preview(&sample)
}

/// The first bytes of `file` (at most [`PREVIEW_BYTES`]): its header picks a
/// remembered mapping, and a file whose columns are not understood is previewed from
/// them.
async fn head_of(file: &web_sys::File) -> Result<Vec<u8>, String> {
    let head = file
        .slice_with_f64_and_f64(0.0, PREVIEW_BYTES as f64)
        .map_err(super::describe_js_error)?;
    let mut reader = ChunkReader::new(head, PREVIEW_BYTES as f64);
    let mut bytes = Vec::new();
    if let Some(read) = reader.next_into(&mut bytes).await {
        read?;
    }
    Ok(bytes)
}

impl Page {
    /// Reads every file dropped or chosen, in chunks, and analyses them as one recording
    /// (phyphox writes one file per sensor), on the analysis worker where there is one.
    pub(super) fn analyse_files(self: &Rc<Self>, files: &web_sys::FileList) {
        let files: Vec<web_sys::File> = (0..files.length())
            .filter_map(|idx| files.get(idx))
            .collect();
        if !files.is_empty() {
            self.analyse_file_list(files, None);
        }
    }

    /// Reads the files in chunks and analyses them as one recording. `mapping` is the
    /// one the user just made in the mapping dialog; otherwise a remembered one is used
    /// for a header seen before. A job still running is cancelled.
    pub(crate) fn analyse_file_list(
        self: &Rc<Self>,
        files: Vec<web_sys::File>,
        mapping: Option<ColumnMapping>,
    ) {
        let page = Rc::clone(self);
        let largest_bytes = files.iter().map(|file| file.size()).fold(0.0, f64::max);
        let cancel = self.begin_job(largest_bytes <= loading::HELD_UP_TO_BYTES);
        spawn_local(async move {
            let names: Vec<String> = files.iter().map(web_sys::File::name).collect();
            page.set_state("loading", &format!("Reading {}…", names.join(", ")));
            let mut mappings = vec![mapping.clone(); files.len()];
            let mut remembered_for = Vec::new();
            // A file's header is read first only to look up a mapping the user saved
            // (a few milliseconds per file, one after the other): not when there is
            // none, nor when the user has just chosen one.
            if mapping.is_none() && mapping::any_remembered() {
                for ((file, file_name), file_mapping) in files.iter().zip(&names).zip(&mut mappings)
                {
                    let head = match head_of(file).await {
                        Ok(head) => head,
                        Err(error) => {
                            page.show_error(&format!(
                                "Could not read {file_name}: {error}. Try choosing it again."
                            ));
                            return;
                        }
                    };
                    *file_mapping = header_signature(&head)
                        .and_then(|signature| mapping::remembered(&signature));
                    if file_mapping.is_some() {
                        remembered_for.push(file_name.clone());
                    }
                }
            }
            let Some((import, result)) = page
                .read_and_analyse(&files, &names, mappings, &cancel)
                .await
            else {
                return;
            };
            if cancel.load(Ordering::Acquire) {
                return;
            }
            // A single delimited file whose columns were not understood, or numbers
            // without a header line: ask the user.
            let unreadable_header = matches!(
                result,
                Err(AnalysisError::NoMagnetometerColumns { .. }
                    | AnalysisError::Import(
                        ImportError::UnknownHeader { .. } | ImportError::NoHeaderLine { .. }
                    ))
            );
            if let (true, [file]) = (unreadable_header, files.as_slice()) {
                // The file was read, so its start can be read again; if not, the
                // error stays shown.
                let first_chunk = head_of(file).await.unwrap_or_default();
                if cancel.load(Ordering::Acquire) {
                    return;
                }
                if let Some(preview) = preview_of(&first_chunk) {
                    let reason = result
                        .as_ref()
                        .err()
                        .map(ToString::to_string)
                        .unwrap_or_default();
                    page.show_error(&reason);
                    mapping::open_dialog(
                        &page,
                        file.clone(),
                        &preview,
                        &reason,
                        header_signature(&first_chunk),
                    );
                    return;
                }
            }
            page.show_outcome(result, import, (Stage::Calibration, &cancel))
                .await;
            if !remembered_for.is_empty() {
                let status = page.status.text_content().unwrap_or_default();
                page.status.set_text_content(Some(&format!(
                    "{status} Read with your saved column mapping for {}.",
                    remembered_for.join(", ")
                )));
            }
        });
    }

    /// Reads the files and analyses them: on the analysis worker where there is one,
    /// else here. `None` when cancelled.
    async fn read_and_analyse(
        self: &Rc<Self>,
        files: &[web_sys::File],
        names: &[String],
        mappings: Vec<Option<ColumnMapping>>,
        cancel: &Arc<AtomicBool>,
    ) -> Option<Outcome> {
        let options = controls::read(&self.document).options();
        #[cfg(target_feature = "atomics")]
        if let Some(worker) = self.worker() {
            use crate::web::worker::{FileRead, Job, Work};
            let reads = files
                .iter()
                .zip(names)
                .zip(mappings.iter().cloned())
                .map(|((file, name), mapping)| {
                    FileRead::new(name.clone(), file.size() as usize, mapping)
                })
                .collect();
            let work = Work::Files {
                files: reads,
                options: Box::new(options.clone()),
            };
            let job = Job::new(work, cancel);
            let blobs: Vec<web_sys::Blob> = files.iter().map(|file| file.clone().into()).collect();
            let on_update = self.on_update(&job);
            match worker.run(job, &blobs, on_update).await {
                Ok(job) => {
                    self.hide_progress();
                    return job.outcome;
                }
                // The worker never took the job: read the files here instead.
                Err(Some(_)) => {}
                Err(None) => {
                    // The worker failed, and the page says so: nothing held back is shown.
                    self.loading.end();
                    self.hide_progress();
                    return None;
                }
            }
        }
        let total_bytes: f64 = files.iter().map(|file| file.size()).sum();
        let mut bytes_done = 0.0;
        let mut results = Vec::with_capacity(files.len());
        for ((file, file_name), mapping) in files.iter().zip(names).zip(mappings) {
            match self
                .read_in_chunks(
                    file,
                    file_name,
                    mapping,
                    (&mut bytes_done, total_bytes),
                    cancel,
                )
                .await
            {
                Ok(Some(result)) => results.push((file_name.clone(), result)),
                Ok(None) => {
                    self.hide_progress();
                    return None;
                }
                Err(message) => {
                    self.hide_progress();
                    self.show_error(&message);
                    return None;
                }
            }
        }
        self.hide_progress();
        self.set_state("loading", &format!("Analysing {}…", names.join(", ")));
        let import = match merge(results) {
            Ok(import) => Arc::new(import),
            Err(error) => return Some((None, Err(error.into()))),
        };
        let request = Request {
            import: Arc::clone(&import),
            stage: Stage::Calibration,
            previous: None,
            options,
        };
        let result = self.analyse_here(request, cancel).await?;
        Some((Some(import), result))
    }

    /// One file through a [`ChunkedImport`] on this thread; `Ok(None)` when cancelled,
    /// `Err` only when the browser cannot read it. The next chunk is read while this
    /// one is parsed ([`ChunkReader`]); the browser gets a turn (to paint the progress
    /// bar, to answer input) at least every [`YIELD_EVERY_MS`].
    async fn read_in_chunks(
        &self,
        file: &web_sys::File,
        file_name: &str,
        mapping: Option<ColumnMapping>,
        (bytes_done, total_bytes): (&mut f64, f64),
        cancel: &AtomicBool,
    ) -> Result<Option<Result<FileImport, ImportError>>, String> {
        let mut reader = ChunkReader::new(file.clone().into(), CHUNK_BYTES);
        let mut import =
            ChunkedImport::new(file_name, Some(reader.size() as usize)).with_mapping(mapping);
        let mut bytes = Vec::new();
        let mut n_chunks = 0;
        let mut last_turn_ms = now_ms();
        while let Some(read) = reader.next_into(&mut bytes).await {
            read.map_err(|error| {
                format!("Could not read {file_name}: {error}. Try choosing it again.")
            })?;
            if cancel.load(Ordering::Acquire) {
                return Ok(None);
            }
            n_chunks += 1;
            if let Err(error) = import.feed(&bytes) {
                return Ok(Some(Err(error)));
            }
            *bytes_done += bytes.len() as f64;
            self.show_progress(*bytes_done / total_bytes.max(1.0), file_name);
            if now_ms() - last_turn_ms >= YIELD_EVERY_MS {
                yield_to_browser().await;
                last_turn_ms = now_ms();
            }
        }
        Ok(Some(if n_chunks == 0 {
            Err(ImportError::Empty {
                file_name: file_name.to_string(),
            })
        } else {
            import.finish()
        }))
    }

    pub(super) fn show_progress(&self, fraction: f64, file_name: &str) {
        if self.loading.hold_progress(fraction, file_name) {
            return;
        }
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("value", &format!("{:.4}", fraction.clamp(0.0, 1.0)));
            let _ = progress.remove_attribute("hidden");
        }
        self.status.set_text_content(Some(&format!(
            "Reading {file_name}… {:.0} %",
            100.0 * fraction.clamp(0.0, 1.0)
        )));
    }

    pub(super) fn hide_progress(&self) {
        self.loading.drop_progress();
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("hidden", "");
        }
    }
}
