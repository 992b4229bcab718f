// End-to-end tests of WebAssembly threads: served as ./run serves it (COOP/COEP headers),
// the page loads its threaded module and reads large files on every core; served
// without those headers it reads them on one thread. Both must show the same results.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { openPage, out, plainUrl, text } from './common.mjs';

/** A GPS log of `nEpochs` at 10 Hz (RMC and GGA each, CRLF), with a bad checksum
 * every 5,000 epochs: about 70 bytes per sentence. */
function nmeaLog(nEpochs) {
  const checksum = (body) => {
    let sum = 0;
    for (const char of body) sum ^= char.charCodeAt(0);
    return sum.toString(16).toUpperCase().padStart(2, '0');
  };
  const pad = (value) => String(value).padStart(2, '0');
  const lines = [];
  for (let epoch = 0; epoch < nEpochs; epoch += 1) {
    const t = epoch / 10;
    const time = `${pad(Math.floor(t / 3600))}${pad(Math.floor(t / 60) % 60)}${(t % 60).toFixed(2).padStart(5, '0')}`;
    const lat = (4808 + epoch * 0.00002).toFixed(5);
    const rmc = `GPRMC,${time},A,${lat},N,01134.80000,E,2.5,45.0,221126,,,A`;
    const gga = `GPGGA,${time},${lat},N,01134.80000,E,1,08,0.9,520.0,M,47.0,M,,`;
    lines.push(`$${rmc}*${checksum(rmc)}`, `$${gga}*${checksum(gga)}`);
    if (epoch % 5000 === 4999) lines.push(`$${rmc}*00`);
  }
  return Buffer.from(`${lines.join('\r\n')}\r\n`);
}

/** What the page shows of a file once it is read: the status, what was read, and the
 * statistics table. */
async function shown(page, fileName) {
  await page.waitForSelector(`body[data-state="ready"][data-file="${fileName}"], body[data-state="error"]`, { timeout: 60_000 });
  return page.evaluate(() => ({
    state: document.body.dataset.state,
    status: document.getElementById('status').textContent,
    streams: document.getElementById('streams').textContent,
    table: document.getElementById("methods").textContent,
  }));
}

async function threadsOf(page) {
  const cores = await page.evaluate(() => Math.min(navigator.hardwareConcurrency || 1, 32));
  await page.waitForFunction((n) => document.body.dataset.threads === String(n), cores, { timeout: 15_000 });
  return cores;
}

test('cross-origin isolated, the page reads large files on every core, as on one thread', async () => {
  const threaded = await openPage();
  const plain = await openPage({ url: plainUrl });
  assert.equal(await threaded.page.evaluate(() => self.crossOriginIsolated), true, 'served with COOP/COEP');
  assert.equal(await plain.page.evaluate(() => self.crossOriginIsolated), false);
  const cores = await threadsOf(threaded.page);
  assert.match(await text(threaded.page, 'engine'), new RegExp(`read on ${cores} of this computer's ${cores} threads`));
  assert.equal(await plain.page.evaluate(() => document.body.dataset.threads), '1');
  assert.match(await text(plain.page, 'engine'), /read on one thread: this page is not cross-origin isolated/);
  console.log(`threads: ${cores} (navigator.hardwareConcurrency)`);

  // A 51 MB walk (canonical CSV) and an 8 MB GPS log: chunks of 4 MiB, each read in
  // parts on every thread. What the page shows of them is the same on one thread.
  const nmea = { name: 'track.nmea', mimeType: 'text/plain', buffer: nmeaLog(60_000) };
  for (const [file, fileName] of [[join(out, 'large-walk.csv'), 'large-walk.csv'], [nmea, 'track.nmea']]) {
    const results = [];
    for (const { page } of [threaded, plain]) {
      const started = Date.now();
      await page.setInputFiles('#file-input', file);
      results.push({ ...(await shown(page, fileName)), ms: Date.now() - started });
    }
    const [onThreads, onOne] = results;
    console.log(`${fileName}: ${onThreads.ms} ms on ${cores} threads, ${onOne.ms} ms on one (read and analysed)`);
    assert.equal(onThreads.state, onOne.state, fileName);
    assert.equal(onThreads.status, onOne.status, fileName);
    assert.equal(onThreads.streams, onOne.streams, fileName);
    assert.equal(onThreads.table, onOne.table, fileName);
    if (fileName === 'track.nmea') {
      // No magnetometer: the page says what the log holds (one fix per epoch, RMC and
      // GGA merged; the sentences with a bad checksum skipped).
      assert.equal(onThreads.state, 'error');
      assert.match(onThreads.status, /^track\.nmea holds no magnetometer samples, only 60,000 GNSS fixes\. To calibrate, drop it together with the log that has the magnetometer/);
    } else {
      assert.match(onThreads.status, /Analysed large-walk\.csv: 450,000 magnetometer samples\./);
    }
  }
  await threaded.page.screenshot({ path: join(out, 'threads.png'), fullPage: true });
  assert.deepEqual(threaded.problems, []);
  assert.deepEqual(plain.problems, []);
  await threaded.close();
  await plain.close();
});
