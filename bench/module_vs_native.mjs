// The page's analysis without the page: the WebAssembly module's whole pipeline
// (`pdr_pipeline`: import, calibration, heading models, dead reckoning) in Node's V8,
// on one thread, beside the native CLI's `compass-pdr pdr` on the same file pinned to
// one core (`taskset -c 0`), on the bundled demo (first, on the cold module) and on each
// single-file real recording of ../shared/data.
// It separates what the page adds (reading the dropped files, the worker's messages,
// the drawing) from what WebAssembly costs against native code on the same core.
//
//   bench/module_vs_native.sh   # builds the module (opt-level "s", as the page's
//                               # threaded module) and runs this
//   node bench/module_vs_native.mjs PKG_DIR CLI [runs]
import { createRequire } from 'node:module';
import { execFileSync } from 'node:child_process';
import { existsSync, readFileSync } from 'node:fs';
import { basename, join } from 'node:path';

const [pkgDir, cli, runsText] = process.argv.slice(2);
const runs = Number(runsText || 7);
const wasm = createRequire(import.meta.url)(join(pkgDir, 'compass_pdr.js'));
const data = process.env.SHARED_DATA || join(import.meta.dirname, '..', '..', 'shared', 'data');
if (!existsSync(data)) {
  console.log(`skipped: ${data} not found (the real recordings live beside the project)`);
  process.exit(0);
}
// The bundled demo first, on the cold module: its "first run" is the page's first analysis.
const demo = join(import.meta.dirname, '..', 'assets', 'demo-walk.csv');
const logs = [demo, ...[
  'px4-ulog/sample.ulg',
  'px4-ulog/sample_log_small.ulg',
  'ardupilot-copter-log171/log171.bin',
  'ardupilot-text-log/nan.log',
  'msft-indoor-2020/site1/F1/5dd9ef979191710006b57086.txt',
  'msft-indoor-2020/site1/F4/5ddb6573c5b77e0006b17932.txt',
  'vehicle-pixel6a/2023-08-09_12-47-42.csv',
  'qmc5883l-calibration/noisy_raw_data.csv',
  'qmc5883l-calibration/filtered_raw_data.csv',
].map((path) => join(data, path))].filter((path) => existsSync(path));
const median = (values) => [...values].sort((a, b) => a - b)[Math.floor(values.length / 2)];

console.log(`| recording | native \`pdr\`, one core (median of ${runs}) | module in Node, warm (median of ${runs} after one run) | module's first run | module / native |`);
console.log('|---|---:|---:|---:|---:|');
for (const path of logs) {
  const bytes = readFileSync(path);
  const native = [];
  for (let run = 0; run < runs; run += 1) {
    const started = performance.now();
    try {
      execFileSync('taskset', ['-c', '0', cli, 'pdr', path], { stdio: 'ignore' });
    } catch {
      // A log the CLI cannot dead-reckon still timed: it ran the same stages.
    }
    native.push(performance.now() - started);
  }
  const module = [];
  let first = null;
  for (let run = 0; run <= runs; run += 1) {
    const started = performance.now();
    try {
      wasm.pdr_pipeline(basename(path), bytes);
    } catch {
      // As above.
    }
    const ms = performance.now() - started;
    if (run === 0) first = ms;
    else module.push(ms);
  }
  const [n, m] = [median(native), median(module)];
  console.log(`| ${basename(path)} | ${n.toFixed(0)} ms | ${m.toFixed(0)} ms | ${first.toFixed(0)} ms | ${(m / n).toFixed(2)} |`);
}
