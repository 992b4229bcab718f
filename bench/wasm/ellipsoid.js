// The ellipsoid-fit benchmark in the browser: the release module's `fit_ellipsoid_xyz`
// (the Float64Array copied into the module's memory, the fit, the result converted to a
// JS object) on each sample set, algebraic only (`refine = false`, what numpy's
// Li-Griffiths peer does) and with the Levenberg-Marquardt refinement. One warm-up call,
// then `runs` timed samples; the median is reported. performance.now() is coarsened to
// 0.1 ms in a page that is not cross-origin isolated, so a sample of the smaller sets
// times several calls (`calls`, 10⁵ / n of them) and reports the time per call. The result is left in
// `window.benchResults` (or `window.benchError`) for bench/wasm-bench.mjs.
import { report } from './report.js';
import init, { fit_ellipsoid_xyz } from './pkg/compass_pdr.js';

const SIZES = [1000, 10000, 100000, 1000000];

function median(values) {
  const sorted = [...values].sort((a, b) => a - b);
  const mid = Math.floor(sorted.length / 2);
  return sorted.length % 2 ? sorted[mid] : (sorted[mid - 1] + sorted[mid]) / 2;
}

async function run() {
  const params = new URLSearchParams(location.search);
  const runs = Math.max(1, Number(params.get('runs') || 5));
  await init();
  const results = { runs, fits: {} };
  for (const n of SIZES) {
    const url = `data/sphere_${n}.f64`;
    const response = await fetch(url);
    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
    const xyz = new Float64Array(await response.arrayBuffer());
    if (xyz.length !== 3 * n) throw new Error(`${url}: ${xyz.length} numbers, expected ${3 * n}`);
    const calls = Math.max(1, Math.round(100000 / n));
    const entry = { calls };
    for (const [name, refine] of [['algebraic', false], ['refined', true]]) {
      let fit = fit_ellipsoid_xyz(xyz, refine);
      const ms = [];
      for (let i = 0; i < runs; i += 1) {
        const start = performance.now();
        for (let call = 0; call < calls; call += 1) fit = fit_ellipsoid_xyz(xyz, refine);
        ms.push((performance.now() - start) / calls);
      }
      entry[name] = {
        ms: ms.map((value) => Math.round(value * 1000) / 1000),
        median_ms: median(ms),
        model: fit.model,
        hard_iron_ut: fit.calibration.hard_iron_ut,
        refined: fit.refined,
      };
    }
    results.fits[n] = entry;
    document.getElementById('status').textContent = JSON.stringify(results, null, 2);
  }
  return results;
}

report(run());
