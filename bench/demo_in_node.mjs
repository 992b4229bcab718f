// The demo's whole analysis (the module's `pdr_pipeline` on assets/demo-walk.csv) run
// `runs` times in one Node process: the first run on the cold module (V8's baseline
// tier, Liftoff, compiled as each function is first called), the later ones on what
// V8 has optimised meanwhile. Separates what the cold module costs from the page.
//
//   bench/module_vs_native.sh 1   # builds target/bench-node/pkg (opt-level "s")
//   node bench/demo_in_node.mjs target/bench-node/pkg [runs]
//   node --cpu-prof bench/demo_in_node.mjs target/bench-node/pkg 1   # where it goes
import { createRequire } from 'node:module';
import { readFileSync } from 'node:fs';
import { join, resolve } from 'node:path';

const [pkgDir, runsText] = process.argv.slice(2);
const wasm = createRequire(import.meta.url)(join(resolve(pkgDir), 'compass_pdr.js'));
const bytes = readFileSync(join(import.meta.dirname, '..', 'assets', 'demo-walk.csv'));
const times = [];
for (let run = 0; run < Number(runsText || 4); run += 1) {
  const started = performance.now();
  wasm.pdr_pipeline('demo-walk.csv', bytes);
  times.push(Math.round(performance.now() - started));
}
console.log(JSON.stringify({ first_run_ms: times[0], later_runs_ms: times.slice(1) }));
