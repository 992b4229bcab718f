// The same recording dropped several times on one page, in headless Chromium: the
// first drop runs the module's code as V8 first compiles it (its baseline tier), the
// later ones on the code it has optimised meanwhile. Prints, per recording, the time
// from the choice of the files to the answer in the summary for each drop: how much of
// the page's time is the cold module (BENCHMARKS.md, issue 20).
//
//   python3 scripts/serve.py 8877 www &
//   node bench/redrop.mjs http://127.0.0.1:8877/ [drops] [../shared/data]
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { lastDropTiming, openBenchPage, recordings } from '../tests/e2e/drops.mjs';

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const { chromium } = await import(join(root, 'tests/e2e/node_modules/playwright-core/index.mjs'));
const [url, dropsText, dataDir] = process.argv.slice(2);
const drops = Number(dropsText || 4);
/** A few recordings of each kind of file (ULog, DataFlash, phone text logs and folders,
 * a board's CSVs), of the list the end-to-end test drops. */
const chosen = ['px4-sample', 'ardupilot-log171', 'msft-f1', 'qmc5883l-calibration', 'sensorlogger-walk-ethz',
  'tyrex-Thibaud_Nexus5_Dist_FrontPocket'];
const all = new Map(recordings(dataDir || join(root, '..', 'shared', 'data')));
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-background-networking'],
});
console.log(`| recording | ${Array.from({ length: drops }, (_, k) => `drop ${k + 1}`).join(' | ')} |`);
console.log(`|---|${'---:|'.repeat(drops)}`);
for (const name of chosen) {
  const files = all.get(name);
  const { context, page } = await openBenchPage(browser, url);
  const times = [];
  for (let drop = 0; drop < drops; drop += 1) {
    // The next "ready" or "error", and the next grade, are this drop's.
    await page.evaluate(() => {
      document.body.dataset.state = 'dropped';
      document.getElementById('summary').removeAttribute('data-grade');
    });
    await page.setInputFiles('#file-input', files);
    await page.waitForFunction(() => ['ready', 'error'].includes(document.body.dataset.state), null, { timeout: 100_000 });
    times.push((await lastDropTiming(page)).dropToSummaryMs);
  }
  console.log(`| ${name} | ${times.map((ms) => `${ms.toFixed(0)} ms`).join(' | ')} |`);
  await context.close();
}
await browser.close();
