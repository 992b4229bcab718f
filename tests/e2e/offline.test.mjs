// End-to-end tests of privacy and offline use: once the page has loaded (and kept its
// offline copy), using it makes no network request; after the first visit it works
// without a network.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { download, openPage, out, text, waitForState } from './common.mjs';

test('after load nothing goes over the network, and the page works offline after the first visit', async () => {
  const { page, context, problems, close } = await openPage({ acceptDownloads: true });
  await waitForState(page, 'ready', 'demo-walk.csv');
  await page.evaluate(() => navigator.serviceWorker.ready);

  // Using the page: a log dropped, analysed, exported. Nothing leaves the browser.
  const requests = [];
  context.on('request', (request) => {
    const url = request.url();
    if (!url.startsWith('blob:') && !url.startsWith('data:')) requests.push(url);
  });
  await page.setInputFiles('#file-input', { name: 'drop-walk.csv', mimeType: 'text/csv', buffer: readFileSync(join(out, 'drop-walk.csv')) });
  await waitForState(page, 'ready', 'drop-walk.csv');
  await download(page, '#export-report');
  await download(page, '#export-csv');
  assert.deepEqual(requests, [], 'no request after load');

  // Offline: the page, its module and the demo come from the service worker's copy.
  await context.setOffline(true);
  await page.reload();
  await waitForState(page, 'ready', 'demo-walk.csv');
  assert.match(await text(page, 'status'), /Analysed demo-walk\.csv: 12,000 magnetometer samples\./);
  await context.setOffline(false);
  assert.deepEqual(problems, []);
  await close();
});
