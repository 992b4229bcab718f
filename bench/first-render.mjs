// Time to first render of the demo, in headless Chromium: loads the served page `runs`
// times in fresh contexts (no cache, no service worker) and reports, from navigation
// start, when the answer was in the summary, when the first plot was drawn and when
// every figure was (the page's `ready`), as the page records them on its body.
//
//   ./run &   # serves the page on http://127.0.0.1:8000/
//   node bench/first-render.mjs http://127.0.0.1:8000/ [runs]
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const { chromium } = await import(join(root, 'tests/e2e/node_modules/playwright-core/index.mjs'));

const [url, runsText] = process.argv.slice(2);
const runs = Number(runsText || 5);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-background-networking'],
});
const median = (values) => [...values].sort((a, b) => a - b)[Math.floor(values.length / 2)];
const summary = [];
const first = [];
const ready = [];
for (let run = 0; run < runs; run += 1) {
  const context = await browser.newContext({ viewport: { width: 1360, height: 1000 }, serviceWorkers: 'block' });
  const page = await context.newPage();
  await page.goto(url);
  await page.waitForSelector('body[data-state="ready"][data-file="demo-walk.csv"]', { timeout: 30_000 });
  const times = await page.evaluate(() => [Number(document.body.dataset.firstPlotMs), Number(document.body.dataset.readyMs), Number(document.body.dataset.summaryMs)]);
  first.push(times[0]);
  ready.push(times[1]);
  summary.push(times[2]);
  await context.close();
}
await browser.close();
console.log(JSON.stringify({ runs, summary_ms: summary, first_plot_ms: first, ready_ms: ready, median_summary_ms: median(summary), median_first_plot_ms: median(first), median_ready_ms: median(ready) }));
