// The PDR benchmark in the browser, on the inputs of benches/pdr.rs:
// - EKF: the release module's `pdr_ekf_steps` runs every step of pdr_steps.f64 through
//   the filter (the Float64Array is copied into the module's memory on each call; the
//   same call with 0 steps times that copy alone, `copy_ms`);
// - pipeline: `pdr_pipeline` (import and pdr::run with the default options) on the bytes
//   of the simulated hour (copied into the module's memory on each call).
// One warm-up call of each, then `runs` timed calls of the EKF and min(runs, 3) of the
// pipeline; medians are reported. The result is left in `window.benchResults` (or
// `window.benchError`) for bench/wasm-bench.mjs.
import { report } from './report.js';
import init, { pdr_ekf_steps, pdr_pipeline } from './pkg/compass_pdr.js';

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

function timeCalls(count, call) {
  let value = call();
  const ms = [];
  for (let i = 0; i < count; i += 1) {
    const start = performance.now();
    value = call();
    ms.push(performance.now() - start);
  }
  return { ms, value };
}

async function run() {
  const params = new URLSearchParams(location.search);
  const runs = Math.max(1, Number(params.get('runs') || 5));
  await init();
  const settings = await (await fetchOk('data/pdr_settings.json')).json();
  const steps = new Float64Array(await (await fetchOk('data/pdr_steps.f64')).arrayBuffer());
  if (steps.length !== 2 * settings.n_steps) {
    throw new Error(`pdr_steps.f64: ${steps.length} numbers, expected ${2 * settings.n_steps}`);
  }
  const [east, north] = settings.start_en_m;
  const sigma = settings.start_sigma_m;
  const status = document.getElementById('status');

  const ekf = timeCalls(runs, () => pdr_ekf_steps(steps, settings.n_steps, east, north, sigma));
  const copy = timeCalls(runs, () => pdr_ekf_steps(steps, 0, east, north, sigma));
  const ekfMs = median(ekf.ms);
  const results = {
    runs,
    ekf: {
      n_steps: settings.n_steps,
      ms: ekf.ms.map((value) => Math.round(value * 10) / 10),
      median_ms: ekfMs,
      copy_ms: median(copy.ms),
      steps_per_s: settings.n_steps / (ekfMs / 1e3),
      x: Array.from(ekf.value.slice(0, 4)),
      p: Array.from(ekf.value.slice(4)),
    },
  };
  status.textContent = JSON.stringify(results, null, 2);

  const bytes = new Uint8Array(await (await fetchOk(`data/${settings.hour_file}`)).arrayBuffer());
  const pipeline = timeCalls(Math.min(runs, 3), () => pdr_pipeline(settings.hour_file, bytes));
  results.pipeline = {
    bytes: bytes.length,
    runs: pipeline.ms.length,
    ms: pipeline.ms.map((value) => Math.round(value)),
    median_ms: median(pipeline.ms),
    ...pipeline.value,
  };
  status.textContent = JSON.stringify(results, null, 2);
  return results;
}

report(run());
