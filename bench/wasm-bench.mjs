// Runs a benchmark page in headless Chromium: serves bench/wasm/ (the pages),
// target/bench-wasm/pkg/ (the release module, built by bench/run) as pkg/ and
// target/bench-data/ (the inputs) as data/ on 127.0.0.1, opens the page with
// playwright-core driving /usr/bin/chromium, waits for its results and prints them as
// JSON on stdout.
//
// Usage: node bench/wasm-bench.mjs [--runs N] [--page PAGE] [--threads [--workers N]]   (bench/run
// builds the modules and the inputs first). --threads: the threaded module
// (target/bench-wasm/pkg-threads/ as pkg-threads/, with www/threads.js and
// www/pool-worker.js); the server always sends the COOP/COEP headers that allow it. PAGE is index.html (import, the default),
// ellipsoid.html (ellipsoid fit), mlp.html (MLP training; bench/mlp.sh) or pdr.html (PDR EKF
// and pipeline; bench/pdr.sh).
import { createServer } from 'node:http';
import { createReadStream, existsSync, statSync } from 'node:fs';
import { dirname, extname, join, normalize, resolve, sep } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '..');
const { chromium } = await import(join(root, 'tests/e2e/node_modules/playwright-core/index.mjs'));

const runsIdx = process.argv.indexOf('--runs');
const runs = runsIdx > 0 ? Number(process.argv[runsIdx + 1]) : 5;
const pageIdx = process.argv.indexOf('--page');
const pageName = pageIdx > 0 ? process.argv[pageIdx + 1] : 'index.html';
const threads = process.argv.includes('--threads');
const workersIdx = process.argv.indexOf('--workers');
const workers = workersIdx > 0 ? `&workers=${Number(process.argv[workersIdx + 1])}` : '';
const INPUTS_OF_PAGE = {
  'index.html': ['target/bench-data/walk.csv', 'target/bench-data/track.nmea'],
  'ellipsoid.html': [1000, 10000, 100000, 1000000].map((n) => `target/bench-data/sphere_${n}.f64`),
  'mlp.html': ['target/bench-data/mlp_samples.f64', 'target/bench-data/mlp_settings.json'],
  'pdr.html': ['target/bench-data/pdr_steps.f64', 'target/bench-data/pdr_settings.json', 'target/bench-data/pdr_hour.csv'],
};
if (!(pageName in INPUTS_OF_PAGE)) {
  console.error(`--page must be one of ${Object.keys(INPUTS_OF_PAGE).join(', ')}`);
  process.exit(1);
}

const MOUNTS = [
  ['/pkg/', join(root, 'target/bench-wasm/pkg')],
  ['/pkg-threads/', join(root, 'target/bench-wasm/pkg-threads')],
  ['/threads.js', join(root, 'www/threads.js')],
  ['/pool-worker.js', join(root, 'www/pool-worker.js')],
  ['/data/', join(root, 'target/bench-data')],
  ['/', join(here, 'wasm')],
];
const TYPES = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.wasm': 'application/wasm',
};

const module = threads ? 'target/bench-wasm/pkg-threads/compass_pdr_bg.wasm' : 'target/bench-wasm/pkg/compass_pdr_bg.wasm';
for (const needed of [module, ...INPUTS_OF_PAGE[pageName]]) {
  if (!existsSync(join(root, needed))) {
    console.error(`${needed} is missing: run bench/run (it builds the module and the inputs)`);
    process.exit(1);
  }
}

/** The file a URL path names, or null when it is outside the served folders. */
function fileFor(urlPath) {
  const path = decodeURIComponent(urlPath === '/' ? '/index.html' : urlPath);
  for (const [prefix, dir] of MOUNTS) {
    if (!prefix.endsWith('/') && path === prefix) return dir;
    if (prefix.endsWith('/') && path.startsWith(prefix)) {
      const file = normalize(join(dir, path.slice(prefix.length)));
      return file.startsWith(dir + sep) ? file : null;
    }
  }
  return null;
}

const server = createServer((request, response) => {
  const file = fileFor(new URL(request.url, 'http://127.0.0.1').pathname);
  if (!file || !existsSync(file) || !statSync(file).isFile()) {
    response.writeHead(404).end('not found');
    return;
  }
  response.writeHead(200, {
    'Content-Type': TYPES[extname(file)] || 'application/octet-stream',
    'Content-Length': statSync(file).size,
    'Cache-Control': 'no-store',
    ...(threads ? {'Cross-Origin-Opener-Policy': 'same-origin',
    'Cross-Origin-Embedder-Policy': 'require-corp'} : {}),
  });
  createReadStream(file).pipe(response);
});
await new Promise((ready) => server.listen(0, '127.0.0.1', ready));
const url = `http://127.0.0.1:${server.address().port}/${pageName}?runs=${runs}${threads ? `&threads=1${workers}` : ''}`;

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync'],
});
let exitCode = 0;
try {
  const page = await browser.newPage();
  const problems = [];
  page.on('pageerror', (error) => problems.push(`page error: ${error.message}`));
  page.on('console', (message) => {
    if (message.type() === 'error') problems.push(`console: ${message.text()}`);
  });
  await page.goto(url);
  await page.waitForFunction(() => window.benchResults || window.benchError, null, {
    timeout: 600_000,
    polling: 500,
  });
  const { results, error } = await page.evaluate(() => ({
    results: window.benchResults,
    error: window.benchError,
  }));
  if (error) throw new Error(`the benchmark page failed: ${error}\n${problems.join('\n')}`);
  console.log(JSON.stringify({ chromium: browser.version(), ...results }, null, 2));
} catch (error) {
  console.error(String((error && error.stack) || error));
  exitCode = 1;
} finally {
  await browser.close();
  server.close();
}
process.exit(exitCode);
