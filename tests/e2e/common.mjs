// What every end-to-end test file needs: the browser, a fresh page with its errors
// collected, and small readers of the page. ./test sets E2E_BASE_URL and E2E_OUT.
import { before, after } from 'node:test';
import { chromium } from 'playwright-core';

export const baseUrl = process.env.E2E_BASE_URL;
/** The same site served without the cross-origin isolation headers: one thread. */
export const plainUrl = process.env.E2E_PLAIN_URL;
export const out = process.env.E2E_OUT;
if (!baseUrl || !plainUrl || !out) {
  throw new Error('E2E_BASE_URL, E2E_PLAIN_URL and E2E_OUT must be set: run the end-to-end tests through ./test');
}

let browser;
before(async () => {
  browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage', '--disable-quic', '--no-first-run',
           '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
});
after(async () => { await browser?.close(); });

/** A fresh page at the site, with console errors and page errors collected.
 * `initScript` (a function and its argument) runs in the page before its own scripts. */
export async function openPage({ initScript, initArg, acceptDownloads = false, viewport = { width: 1360, height: 1000 }, deviceScaleFactor = 1, url = baseUrl } = {}) {
  const context = await browser.newContext({ viewport, acceptDownloads, deviceScaleFactor });
  const page = await context.newPage();
  if (initScript) await page.addInitScript(initScript, initArg);
  const problems = [];
  page.on('pageerror', (error) => problems.push(`page error: ${error.message}`));
  page.on('console', (message) => { if (message.type() === 'error') problems.push(`console: ${message.text()}`); });
  await page.goto(url);
  return { page, context, problems, close: () => context.close() };
}

export async function waitForState(page, state, fileName) {
  const selector = fileName ? `body[data-state="${state}"][data-file="${fileName}"]` : `body[data-state="${state}"]`;
  await page.waitForSelector(selector, { timeout: 15_000 });
}

/** One pass over a canvas's pixels: how many are drawn (not white), how many are in the
 * strong red the plots use for what is missing (the live 3D view's regions with no
 * sample; not the orange of raw samples), and a digest of them all (to tell whether it
 * was redrawn differently). */
function canvasPixels(page, id) {
  return page.evaluate((canvasId) => {
    const canvas = document.getElementById(canvasId);
    const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
    let drawn = 0;
    let red = 0;
    let digest = 0;
    let message = 0;
    for (let i = 0; i < data.length; i += 4) {
      const [r, g, b] = [data[i], data[i + 1], data[i + 2]];
      if (r < 250 || g < 250 || b < 250) drawn += 1;
      // The background of a plot replaced by a message (`canvas::draw_message`).
      if (r === 250 && g === 246 && b === 240) message += 1;
      if (r > 150 && r - g > 80 && g - b < 40) red += 1;
      for (let k = 0; k < 4; k += 1) digest = (digest * 31 + data[i + k]) | 0;
    }
    return { drawn, red, digest, message, total: data.length / 4 };
  }, id);
}

/** Pixels of a canvas that are not white. */
export const drawnPixels = async (page, id) => (await canvasPixels(page, id)).drawn;

/** Whether a canvas holds a plot: thousands of pixels drawn (axes, labels, data), and
 * not a message in the plot's place (its background covers the canvas). */
export async function plotDrawn(page, id) {
  const { drawn, message, total } = await canvasPixels(page, id);
  return { drawn, isPlot: drawn > 5_000 && message < total / 2, isMessage: message >= total / 2 };
}

/** Pixels of a canvas in the plots' strong red (see `canvasPixels`). */
export const redPixels = async (page, id) => (await canvasPixels(page, id)).red;

/** A digest of a canvas's pixels. */
export const canvasDigest = async (page, id) => (await canvasPixels(page, id)).digest;

/** Waits until the canvas is drawn differently from `digest` (at most `timeoutMs`). */
export async function waitForRedraw(page, id, digest, timeoutMs = 5_000) {
  const until = Date.now() + timeoutMs;
  while ((await canvasDigest(page, id)) === digest) {
    if (Date.now() > until) throw new Error(`#${id} was not redrawn within ${timeoutMs} ms`);
    await new Promise((resolve) => setTimeout(resolve, 50));
  }
}

export const text = (page, id) => page.textContent(`#${id}`);

/** Opens every folded section of the page (the details under the summary), as a person
 * who wants the plots, the settings or the lists does. */
export const openAllDetails = (page) => page.evaluate(() => document.querySelectorAll('details').forEach((details) => { details.open = true; }));

/** Clicks `selector` and returns the bytes of the download it starts, with its name. */
export async function download(page, selector) {
  const [file] = await Promise.all([page.waitForEvent('download'), page.click(selector)]);
  const stream = await file.createReadStream();
  const chunks = [];
  for await (const chunk of stream) chunks.push(chunk);
  return { name: file.suggestedFilename(), bytes: Buffer.concat(chunks) };
}

// The drop timings live in drops.mjs (the benchmarks use them without the test runner).
export { lastDropTiming, recordMainThread } from './drops.mjs';
