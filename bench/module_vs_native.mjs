// The page's analysis without the page: the WebAssembly module's whole pipeline
// (`pdr_pipeline`: import, calibration, heading models, dead reckoning) in Node's V8,
// on one thread, beside the native CLI's `compass-pdr pdr` on the same files pinned to
// one core (`taskset -c 0`), on the bundled demo (first, on the cold module) and on each
// real recording of ../shared/data as the page's end-to-end tests drop it.
// It separates what the page adds (reading the dropped files, the worker's messages,
// the drawing) from what WebAssembly costs against native code on the same core.
//
//   bench/module_vs_native.sh   # builds the module (opt-level 3, as the page's
//                               # threaded module) and runs this
//   node bench/module_vs_native.mjs PKG_DIR CLI [runs]
import { createRequire } from 'node:module';
import { execFileSync } from 'node:child_process';
import { existsSync, readFileSync } from 'node:fs';
import { basename, join } from 'node:path';
import { recordings } from '../tests/e2e/drops.mjs';

const [pkgDir, cli, runsText] = process.argv.slice(2);
const runs = Number(runsText || 7);
const wasm = createRequire(import.meta.url)(join(pkgDir, 'compass_pdr.js'));
const data = process.env.SHARED_DATA || join(import.meta.dirname, '..', '..', 'shared', 'data');
if (!existsSync(data)) {
  console.log(`skipped: ${data} not found (the real recordings live beside the project)`);
  process.exit(0);
}
// The bundled demo first, on the cold module: its "first run" is the page's first analysis.
// Then every recording as the page's end-to-end tests drop it (tests/e2e/drops.mjs: a
// folder's files together).
const demo = join(import.meta.dirname, '..', 'assets', 'demo-walk.csv');
const logs = [['demo-walk', [demo]], ...recordings(data)];
const median = (values) => [...values].sort((a, b) => a - b)[Math.floor(values.length / 2)];

console.log(`| recording | size | native \`pdr\`, one core (median of ${runs}) | module in Node, warm (median of ${runs} after one run) | module's first run | module / native |`);
console.log('|---|---:|---:|---:|---:|---:|');
for (const [name, paths] of logs) {
  const names = paths.map((path) => basename(path));
  const contents = paths.map((path) => readFileSync(path));
  const sizeMb = contents.reduce((sum, bytes) => sum + bytes.length, 0) / 1e6;
  const native = [];
  for (let run = 0; run < runs; run += 1) {
    const started = performance.now();
    try {
      execFileSync('taskset', ['-c', '0', cli, 'pdr', ...paths], { stdio: 'ignore' });
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
      wasm.pdr_pipeline_files(names, contents);
    } catch {
      // As above.
    }
    const ms = performance.now() - started;
    if (run === 0) first = ms;
    else module.push(ms);
  }
  const [n, m] = [median(native), median(module)];
  console.log(`| ${name} | ${sizeMb.toFixed(1)} MB | ${n.toFixed(0)} ms | ${m.toFixed(0)} ms | ${first.toFixed(0)} ms | ${(m / n).toFixed(2)} |`);
}
