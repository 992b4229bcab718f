//! Reading the files a command names (`import_paths`: each mapped into memory and read
//! whole, or in chunks where it cannot be mapped, with a remembered column mapping) and
//! `compass-pdr inspect`: what a log holds.

use super::args::ImportArgs;
use super::{mapping_store, print_out, print_report};
use compass_pdr::io::delimited::ColumnMapping;
use compass_pdr::io::import::{header_signature, import_file, merge, ChunkedImport, Inspection};
use compass_pdr::io::{Diagnostics, ImportReport};

/// Reads the files of one recording and merges them: each file mapped into memory and
/// read whole ([`import_file`]), or, where it cannot be mapped (a pipe), in chunks
/// through [`ChunkedImport`] (memory then holds the samples, not the text); the maps are
/// dropped on a thread of their own. A file that cannot be opened ends the command with
/// its name;
/// one that cannot be parsed is left out with a diagnostic unless all fail. A column
/// mapping given with `--map` is remembered for the file's header; without one, a
/// remembered mapping is used and said so.
pub(super) fn import_paths(input: &ImportArgs) -> Result<ImportReport, String> {
    use std::io::Read as _;
    // Large enough that each chunk's whole lines (a chunk less its first, carried line)
    // reach the delimited reader's parallel threshold (1 MiB): a chunk of 8 MiB is read
    // on every core, as the page's 4 MiB chunks are in the threaded module.
    const CHUNK_BYTES: usize = 8 << 20;
    let given_mapping = input
        .map
        .as_deref()
        .map(ColumnMapping::parse)
        .transpose()
        .map_err(|error| format!("--map: {error}"))?;
    let mut store = mapping_store::MappingStore::load();
    let mut results = Vec::with_capacity(input.files.len());
    let mut buffer = vec![0u8; CHUNK_BYTES];
    let mut maps: Vec<memmap2::Mmap> = Vec::new();
    for path in &input.files {
        let file_name = path.display().to_string();
        let cannot_read = |error: std::io::Error| format!("cannot read {file_name}: {error}");
        let mut file = std::fs::File::open(path).map_err(cannot_read)?;
        let size_hint = file
            .metadata()
            .ok()
            .and_then(|metadata| usize::try_from(metadata.len()).ok());
        let mapped = map_file(&file);
        let n_read = match &mapped {
            Some(_) => 0,
            None => file.read(&mut buffer).map_err(cannot_read)?,
        };
        let first_chunk = match &mapped {
            Some(map) => map.get(..map.len().min(CHUNK_BYTES)).unwrap_or_default(),
            None => buffer.get(..n_read).unwrap_or_default(),
        };
        let signature = header_signature(first_chunk);
        let mapping = match (&given_mapping, &signature) {
            (Some(mapping), Some(signature)) => {
                store.remember(signature, mapping);
                Some(mapping.clone())
            }
            (Some(mapping), None) => Some(mapping.clone()),
            (None, Some(signature)) => store.recall(signature).inspect(|_| {
                eprintln!(
                    "note: {file_name}: using the column mapping remembered for this header ({}); pass --map to change it",
                    store.path_text()
                );
            }),
            (None, None) => None,
        };
        if let Some(map) = &mapped {
            // The whole file at once: the streams sized once, a large file parsed on
            // every core.
            results.push((
                file_name.clone(),
                import_file(&file_name, map, mapping.as_ref()),
            ));
        }
        if let Some(map) = mapped {
            maps.push(map);
            continue;
        }
        let mut n_read = n_read;
        let mut import = ChunkedImport::new(&file_name, size_hint).with_mapping(mapping);
        let mut result = Ok(());
        while n_read > 0 {
            let Some(chunk) = buffer.get(..n_read) else {
                break;
            };
            result = import.feed(chunk);
            if result.is_err() {
                break;
            }
            n_read = file.read(&mut buffer).map_err(cannot_read)?;
        }
        results.push((file_name, result.and_then(|()| import.finish())));
    }
    unmap_meanwhile(maps);
    if let Err(message) = store.save_if_changed() {
        eprintln!("warning: {message}");
    }
    let mut report = merge(results).map_err(|error| error.to_string())?;
    if let Some(stated) = input.gyro_bias {
        report.recording.gyro_bias = stated.gyro_bias();
        report.notes.push(stated.note().to_string());
    }
    Ok(report)
}

/// Unmaps the files' maps on a thread of its own while the command goes on: taking
/// down a 100 MB file's 24,000 page mappings kept `inspect`'s one thread busy for
/// 5-6 ms after the import, the other core idle (timed 2026-11-28). Where no thread
/// can be started, here.
fn unmap_meanwhile(maps: Vec<memmap2::Mmap>) {
    if maps.is_empty() {
        return;
    }
    // On failure the closure, and the maps with it, are dropped on this thread.
    let _ = std::thread::Builder::new()
        .name("unmap".to_string())
        .spawn(move || drop(maps));
}

/// `file` mapped into memory, where the system allows it (not a pipe, not empty).
/// Read through a buffer, a quarter of `inspect`'s time on a 100 MB CSV was the kernel
/// copying the file into the buffer (perf record, 2026-11-27), and the chunks' streams
/// grew (and were copied) chunk by chunk.
fn map_file(file: &std::fs::File) -> Option<memmap2::Mmap> {
    // SAFETY: the map is only read, within this command, while the file is open.
    // Were another program to shorten the file meanwhile, reading the lost pages would
    // end the process with SIGBUS: the trade every tool that maps its input makes
    // (ripgrep, polars). A file that cannot be mapped is read through a buffer.
    let map = unsafe { memmap2::Mmap::map(file) }.ok()?;
    if map.is_empty() {
        return None;
    }
    let _ = map.advise(memmap2::Advice::Sequential);
    Some(map)
}

pub(super) fn run_inspect(input: &ImportArgs, json: bool) -> Result<(), String> {
    let report = import_paths(input)?;
    let inspection = Inspection::of(&report);
    print_import_diagnostics(&inspection.file_name, &inspection.diagnostics);
    if json {
        return print_report(&inspection, true, |_| String::new());
    }
    use std::fmt::Write as _;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {}, {} {}, {} {}skipped or suspect",
        inspection.file_name,
        inspection.format,
        inspection.n_data_lines,
        if inspection.compass_params.is_some() {
            "messages"
        } else {
            "data lines"
        },
        inspection.diagnostics.total(),
        if inspection.compass_params.is_some() {
            ""
        } else {
            compass_pdr::base::words::plural(inspection.diagnostics.total(), "line ", "lines ")
        }
    );
    let _ = writeln!(
        text,
        "  {:<34} {:>9} {:>9} {:>10} {:>5} {:>9} {:>8} {:>11}",
        "stream", "samples", "rate Hz", "duration s", "gaps", "max gap s", "repeats", "mean |v|"
    );
    for stream in &inspection.streams {
        let _ = writeln!(
            text,
            "  {:<34} {:>9} {:>9} {:>10.2} {:>5} {:>9.3} {:>8} {:>11}",
            stream.stream,
            stream.n_samples,
            stream
                .rate_hz
                .map_or("—".to_string(), |rate_hz| format!("{rate_hz:.2}")),
            stream.duration_s,
            stream.n_gaps,
            stream.largest_gap_s,
            stream.n_repeated_times,
            stream
                .mean_magnitude
                .map_or(String::new(), |magnitude| format!(
                    "{magnitude:.3} {}",
                    stream.unit
                )),
        );
    }
    if let Some(frame) = &inspection.mag_frame {
        let _ = writeln!(text, "  {}", frame.describe());
    }
    if let Some(params) = inspection.compass_params.as_ref().filter(|p| !p.is_empty()) {
        let listed: Vec<String> = params
            .iter()
            .map(|(name, value)| format!("{name} {}", *value as f32))
            .collect();
        let _ = writeln!(text, "  compass parameters in force: {}", listed.join(", "));
    }
    for note in &inspection.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    print_out(&text)
}

/// Every skipped or suspect line goes to stderr as `file:line: message`.
pub(super) fn print_import_diagnostics(file_name: &str, diagnostics: &Diagnostics) {
    for diagnostic in &diagnostics.kept {
        let file_name = diagnostic.file_name.as_deref().unwrap_or(file_name);
        match diagnostic.line {
            Some(line) => eprintln!("warning: {file_name}:{line}: {}", diagnostic.message),
            None => eprintln!("warning: {file_name}: {}", diagnostic.message),
        }
    }
    if diagnostics.n_not_kept > 0 {
        eprintln!(
            "warning: {file_name}: {} more lines had problems (not listed)",
            diagnostics.n_not_kept
        );
    }
}
