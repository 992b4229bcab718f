// Dropping the real recordings on the page, for the end-to-end tests (real.test.mjs,
// page.test.mjs through common.mjs) and the page's benchmarks (bench/redrop.mjs): which
// files make each recording of ../shared/data, and the page's timings of a drop. Needs
// neither the test runner nor ./test's environment.
import { readdirSync, statSync } from 'node:fs';
import { join } from 'node:path';

/** A folder's files as a person drops them (its subfolders are recordings of their own). */
export function dropped(dir) {
  return readdirSync(dir)
    .filter((name) => !/^licen|\.md$/i.test(name))
    .map((name) => join(dir, name))
    .filter((path) => statSync(path).isFile())
    .sort();
}

/** One entry per recording of the data README (`data`: the folder ../shared/data): a
 * short name and the files dropped. */
export function recordings(data) {
  const at = (...parts) => join(data, ...parts);
  const list = [
    ['msft-f1', dropped(at('msft-indoor-2020', 'site1', 'F1'))],
    ['msft-f4', dropped(at('msft-indoor-2020', 'site1', 'F4'))],
    ['vehicle-pixel6a', dropped(at('vehicle-pixel6a'))],
    ['phyphox-hallway-loop', dropped(at('phyphox-hallway-loop'))],
    ['sensorlogger-walk-ethz', dropped(at('sensorlogger-walk-ethz'))],
    // The folder dropped whole: the filtered and the raw export of one calibration.
    ['qmc5883l-calibration', dropped(at('qmc5883l-calibration'))],
    ['qmc5883l-noisy', [at('qmc5883l-calibration', 'noisy_raw_data.csv')]],
    ['ardupilot-log171', dropped(at('ardupilot-copter-log171'))],
    ['ardupilot-text-log', dropped(at('ardupilot-text-log'))],
    ['px4-sample', [at('px4-ulog', 'sample.ulg')]],
    ['px4-sample-small', [at('px4-ulog', 'sample_log_small.ulg')]],
  ];
  for (const trial of readdirSync(at('hmc5883l-sphere')).sort()) {
    if (statSync(at('hmc5883l-sphere', trial)).isDirectory()) list.push([`hmc5883l-${trial}`, dropped(at('hmc5883l-sphere', trial))]);
  }
  for (const folder of ['tyrex-attitude', 'tyrex-attitude-more']) {
    for (const trial of readdirSync(at(folder)).sort()) {
      if (statSync(at(folder, trial)).isDirectory()) list.push([`tyrex-${trial}`, dropped(at(folder, trial))]);
    }
  }
  // The IPIN 2023 walks: one GetSensorData file each.
  for (const walk of readdirSync(at('ipin2023-track3-walks')).filter((name) => name.endsWith('.txt')).sort()) {
    list.push([`ipin-${walk.replace(/^IPIN2023_T3_Training|\.txt$/g, '')}`, [at('ipin2023-track3-walks', walk)]]);
  }
  return list;
}

/** An init script (for `openPage`) that records the main thread's long tasks (over 50 ms,
 * the browser's own threshold) and the times of the inputs' `change` events, of the
 * body's state changes and of each answer put in the summary (its grade set), on the
 * page's clock. */
export function recordMainThread() {
  const perf = { longTasks: [], changes: [], states: [], summaries: [] };
  window.__perf = perf;
  new PerformanceObserver((list) => {
    for (const entry of list.getEntries()) perf.longTasks.push({ start: entry.startTime, duration: entry.duration });
  }).observe({ type: 'longtask', buffered: true });
  document.addEventListener('change', () => perf.changes.push(performance.now()), true);
  const watchBody = () => {
    new MutationObserver(() => {
      const state = document.body.dataset.state;
      if (perf.states.at(-1)?.state !== state) perf.states.push({ state, at: performance.now() });
    }).observe(document.body, { attributes: true, attributeFilter: ['data-state'] });
    const summary = document.getElementById('summary');
    new MutationObserver(() => {
      if (summary.dataset.grade) perf.summaries.push(performance.now());
    }).observe(summary, { attributes: true, attributeFilter: ['data-grade'] });
  };
  if (document.body) watchBody(); else document.addEventListener('DOMContentLoaded', watchBody);
}

/** A fresh desktop-sized page of `browser` at `url` for the benchmarks, recording its main
 * thread (`recordMainThread`): once the page is ready and, with `warm`, once the analysis
 * worker's warm-up has ended (www/analysis-worker.js). Returns its context and the page. */
export async function openBenchPage(browser, url, { warm = false } = {}) {
  const context = await browser.newContext({ viewport: { width: 1360, height: 900 } });
  const page = await context.newPage();
  await page.addInitScript(recordMainThread);
  await page.goto(url);
  await page.waitForSelector('body[data-state="ready"]', { timeout: 30_000 });
  if (warm) await page.waitForSelector('body[data-warmed-up-ms]', { state: 'attached', timeout: 60_000 });
  return { context, page };
}

/** After `recordMainThread`: from the last file chosen to its answer in the summary and
 * to the next `ready` or `error` (every figure drawn), and the main thread's long tasks
 * meanwhile. */
export async function lastDropTiming(page) {
  return page.evaluate(() => {
    const perf = window.__perf;
    const chosenAt = perf.changes.at(-1);
    const end = perf.states.find(({ state, at }) => at > chosenAt && ['ready', 'error'].includes(state));
    const endAt = end?.at ?? performance.now();
    const tasks = perf.longTasks.filter(({ start, duration }) => start + duration > chosenAt && start < endAt);
    const summaryAt = perf.summaries.find((at) => at > chosenAt) ?? endAt;
    return {
      dropToSummaryMs: summaryAt - chosenAt,
      dropToReadyMs: endAt - chosenAt,
      longTasks: tasks.length,
      longestTaskMs: Math.max(0, ...tasks.map(({ duration }) => duration)),
    };
  });
}
