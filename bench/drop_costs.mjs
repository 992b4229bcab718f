// Where a drop's time goes on the page, the analysis apart from the page's fixed costs
// (issue 45): each recording dropped on the page as a person drops it (headless
// Chromium, the page cross-origin isolated as ./run serves it, so the analysis runs on
// its worker), twice on one page (the second on the module V8 has optimised), and the
// second drop's time split by the worker's and the page's marks:
//
// - hand-off in: from the file input's `change` to the worker's start of the job (the
//   page listing the files and posting the job);
// - read: the worker waiting for the dropped files' bytes (the blob read);
// - analysis: the import and the pipeline in the worker (what the module does headless);
// - hand-off out: from the analysis's end to the page's hearing of it;
// - summary: from then to the answer in the summary (the verdict and the lists' DOM);
// - picture: to the answer's picture drawn; figures: to every figure drawn (`ready`).
//
//   python3 scripts/serve.py 8877 www &
//   node bench/drop_costs.mjs http://127.0.0.1:8877/ [../shared/data] [name...]
//
// With DROP=1 in the environment, the first drop's split instead (a fresh page's, on the
// code V8 has compiled for the demo only). With PAUSE_MS=N, each drop comes N ms after
// the page is ready, as a person's drop comes after they picked the file (V8 optimises
// the demo's hot code in the background meanwhile); without it, at once. With WARM=1,
// the first drop waits for the analysis worker's warm-up (www/analysis-worker.js: small
// logs of every format analysed while the user picks a file) to end.
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { openBenchPage, recordings } from '../tests/e2e/drops.mjs';

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const { chromium } = await import(join(root, 'tests/e2e/node_modules/playwright-core/index.mjs'));
const [url, dataDir, ...names] = process.argv.slice(2);
const all = recordings(dataDir || join(root, '..', 'shared', 'data'));
const chosen = names.length ? all.filter(([name]) => names.includes(name)) : all;
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-background-networking'],
});
const columns = ['hand-off in', 'read', 'analysis', 'hand-off out', 'summary', 'drop to summary', 'picture', 'figures'];
console.log(`| recording | ${columns.join(' | ')} | fixed part (drop to summary − analysis) |`);
console.log(`|---|${'---:|'.repeat(columns.length + 1)}`);
const ms = (value) => (Number.isFinite(value) ? `${value.toFixed(0)}` : '–');
for (const [name, files] of chosen) {
  const { context, page } = await openBenchPage(browser, url, { warm: process.env.WARM === '1' });
  let split = null;
  const drops = process.env.DROP === '1' ? 1 : 2;
  for (let drop = 0; drop < drops; drop += 1) {
    await page.waitForTimeout(Number(process.env.PAUSE_MS || 0));
    await page.evaluate(() => {
      document.body.dataset.state = 'dropped';
      document.getElementById('summary').removeAttribute('data-grade');
      window.__jobTimings = [];
    });
    await page.setInputFiles('#file-input', files);
    await page.waitForFunction(() => ['ready', 'error'].includes(document.body.dataset.state), null, { timeout: 100_000 });
    split = await page.evaluate(() => {
      const perf = window.__perf;
      const origin = performance.timeOrigin;
      const dropAt = origin + perf.changes.at(-1);
      const job = window.__jobTimings.at(-1);
      const summaryAt = origin + perf.summaries.find((at) => origin + at > dropAt);
      const readyAt = origin + perf.states.find(({ state, at }) => origin + at > dropAt && state === 'ready').at;
      const pictureAt = origin + Number(document.getElementById('answer-figure').dataset.drawnAt);
      return {
        'hand-off in': job.startAt - dropAt,
        read: job.blobMs,
        analysis: job.analysedAt - job.startAt - job.blobMs,
        'hand-off out': job.receivedAt - job.analysedAt,
        summary: summaryAt - job.receivedAt,
        'drop to summary': summaryAt - dropAt,
        picture: pictureAt - summaryAt,
        figures: readyAt - pictureAt,
      };
    });
  }
  const fixed = split['drop to summary'] - split.analysis;
  console.log(`| ${name} | ${columns.map((column) => ms(split[column])).join(' | ')} | ${ms(fixed)} |`);
  await context.close();
}
await browser.close();
