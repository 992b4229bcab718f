// What V8 compiles with its optimising tier (TurboFan) during a recording's first drop
// (issue 45): each recording dropped once on a fresh page after the analysis worker's
// warm-up, in headless Chromium with `--js-flags=--trace-wasm-compilation-times`, and the
// compiles logged from the drop to the page's ready state (every figure drawn; the page's
// own thread runs the module too) summed per function, the drop 0.5 s after the warm-up.
// A first drop is slower than the next when code the warm-up did not make hot turns hot:
// V8 then compiles it on a background thread, taking one of the machine's cores from
// the worker and its pool, and the running call keeps its baseline code.
//
//   KEEP_WASM_NAMES=1 ./run            (or: python3 scripts/serve.py 8877 www, after
//                                       building the page with KEEP_WASM_NAMES=1)
//   node bench/first_drop_compiles.mjs http://127.0.0.1:8877/ [../shared/data] [name...]
//
// Function names come from the served module's name section (kept by scripts/setup.sh
// when KEEP_WASM_NAMES=1); without one, functions are named by their index.
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { openBenchPage, recordings } from '../tests/e2e/drops.mjs';

/** The browser's output lines, as they come: playwright-core prints them on this
 * process's stderr under `DEBUG=pw:browser`, set before it is loaded. */
const lines = [];
process.env.DEBUG = 'pw:browser';
const writeStderr = process.stderr.write.bind(process.stderr);
process.stderr.write = (chunk, ...rest) => {
  const text = `${chunk}`;
  if (!text.includes('pw:browser')) return writeStderr(chunk, ...rest);
  lines.push(...text.split('\n'));
  return true;
};
const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const { chromium } = await import(join(root, 'tests/e2e/node_modules/playwright-core/index.mjs'));
const [url, dataDir, ...names] = process.argv.slice(2);
const all = recordings(dataDir || join(root, '..', 'shared', 'data'));
const chosen = names.length ? all.filter(([name]) => names.includes(name)) : all;

/** Function index → name, from a module's `name` section (none: an empty map). */
function functionNames(bytes) {
  const names = new Map();
  const [section] = WebAssembly.Module.customSections(new WebAssembly.Module(bytes), 'name');
  if (!section) return names;
  const data = new Uint8Array(section);
  let at = 0;
  const leb = () => {
    let value = 0;
    let shift = 0;
    for (;;) {
      const byte = data[at++];
      value += (byte & 0x7f) * 2 ** shift;
      shift += 7;
      if (byte < 0x80) return value;
    }
  };
  while (at < data.length) {
    const id = data[at++];
    const size = leb();
    const end = at + size;
    if (id === 1) {
      for (let count = leb(); count > 0; count -= 1) {
        const idx = leb();
        const length = leb();
        names.set(idx, new TextDecoder().decode(data.subarray(at, at + length)));
        at += length;
      }
    }
    at = end;
  }
  return names;
}

const wasm = await (await fetch(new URL('pkg-threads/compass_pdr_bg.wasm', url))).arrayBuffer();
const fnNames = functionNames(wasm);
const shortName = (idx) => (fnNames.get(idx) ?? `wasm-function#${idx}`).replace(/\[[0-9a-f]+\]/g, '').slice(0, 70);

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-background-networking',
    '--js-flags=--trace-wasm-compilation-times'],
});
console.log('| recording | TurboFan compiles during the first drop | ms | the three longest (ms) |');
console.log('|---|---:|---:|---|');
for (const [name, files] of chosen) {
  const { context, page } = await openBenchPage(browser, url, { warm: true });
  await page.waitForTimeout(500);
  const from = lines.length;
  await page.evaluate(() => {
    document.body.dataset.state = 'dropped';
  });
  await page.setInputFiles('#file-input', files);
  await page.waitForFunction(() => ['ready', 'error'].includes(document.body.dataset.state), null, { timeout: 100_000 });
  const compiles = lines.slice(from).flatMap((line) => {
    const match = line.match(/using TurboFan, took (\d+) μs.*wasm-function#(\d+)/);
    return match ? [{ us: Number(match[1]), idx: Number(match[2]) }] : [];
  });
  const totalMs = compiles.reduce((sum, { us }) => sum + us, 0) / 1000;
  const longest = compiles.sort((a, b) => b.us - a.us).slice(0, 3)
    .map(({ us, idx }) => `${shortName(idx)} (${(us / 1000).toFixed(0)})`).join(', ');
  console.log(`| ${name} | ${compiles.length} | ${totalMs.toFixed(0)} | ${longest} |`);
  await context.close();
}
await browser.close();
