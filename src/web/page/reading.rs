//! Reading what was dropped or chosen: each file in chunks through a [`ChunkedImport`],
//! the progress bar, the browser's turns between chunks, a remembered column mapping
//! for a header seen before, and the hand-off to the mapping dialog when a single
//! file's columns are not understood. Also the calibration stage on what was read.

use std::rc::Rc;

use wasm_bindgen_futures::spawn_local;

use super::{now_ms, yield_to_browser, Page, CHUNK_BYTES};
use crate::analysis::AnalysisError;
use crate::calibration::CalibrationAnalysis;
use crate::io::delimited::{preview, ColumnMapping, Preview};
use crate::io::import::import_files;
use crate::io::import::{header_signature, merge, ChunkedImport, FileImport};
use crate::io::{ImportError, ImportReport};
use crate::pipeline;
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

/// What reading one file gave.
struct ChunkedRead {
    result: Result<FileImport, ImportError>,
    first_chunk: Vec<u8>,
    used_remembered_mapping: bool,
}

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

impl Page {
    /// Reads every file dropped or chosen, in chunks, and analyses them as one recording
    /// (phyphox writes one file per sensor). Each chunk is read asynchronously, so the
    /// page repaints and answers between chunks, and the progress bar moves.
    pub(super) fn analyse_files(self: &Rc<Self>, files: web_sys::FileList) {
        let files: Vec<web_sys::File> = (0..files.length())
            .filter_map(|idx| files.get(idx))
            .collect();
        if !files.is_empty() {
            self.analyse_file_list(files, None);
        }
    }

    /// Reads the files in chunks and analyses them as one recording. `mapping` is the
    /// one the user just made in the mapping dialog; otherwise a remembered one is used
    /// for a header seen before.
    pub(crate) fn analyse_file_list(
        self: &Rc<Self>,
        files: Vec<web_sys::File>,
        mapping: Option<ColumnMapping>,
    ) {
        let page = Rc::clone(self);
        spawn_local(async move {
            let names: Vec<String> = files.iter().map(web_sys::File::name).collect();
            page.set_state("loading", &format!("Reading {}…", names.join(", ")));
            let total_bytes: f64 = files.iter().map(|file| file.size()).sum();
            let mut bytes_done = 0.0;
            let mut results = Vec::with_capacity(files.len());
            let mut first_chunks = Vec::with_capacity(files.len());
            let mut remembered_for = Vec::new();
            for (file, file_name) in files.iter().zip(&names) {
                let read = page
                    .read_in_chunks(
                        file,
                        file_name,
                        mapping.as_ref(),
                        &mut bytes_done,
                        total_bytes,
                    )
                    .await;
                match read {
                    Ok(read) => {
                        if read.used_remembered_mapping {
                            remembered_for.push(file_name.clone());
                        }
                        results.push((file_name.clone(), read.result));
                        first_chunks.push(read.first_chunk);
                    }
                    Err(message) => {
                        page.hide_progress();
                        page.show_error(&message);
                        return;
                    }
                }
            }
            page.hide_progress();
            page.set_state("loading", &format!("Analysing {}…", names.join(", ")));
            let merged = merge(results).map_err(AnalysisError::from);
            let (result, import) = page.calibrate_import(merged);
            // A single delimited file whose columns were not understood, or numbers
            // without a header line: ask the user.
            let unreadable_header = matches!(
                result,
                Err(AnalysisError::NoMagnetometerColumns { .. }
                    | AnalysisError::Import(
                        ImportError::UnknownHeader { .. } | ImportError::NoHeaderLine { .. }
                    ))
            );
            if let (true, [file], [first_chunk]) =
                (unreadable_header, files.as_slice(), first_chunks.as_slice())
            {
                if let Some(preview) = preview_of(first_chunk) {
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
                        header_signature(first_chunk),
                    );
                    return;
                }
            }
            page.show_result(result, import).await;
            if !remembered_for.is_empty() {
                let status = page.status.text_content().unwrap_or_default();
                page.status.set_text_content(Some(&format!(
                    "{status} Read with your saved column mapping for {}.",
                    remembered_for.join(", ")
                )));
            }
        });
    }

    /// One file through a [`ChunkedImport`]; `Err` only when the browser cannot read it.
    /// The next chunk is read while this one is parsed ([`ChunkReader`]); the browser
    /// gets a turn (to paint the progress bar, to answer input) at least every
    /// [`YIELD_EVERY_MS`].
    async fn read_in_chunks(
        &self,
        file: &web_sys::File,
        file_name: &str,
        mapping: Option<&ColumnMapping>,
        bytes_done: &mut f64,
        total_bytes: f64,
    ) -> Result<ChunkedRead, String> {
        let mut reader = ChunkReader::new(file.clone().into(), CHUNK_BYTES);
        let size = reader.size();
        let mut import: Option<ChunkedImport> = None;
        let mut first_chunk = Vec::new();
        let mut used_remembered_mapping = false;
        let mut bytes = Vec::new();
        let mut last_turn_ms = now_ms();
        while let Some(read) = reader.next_into(&mut bytes).await {
            read.map_err(|error| {
                format!("Could not read {file_name}: {error}. Try choosing it again.")
            })?;
            let chunked = import.get_or_insert_with(|| {
                // The header is in the first chunk: it picks a remembered mapping.
                let signature = header_signature(&bytes);
                let remembered = match (mapping, &signature) {
                    (None, Some(signature)) => mapping::remembered(signature),
                    _ => None,
                };
                used_remembered_mapping = remembered.is_some();
                first_chunk = bytes
                    .get(..bytes.len().min(PREVIEW_BYTES))
                    .unwrap_or_default()
                    .to_vec();
                ChunkedImport::new(file_name, Some(size as usize))
                    .with_mapping(mapping.cloned().or(remembered))
            });
            if let Err(error) = chunked.feed(&bytes) {
                return Ok(ChunkedRead {
                    result: Err(error),
                    first_chunk,
                    used_remembered_mapping,
                });
            }
            *bytes_done += bytes.len() as f64;
            self.show_progress(*bytes_done / total_bytes.max(1.0), file_name);
            if now_ms() - last_turn_ms >= YIELD_EVERY_MS {
                yield_to_browser().await;
                last_turn_ms = now_ms();
            }
        }
        let result = match import {
            Some(import) => import.finish(),
            None => Err(ImportError::Empty {
                file_name: file_name.to_string(),
            }),
        };
        Ok(ChunkedRead {
            result,
            first_chunk,
            used_remembered_mapping,
        })
    }

    fn show_progress(&self, fraction: f64, file_name: &str) {
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("value", &format!("{:.4}", fraction.clamp(0.0, 1.0)));
            let _ = progress.remove_attribute("hidden");
        }
        self.status.set_text_content(Some(&format!(
            "Reading {file_name}… {:.0} %",
            100.0 * fraction.clamp(0.0, 1.0)
        )));
    }

    fn hide_progress(&self) {
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("hidden", "");
        }
    }

    pub(super) async fn analyse_and_show(&self, files: &[(&str, &[u8])]) {
        let imported = import_files(files).map_err(AnalysisError::from);
        let (result, import) = self.calibrate_import(imported);
        self.show_result(result, import).await;
    }

    /// Keeps the import for re-runs and runs the pipeline's calibration stage on it
    /// with the controls' options; also returns the kept import.
    fn calibrate_import(
        &self,
        imported: Result<ImportReport, AnalysisError>,
    ) -> (
        Result<CalibrationAnalysis, AnalysisError>,
        Option<Rc<ImportReport>>,
    ) {
        let import = match imported {
            Ok(report) => Rc::new(report),
            Err(error) => {
                *self.import.borrow_mut() = None;
                return (Err(error), None);
            }
        };
        *self.import.borrow_mut() = Some(Rc::clone(&import));
        let options = controls::read(&self.document).options();
        self.count_run(&self.n_calibration_runs, "data-calibration-runs");
        let result = pipeline::calibration(&import, &options.heading_options);
        (result, Some(import))
    }
}
