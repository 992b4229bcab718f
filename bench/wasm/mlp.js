// The MLP-training benchmark in the browser: the release module's `train_mlp_rows` (the
// Float64Array copied into the module's memory, split into training and test rows,
// L-BFGS training, test MSE, the result converted to a JS object) on the samples of
// benches/mlp.rs. One warm-up call, then `runs` timed calls; the median is reported. The
// result is left in `window.benchResults` (or `window.benchError`) for
// bench/wasm-bench.mjs.
import { report } from './report.js';
import init, { train_mlp_rows } from './pkg/compass_pdr.js';

function median(values) {
  const sorted = [...values].sort((a, b) => a - b);
  const mid = Math.floor(sorted.length / 2);
  return sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
}

async function fetchOk(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return response;
}

async function run() {
  const params = new URLSearchParams(location.search);
  const runs = Math.max(1, Number(params.get('runs') || 5));
  await init();
  const settings = await (await fetchOk('data/mlp_settings.json')).json();
  const rows = new Float64Array(await (await fetchOk('data/mlp_samples.f64')).arrayBuffer());
  const width = settings.n_inputs + 1;
  if (rows.length !== width * (settings.n_train + settings.n_test)) {
    throw new Error(`mlp_samples.f64: ${rows.length} numbers, expected ${width * (settings.n_train + settings.n_test)}`);
  }
  let training = train_mlp_rows(rows, settings.n_inputs, settings.n_train, settings.max_iter);
  const ms = [];
  for (let i = 0; i < runs; i += 1) {
    const start = performance.now();
    training = train_mlp_rows(rows, settings.n_inputs, settings.n_train, settings.max_iter);
    ms.push(performance.now() - start);
  }
  const results = {
    runs,
    ms: ms.map((value) => Math.round(value * 10) / 10),
    median_ms: median(ms),
    ...training,
  };
  document.getElementById('status').textContent = JSON.stringify(results, null, 2);
  return results;
}

report(run());
