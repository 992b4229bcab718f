// The import benchmark in the browser: the release module's `ImportBench` (the import
// alone, on bytes held in the module's memory, as the native benchmark times it),
// `inspect_file` (the bytes copied in, import, stream summaries and conversion to a JS
// object) on each benchmark input, and `inspect_blob` (the page's path for a dropped file: the
// bytes as a Blob, read in chunks through the chunked importer; its result must equal
// the whole-file one). One warm-up call, then `runs` timed calls; the median is
// reported. The result is left in `window.benchResults` (or `window.benchError`) for
// bench/wasm-bench.mjs, and shown in the page.
//
// `?threads=1`: the threaded module (pkg-threads/, what the page loads when it is
// cross-origin isolated) with its workers started as the page starts them (threads.js,
// served from www/), timed once every worker waits for work.
import { report } from './report.js';

const INPUTS = [
  { name: 'walk.csv', url: 'data/walk.csv' },
  { name: 'track.nmea', url: 'data/track.nmea' },
];

function median(values) {
  const sorted = [...values].sort((a, b) => a - b);
  const mid = Math.floor(sorted.length / 2);
  return sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
}

async function run() {
  const params = new URLSearchParams(location.search);
  const runs = Math.max(1, Number(params.get('runs') || 5));
  const threaded = params.get('threads') === '1';
  const wasm = await import(threaded ? './pkg-threads/compass_pdr.js' : './pkg/compass_pdr.js');
  await wasm.default();
  const { ImportBench, inspect_blob, inspect_file } = wasm;
  let nThreads = 1;
  if (threaded) {
    if (!self.crossOriginIsolated) throw new Error('?threads=1 needs a cross-origin isolated page (COOP/COEP headers)');
    const { startWorkers, whenWorkersReady } = await import('./threads.js');
    const nWorkers = startWorkers(wasm, Number(params.get('workers') ?? Infinity));
    nThreads = await whenWorkersReady(wasm, nWorkers);
    if (nThreads !== nWorkers + 1) throw new Error(`only ${nThreads - 1} of ${nWorkers} workers started`);
  }
  const results = { runs, threaded, n_threads: nThreads, inputs: {} };
  for (const input of INPUTS) {
    const response = await fetch(input.url);
    if (!response.ok) throw new Error(`${input.url}: HTTP ${response.status}`);
    const bytes = new Uint8Array(await response.arrayBuffer());
    let inspection = inspect_file(input.name, bytes);
    const ms = [];
    for (let i = 0; i < runs; i += 1) {
      const start = performance.now();
      inspection = inspect_file(input.name, bytes);
      ms.push(performance.now() - start);
    }
    const medianMs = median(ms);

    // The page's path for a dropped file: the same bytes as a Blob, read in chunks (the
    // next read while this one is parsed) through the chunked importer.
    const blob = new Blob([bytes]);
    const fromBlob = await inspect_blob(input.name, blob);
    if (JSON.stringify(fromBlob) !== JSON.stringify(inspection)) {
      throw new Error(`${input.name}: read from a Blob in chunks, the import differs from reading it whole`);
    }
    const blobMs = [];
    for (let i = 0; i < runs; i += 1) {
      const start = performance.now();
      await inspect_blob(input.name, blob);
      blobMs.push(performance.now() - start);
    }
    const blobMedianMs = median(blobMs);
    // The import alone, on bytes already in the module's memory (copied there once), as
    // the native benchmark imports bytes already in memory. (Last: with a second copy of
    // the file held in the module, Chromium refused to read the Blob above.)
    const held = new ImportBench(input.name, bytes);
    if (held.run() !== inspection.n_data_lines) throw new Error(`${input.name}: the held import differs`);
    const importMs = [];
    for (let i = 0; i < runs; i += 1) {
      const start = performance.now();
      held.run();
      importMs.push(performance.now() - start);
    }
    held.free();
    const importMedianMs = median(importMs);
    results.inputs[input.name] = {
      bytes: bytes.length,
      ms: ms.map((value) => Math.round(value * 10) / 10),
      median_ms: medianMs,
      mb_per_s: bytes.length / 1e6 / (medianMs / 1e3),
      import_ms: importMs.map((value) => Math.round(value * 10) / 10),
      import_median_ms: importMedianMs,
      import_mb_per_s: bytes.length / 1e6 / (importMedianMs / 1e3),
      blob_ms: blobMs.map((value) => Math.round(value * 10) / 10),
      blob_median_ms: blobMedianMs,
      blob_mb_per_s: bytes.length / 1e6 / (blobMedianMs / 1e3),
      format: inspection.format,
      n_data_lines: inspection.n_data_lines,
      streams: inspection.streams.map((stream) => `${stream.stream} ${stream.n_samples}`),
      n_diagnostics: inspection.diagnostics.kept.length + inspection.diagnostics.n_not_kept,
    };
    document.getElementById('status').textContent = JSON.stringify(results, null, 2);
  }
  return results;
}

report(run());
