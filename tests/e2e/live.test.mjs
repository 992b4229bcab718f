// End-to-end tests of live calibration over Web Serial, with a fake `navigator.serial`
// whose port streams MotionCal `Raw:` lines from a simulated, distorted board turned over
// the whole sphere, records what the page writes back, and answers a calibration packet
// with `Cal1:`/`Cal2:` lines as Adafruit's calibration sketch does.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { canvasDigest, download, drawnPixels, openPage, out, redPixels, text } from './common.mjs';

/** The simulated board (µT, sensor axes): what the calibration must find. */
const BOARD = {
  hardIronUt: [12.0, -7.5, 30.0],
  // Row by row; symmetric, near the identity.
  distortion: [[1.08, 0.03, -0.02], [0.03, 0.95, 0.01], [-0.02, 0.01, 1.02]],
  // The World Magnetic Model's field in Munich (48.14° N, 11.58° E) is about 48.6 µT.
  fieldUt: 48.6,
  // One sweep of the sphere takes this many lines (20 s at 1,000 lines/s).
  sweepLines: 20_000,
};

/** Runs in the page before its scripts: defines navigator.serial. Everything it sent
 * and received is in `window.fakeSerial`. */
function installFakeSerial({ board, linesPerS, totalLines, unplugAfterLines }) {
  const state = {
    sentText: '', linesSent: 0, written: [], openedWith: [], finished: false, unplugged: false,
    maxLagMs: 0,
  };
  window.fakeSerial = state;
  // Event-loop lag while streaming: how late a 50 ms timer fires.
  let expected = performance.now() + 50;
  setInterval(() => {
    const now = performance.now();
    state.maxLagMs = Math.max(state.maxLagMs, now - expected);
    expected = now + 50;
  }, 50);

  // A deterministic generator (SplitMix-like on 32 bits) for noise and chunk cuts.
  let seed = 12345;
  const random = () => {
    seed = (seed + 0x9e3779b9) | 0;
    let z = seed;
    z = Math.imul(z ^ (z >>> 16), 0x85ebca6b);
    z = Math.imul(z ^ (z >>> 13), 0xc2b2ae35);
    return ((z ^ (z >>> 16)) >>> 0) / 4294967296;
  };
  const line = (idx) => {
    const k = idx % board.sweepLines;
    const z = 1 - (2 * (k + 0.5)) / board.sweepLines;
    const r = Math.sqrt(1 - z * z);
    const azimuth = k * 2.399963;
    const truth = [r * Math.cos(azimuth), r * Math.sin(azimuth), z].map((v) => v * board.fieldUt);
    const counts = board.distortion.map((row, i) => {
      const ut = row[0] * truth[0] + row[1] * truth[1] + row[2] * truth[2] + board.hardIronUt[i] + (random() - 0.5) * 0.4;
      return Math.round(ut * 10);
    });
    return `Raw:0,0,8192,0,0,0,${counts.join(',')}\r\n`;
  };

  class FakePort {
    constructor() { this.readable = null; this.writable = null; this.controller = null; this.timer = null; }
    getInfo() { return { usbVendorId: 0x239a, usbProductId: 0x8014 }; }
    async open(options) {
      state.openedWith.push(options);
      const port = this;
      const encoder = new TextEncoder();
      const startedAt = performance.now();
      const linesBefore = state.linesSent;
      this.readable = new ReadableStream({
        start(controller) {
          port.controller = controller;
          port.timer = setInterval(() => {
            const due = Math.min(totalLines, linesBefore + Math.floor(((performance.now() - startedAt) / 1000) * linesPerS));
            let text = '';
            while (state.linesSent < due) {
              if (unplugAfterLines !== undefined && state.linesSent === unplugAfterLines && !state.unplugged) break;
              text += line(state.linesSent);
              state.linesSent += 1;
            }
            if (unplugAfterLines !== undefined && state.linesSent === unplugAfterLines && !state.unplugged) {
              // Half a line goes out, then the board is pulled.
              const half = line(state.linesSent).slice(0, 17);
              text += half;
              state.unplugged = true;
              port.send(text, encoder);
              clearInterval(port.timer);
              // An errored stream drops what the reader has not taken yet: the board
              // goes a moment after its last bytes, as a real one does.
              setTimeout(() => controller.error(new DOMException('The device has been lost.', 'NetworkError')), 200);
              return;
            }
            if (text) port.send(text, encoder);
            if (state.linesSent >= totalLines) { state.finished = true; }
          }, 10);
        },
        cancel() { clearInterval(port.timer); },
      });
      this.writable = new WritableStream({
        write(chunk) {
          state.written.push(...chunk);
          port.answer(encoder);
        },
      });
    }
    /** Sends text in up to three chunks cut at arbitrary bytes (a line may straddle two). */
    send(text, encoder) {
      state.sentText += text;
      const bytes = encoder.encode(text);
      let start = 0;
      const cuts = [random(), random()].map((f) => Math.floor(f * bytes.length)).sort((a, b) => a - b);
      for (const end of [...cuts, bytes.length]) {
        if (end > start) { this.controller.enqueue(bytes.slice(start, end)); start = end; }
      }
    }
    /** The sketch: a whole packet with a good CRC is stored and echoed. */
    answer(encoder) {
      const bytes = Uint8Array.from(state.written);
      if (bytes.length < 68 || bytes[0] !== 117 || bytes[1] !== 84) return;
      let crc = 0xffff;
      for (const byte of bytes.subarray(0, 68)) {
        crc ^= byte;
        for (let bit = 0; bit < 8; bit += 1) crc = crc & 1 ? (crc >>> 1) ^ 0xa001 : crc >>> 1;
      }
      if (crc !== 0) return;
      const view = new DataView(bytes.buffer, 2, 64);
      const f = Array.from({ length: 16 }, (_, i) => view.getFloat32(4 * i, true));
      const soft = [[f[10], f[13], f[14]], [f[13], f[11], f[15]], [f[14], f[15], f[12]]];
      const text = `Cal1:${[...f.slice(0, 9), f[9]].map((v) => v.toFixed(3)).join(',')}\r\n`
        + `Cal2:${soft.flat().map((v) => v.toFixed(4)).join(',')}\r\n`;
      state.echoed = true;
      this.send(text, encoder);
    }
    async close() { clearInterval(this.timer); }
    addEventListener() {}
    removeEventListener() {}
  }
  const serial = {
    async requestPort() { return new FakePort(); },
    async getPorts() { return []; },
    addEventListener() {},
    removeEventListener() {},
  };
  Object.defineProperty(Navigator.prototype, 'serial', { configurable: true, get: () => serial });
}

/** MotionCal's 68-byte packet for a calibration JSON, written here independently of the
 * crate: "uT", 16 little-endian float32 (6 zeros, hard iron, field, soft iron 00 11 22
 * 01 02 12), CRC-16 (0xA001 reflected, initial 0xFFFF) low byte first. */
function packetOf(calibration) {
  const bytes = new Uint8Array(68);
  bytes[0] = 117;
  bytes[1] = 84;
  const s = calibration.soft_iron;
  const floats = [0, 0, 0, 0, 0, 0, ...calibration.hard_iron, calibration.field,
    s[0][0], s[1][1], s[2][2], (s[0][1] + s[1][0]) / 2, (s[0][2] + s[2][0]) / 2, (s[1][2] + s[2][1]) / 2];
  const view = new DataView(bytes.buffer);
  floats.forEach((value, i) => view.setFloat32(2 + 4 * i, value, true));
  let crc = 0xffff;
  for (const byte of bytes.subarray(0, 66)) {
    crc ^= byte;
    for (let bit = 0; bit < 8; bit += 1) crc = crc & 1 ? (crc >>> 1) ^ 0xa001 : crc >>> 1;
  }
  bytes[66] = crc & 0xff;
  bytes[67] = crc >>> 8;
  return bytes;
}

const liveState = (page) => page.getAttribute('#live', 'data-live-state');

test('a live session at 1,000 lines/s for 30 s converges, loses no line, and the board confirms the packet', async () => {
  const totalLines = 30_000;
  const { page, problems, close } = await openPage({
    initScript: installFakeSerial, initArg: { board: BOARD, linesPerS: 1000, totalLines }, acceptDownloads: true,
  });
  await page.waitForSelector('#live[data-live-state="idle"]');
  assert.equal(await page.$eval('#live-baud', (select) => select.value), '115200');
  await page.fill('#live-lat', '48.14');
  await page.fill('#live-lon', '11.58');
  // The demo's analysis at load is a task of its own: measure the page while streaming.
  await page.waitForSelector('body[data-state="ready"]');
  await page.evaluate(() => { window.fakeSerial.maxLagMs = 0; });
  await page.click('#live-connect');
  await page.waitForSelector('#live[data-live-state="connected"]');
  assert.deepEqual(await page.evaluate(() => window.fakeSerial.openedWith), [{ baudRate: 115200 }]);
  await page.waitForFunction(() => document.getElementById('live-format').textContent === 'MotionCal Raw: counts');
  await page.screenshot({ path: join(out, 'live-streaming.png'), fullPage: false });

  await page.waitForFunction(() => window.fakeSerial.finished, null, { timeout: 60_000, polling: 200 });
  await page.waitForFunction((n) => document.getElementById('live-lines').textContent === String(n), totalLines,
    { timeout: 5_000 });
  const fake = await page.evaluate(() => ({ linesSent: window.fakeSerial.linesSent, maxLagMs: window.fakeSerial.maxLagMs }));
  assert.equal(fake.linesSent, totalLines);
  assert.equal(await text(page, 'live-skipped-count'), '0');
  console.log(`live: ${totalLines} lines in 30 s, the page's event loop at most ${fake.maxLagMs.toFixed(0)} ms late`);
  assert.ok(fake.maxLagMs < 250, `the page froze for ${fake.maxLagMs} ms`);
  // The refit and the redraw run on the page's thread (src/web/live_panel/drawing.rs):
  // each stays under the bound the page holds every main-thread task to.
  const longest = await page.evaluate(() => ({
    refit: Number(document.getElementById('live').dataset.longestRefitMs),
    draw: Number(document.getElementById('live').dataset.longestDrawMs),
  }));
  console.log(`live: the longest refit ${longest.refit.toFixed(1)} ms, the longest redraw ${longest.draw.toFixed(1)} ms`);
  assert.ok(longest.refit > 0 && longest.refit < 100 && longest.draw > 0 && longest.draw < 100, JSON.stringify(longest));

  // The fit converged on the board's distortion, and says so.
  await page.waitForSelector('#live[data-good-enough="yes"]', { timeout: 5_000 });
  assert.match(await text(page, 'live-verdict'), /Good enough/);
  const { bytes: jsonBytes, name: jsonName } = await download(page, '#live-download-calibration');
  assert.equal(jsonName, 'compass-pdr-calibration.json');
  const calibration = JSON.parse(jsonBytes.toString('utf8'));
  // The board's own axes as printed, in µT: what it applies the calibration to.
  assert.equal(calibration.axes, 'sensor');
  assert.equal(calibration.unit, 'µT');
  calibration.hard_iron.forEach((ut, i) => assert.ok(Math.abs(ut - BOARD.hardIronUt[i]) < 0.3, `hard iron ${i}: ${ut}`));
  assert.match(await text(page, 'live-fit'), /from the WMM's 4\d\.\d µT/);
  for (const id of ['live-clouds', 'live-coverage', 'live-dial', 'live-sphere']) {
    assert.ok(await drawnPixels(page, id) > 5_000, `#${id} is drawn`);
  }

  // Better than the raw readings on the samples held back: it may be sent.
  await page.waitForSelector('#live[data-sendable="yes"]', { timeout: 5_000 });
  assert.equal(await page.isDisabled('#live-send'), false);
  assert.match(await text(page, 'live-verdict'), /better than the calibration in force on the samples held back/);
  assert.match(await text(page, 'live-fit'),
    /; held back \(\d+ samples\): \|B\| spread 0\.\d\d %, 0\.\d\d % fitted without them \(in force, raw: \d+\.\d\d %\); \|B\| − WMM RMS/);
  assert.deepEqual(await page.$$eval('#live-reasons li', (items) => items.map((item) => item.textContent)), []);

  // Send: exactly MotionCal's 68 bytes, and the board's echo confirms them.
  await page.click('#live-send');
  await page.waitForSelector('#live[data-confirmation="confirmed"]', { timeout: 10_000 });
  const written = await page.evaluate(() => window.fakeSerial.written);
  assert.deepEqual(Uint8Array.from(written), packetOf(calibration));
  assert.match(await text(page, 'live-confirmation'), /Confirmed: the board echoed the calibration sent/);
  await page.waitForFunction((n) => document.getElementById('live-lines').textContent === String(n), totalLines + 2);
  // Confirmed, it is the calibration in force: the same fit is not sent again, and the
  // button says why.
  await page.waitForSelector('#live[data-sendable="no"]', { timeout: 5_000 });
  assert.equal(await page.isDisabled('#live-send'), true);
  assert.match(await page.getAttribute('#live-send', 'title'),
    /^Not sent, the calibration in force is kept: on the held-back samples the calibration to send leaves \|B\| varying by .* the calibration the board confirmed/);
  assert.match(await text(page, 'live-verdict'), /^Good enough, but it will not be sent: the calibration in force is kept, because$/);
  assert.match(await text(page, 'live-fit'), /\(in force, confirmed: 0\.\d\d %\)/);

  // The recording is every byte received, in order.
  const { bytes: recording, name } = await download(page, '#live-download');
  assert.match(name, /^compass-pdr-live-\d{4}-\d\d-\d\dT\d\d-\d\d-\d\d\.txt$/);
  const sentText = await page.evaluate(() => window.fakeSerial.sentText);
  assert.equal(recording.length, Buffer.byteLength(sentText));
  assert.ok(recording.equals(Buffer.from(sentText)), 'the recording is the bytes sent');
  await page.locator('#live').screenshot({ path: join(out, 'live.png') });
  await page.click('#live-disconnect');
  await page.waitForSelector('#live[data-live-state="disconnected"]');
  assert.deepEqual(problems, []);
  await close();
});

test('a session that has not covered the sphere cannot send: the button says why and nothing reaches the board', async () => {
  // The first half of the sweep: the directions with +z up only.
  const totalLines = BOARD.sweepLines / 2;
  const { page, problems, close } = await openPage({
    initScript: installFakeSerial, initArg: { board: BOARD, linesPerS: 1000, totalLines },
  });
  await page.waitForSelector('#live[data-live-state="idle"]');
  await page.click('#live-connect');
  await page.waitForFunction(() => window.fakeSerial.finished, null, { timeout: 30_000, polling: 200 });
  await page.waitForFunction((n) => document.getElementById('live-lines').textContent === String(n), totalLines,
    { timeout: 5_000 });
  await page.waitForFunction(() => document.getElementById('live-fit').textContent.startsWith('hard iron'), null,
    { timeout: 5_000 });
  assert.equal(await page.getAttribute('#live', 'data-sendable'), 'no');
  assert.equal(await page.isDisabled('#live-send'), true);
  const reasons = await page.$$eval('#live-reasons li', (items) => items.map((item) => item.textContent));
  assert.ok(reasons.some((reason) => /^\d+ % of the sphere of directions is still missing/.test(reason)), reasons.join('\n'));
  // The button's title says the same sentences as the list.
  const title = await page.getAttribute('#live-send', 'title');
  assert.match(title, /^Not sent, the calibration in force is kept: \d+ % of the sphere of directions is still missing/);
  for (const reason of reasons) assert.ok(title.includes(reason.replace(/\.$/, '')), `${title} lacks ${reason}`);

  // A click that gets through anyway (a race with a redraw): nothing is written, and the
  // reasons are shown where the board's confirmation would be.
  await page.evaluate(() => {
    const button = document.getElementById('live-send');
    button.disabled = false;
    button.click();
  });
  await page.waitForSelector('#live[data-confirmation="refused"]', { timeout: 5_000 });
  assert.match(await text(page, 'live-confirmation'),
    /^Not sent, the calibration in force is kept: \d+ % of the sphere of directions is still missing/);
  assert.equal(await page.isDisabled('#live-send'), true);
  await new Promise((resolve) => setTimeout(resolve, 500));
  assert.deepEqual(await page.evaluate(() => window.fakeSerial.written), [], 'nothing was written to the port');
  await page.locator('#live').screenshot({ path: join(out, 'live-refused.png') });
  await page.click('#live-disconnect');
  await page.waitForSelector('#live[data-live-state="disconnected"]');
  assert.deepEqual(problems, []);
  await close();
});

test('an unplug mid-stream keeps every byte, and connecting again continues the session', async () => {
  const unplugAfterLines = 4_321;
  const totalLines = 8_000;
  const { page, problems, close } = await openPage({
    initScript: installFakeSerial,
    initArg: { board: BOARD, linesPerS: 1000, totalLines, unplugAfterLines },
    acceptDownloads: true,
  });
  await page.waitForSelector('#live[data-live-state="idle"]');
  await page.click('#live-connect');
  await page.waitForSelector('#live[data-live-state="disconnected"]', { timeout: 20_000 });
  assert.match(await text(page, 'live-status'), /The connection ended: The device has been lost\. All 4322 lines received are kept/);
  // The half line at the unplug is read (and skipped as incomplete), never joined to the next.
  assert.equal(await text(page, 'live-lines'), String(unplugAfterLines + 1));
  assert.equal(await text(page, 'live-skipped-count'), '1');
  const { bytes: recording } = await download(page, '#live-download');
  const sentText = await page.evaluate(() => window.fakeSerial.sentText);
  assert.ok(recording.equals(Buffer.from(sentText)), `the recording (${recording.length} bytes) is every byte sent (${sentText.length})`);
  await page.screenshot({ path: join(out, 'live-unplugged.png'), fullPage: false });

  // Plugged back in: the same session goes on counting.
  assert.equal(await page.isDisabled('#live-connect'), false);
  await page.click('#live-connect');
  await page.waitForSelector('#live[data-live-state="connected"]');
  // Until the board has sent its last line and the page has read it: a disconnect
  // while bytes are on their way drops those still in the port's buffer, as a real
  // port does, and they would be sent but not received.
  await page.waitForFunction((n) => window.fakeSerial.finished
    && document.getElementById('live-lines').textContent === String(n), totalLines + 1, { timeout: 20_000 });
  await page.click('#live-disconnect');
  await page.waitForSelector('#live[data-live-state="disconnected"]');
  const { bytes: whole } = await download(page, '#live-download');
  assert.ok(whole.equals(Buffer.from(await page.evaluate(() => window.fakeSerial.sentText))), 'both ports\' bytes, in order');
  assert.deepEqual(problems, []);
  await close();
});

test('a browser without Web Serial says so, the rest of the page works, and a simulated board can be tried', async () => {
  const { page, problems, close } = await openPage({
    acceptDownloads: true,
    initScript: () => Object.defineProperty(Navigator.prototype, 'serial', { configurable: true, get: () => undefined }),
  });
  await page.waitForSelector('#live[data-live-state="unsupported"]');
  assert.match(await text(page, 'live-status'), /This browser has no Web Serial/);
  assert.equal(await page.isDisabled('#live-connect'), true);
  await page.waitForSelector('body[data-state="ready"]');

  // The simulator's calibration dance, played as a board's port would deliver it.
  await page.click('#live-simulate');
  await page.waitForSelector('#live[data-live-state="connected"]');
  assert.equal(await page.isDisabled('#live-simulate'), true);
  assert.equal(await page.isDisabled('#live-send'), true, 'no board to send to');
  // Early in the dance the 3D view shows the regions not yet covered in red, beside
  // the verdict.
  await page.waitForFunction(() => document.getElementById('live-fit').textContent.startsWith('hard iron'),
    null, { timeout: 20_000 });
  const early = { lines: Number(await text(page, 'live-lines')), red: await redPixels(page, 'live-sphere') };
  assert.ok(early.lines < 2_000, `the fit came only after ${early.lines} lines`);
  assert.ok(early.red > 300, `after ${early.lines} lines, ${early.red} red pixels for the regions not covered`);
  const verdictBox = await page.locator('#live-verdict').boundingBox();
  const sphereBox = await page.locator('#live-sphere').boundingBox();
  assert.ok(sphereBox.x >= verdictBox.x + verdictBox.width - 1 && sphereBox.y < verdictBox.y + 100,
    `the 3D view (${JSON.stringify(sphereBox)}) is beside the verdict (${JSON.stringify(verdictBox)})`);
  assert.ok(sphereBox.width >= 450, `the 3D view is ${sphereBox.width} px wide`);
  await page.locator('#live').screenshot({ path: join(out, 'live-sphere-early.png') });
  await page.waitForSelector('#live[data-live-state="disconnected"]', { timeout: 30_000 });
  const status = await text(page, 'live-status');
  const truth = status.match(/true hard iron was \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) µT/);
  assert.ok(truth, status);
  assert.equal(await text(page, 'live-lines'), '3000', 'the whole dance: 60 s at 50 lines/s');
  assert.equal(await text(page, 'live-skipped-count'), '0');
  await page.waitForSelector('#live[data-good-enough="yes"]', { timeout: 5_000 });
  const calibration = JSON.parse((await download(page, '#live-download-calibration')).bytes.toString('utf8'));
  calibration.hard_iron.forEach((ut, i) => assert.ok(Math.abs(ut - Number(truth[i + 1])) < 1.0, `hard iron ${i}: ${ut} vs ${truth[i + 1]}`));
  for (const id of ['live-clouds', 'live-coverage', 'live-dial', 'live-sphere']) {
    assert.ok(await drawnPixels(page, id) > 5_000, `#${id} is drawn`);
  }
  // After the whole dance no region is left red; a drag turns the view.
  const late = await redPixels(page, 'live-sphere');
  console.log(`live 3D view: ${early.red} red pixels after ${early.lines} lines, ${late} after 3000`);
  assert.ok(late < early.red / 10, `${late} red pixels left after the whole dance`);
  const before = await canvasDigest(page, 'live-sphere');
  const box = await page.locator('#live-sphere').boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 120, box.y + box.height / 2 + 40, { steps: 4 });
  await page.mouse.up();
  assert.notEqual(await canvasDigest(page, 'live-sphere'), before, 'the drag turned the 3D view');
  // The dance's board prints its gyroscope: the dial has the attitude filter's blue needle.
  const blueNeedle = await page.$eval('#live-dial', (canvas) => {
    const data = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
    let n = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (Math.abs(data[i] - 30) < 20 && Math.abs(data[i + 1] - 100) < 20 && Math.abs(data[i + 2] - 200) < 20) n += 1;
    }
    return n;
  });
  assert.ok(blueNeedle > 100, `the filter's needle: ${blueNeedle} blue pixels`);
  await page.locator('#live').screenshot({ path: join(out, 'live-simulated.png') });
  assert.deepEqual(problems, []);
  await close();
});

test('settings and recent calibrations are restored after a reload; a corrupt entry is set aside with a notice', async () => {
  const { page, problems, close } = await openPage({
    initScript: installFakeSerial,
    initArg: { board: { ...BOARD, sweepLines: 3000 }, linesPerS: 1000, totalLines: 3000 },
    acceptDownloads: true,
  });
  await page.waitForSelector('#live[data-live-state="idle"]');
  assert.match(await text(page, 'live-recent'), /None yet/);
  await page.selectOption('#live-baud', '57600');
  await page.fill('#live-lat', '48.14');
  await page.fill('#live-lon', '11.58');
  await page.press('#live-lon', 'Tab');
  await page.click('#live-connect');
  await page.waitForFunction(() => window.fakeSerial.finished, null, { timeout: 20_000 });
  await page.waitForSelector('#live[data-good-enough="yes"]', { timeout: 5_000 });
  assert.deepEqual(await page.evaluate(() => window.fakeSerial.openedWith), [{ baudRate: 57600 }]);
  const { bytes } = await download(page, '#live-download-calibration');
  const fitted = JSON.parse(bytes.toString('utf8'));
  await page.click('#live-disconnect');
  await page.waitForSelector('#live[data-live-state="disconnected"]');
  // The calibration downloaded is kept, as downloaded (and near the board's).
  const shownHard = fitted.hard_iron.map((ut) => ut.toFixed(2)).join(', ');
  assert.ok((await text(page, 'live-recent')).includes(`live session: hard iron (${shownHard}) µT`), await text(page, 'live-recent'));
  fitted.hard_iron.forEach((ut, i) => assert.ok(Math.abs(ut - BOARD.hardIronUt[i]) < 0.3, `hard iron ${i}: ${ut}`));

  // A calibration saved earlier is loaded from its file (an older file: no axes, no unit,
  // hard_iron_ut and field_ut; read as body axes and µT).
  const saved = { hard_iron_ut: [1.5, -2.25, 3], soft_iron: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], field_ut: 50 };
  await page.setInputFiles('#live-import', { name: 'bench-board.json', mimeType: 'application/json', buffer: Buffer.from(JSON.stringify(saved)) });
  await page.waitForFunction(() => document.getElementById('live-import-status').textContent.startsWith('Loaded'));
  const listed = await page.$$eval('#live-recent li', (items) => items.map((item) => item.textContent));
  assert.equal(listed.length, 2);
  assert.match(listed[0], /bench-board\.json: hard iron \(1\.50, -2\.25, 3\.00\) µT, field 50\.00 µT/);
  // One that is not a calibration is refused with the reason.
  await page.setInputFiles('#live-import', { name: 'notes.json', mimeType: 'application/json', buffer: Buffer.from('{"hard_iron_ut": [1, 2]}') });
  await page.waitForFunction(() => document.getElementById('live-import-status').textContent.startsWith('notes.json'));
  assert.match(await text(page, 'live-import-status'), /notes\.json is not a calibration compass-pdr can read/);

  await page.reload();
  await page.waitForSelector('#live[data-live-state="idle"]');
  assert.equal(await page.$eval('#live-baud', (select) => select.value), '57600');
  assert.equal(await page.inputValue('#live-lat'), '48.14');
  assert.equal(await page.inputValue('#live-lon'), '11.58');
  assert.deepEqual(await page.$$eval('#live-recent li', (items) => items.map((item) => item.textContent)), listed);
  // The kept calibration downloads again as it was.
  const again = JSON.parse((await download(page, '#recent-download-1')).bytes.toString('utf8'));
  assert.deepEqual(again, fitted);
  assert.equal(await text(page, 'storage-notice'), '');
  await page.screenshot({ path: join(out, 'restored.png'), fullPage: false });

  // A corrupt entry: set aside with a notice, and the page works.
  await page.evaluate(() => localStorage.setItem('compass-pdr.calibrations.v1', '{"not": "a list"'));
  await page.reload();
  await page.waitForSelector('#live[data-live-state="idle"]');
  assert.match(await text(page, 'storage-notice'), /The saved recent calibrations could not be read \(it is not JSON\) and were set aside/);
  assert.match(await text(page, 'live-recent'), /None yet/);
  assert.equal(await page.$eval('#live-baud', (select) => select.value), '57600', 'the settings are still read');
  await page.waitForSelector('body[data-state="ready"]');
  assert.equal(await page.evaluate(() => localStorage.getItem('compass-pdr.calibrations.v1')), null);
  // Problems logged are the notices' warnings only.
  assert.deepEqual(problems, []);
  await close();
});
