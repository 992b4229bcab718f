// End-to-end tests of the page as a person uses it: load, see the demo analysed, drop
// a log, choose a bad file. playwright-core drives Debian's Chromium; ./test serves
// www/ and writes the expected figures (from the CLI) into E2E_OUT.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { copyFileSync, existsSync, readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { drawnPixels, lastDropTiming, plotDrawn, openAllDetails, openPage, out, recordMainThread, text, waitForState } from './common.mjs';

const statusBackground = (page) => page.$eval('#status', (status) => getComputedStyle(status).backgroundColor);

/** The page shows the same statistics as `compass-pdr heading --json`, row by row: every
 * calibration method and every Fourier stack. */
async function assertStatsMatch(page, expected) {
  const fixed = (value, unit = '°') => (value === undefined || value === null ? '—' : `${value.toFixed(2)}${unit}`);
  assert.ok(expected.rows.some((row) => row.key.endsWith('fourier')), 'the CLI fitted a Fourier model');
  for (const row of expected.rows) {
    const key = row.key.replaceAll('+', '-');
    if (row.error) {
      assert.equal(await text(page, `error-${key}`), row.error, `${key} failed for the same reason`);
      continue;
    }
    const { train, check } = row;
    assert.equal(await text(page, `stat-${key}-train-rms`), fixed(train?.rms_deg), `${key} train RMS`);
    assert.equal(await text(page, `stat-${key}-check-rms`), fixed(check?.rms_deg), `${key} check RMS`);
    assert.equal(await text(page, `stat-${key}-check-mean`), fixed(check?.mean_deg));
    assert.equal(await text(page, `stat-${key}-check-std`), fixed(check?.std_deg));
    assert.equal(await text(page, `stat-${key}-check-p95`), fixed(check?.p95_abs_deg));
    assert.equal(await text(page, `stat-${key}-check-within5`), fixed(check?.within_5_deg_pct, ' %'));
  }
  // One choice of "best" (crate::analysis::calibration::selection), the same row and the same sentence.
  const bestRows = await page.$$eval('#methods-body tr.best', (rows) => rows.map((row) => row.id));
  assert.deepEqual(bestRows, [`row-${expected.choice.key.replaceAll('+', '-')}`], 'the best row');
  assert.ok((await text(page, 'verdict-method')).includes(`Method: ${expected.choice.label}: `), await text(page, 'verdict-method'));
}

/** The check RMS of one row in the CLI's report. */
const checkRms = (report, key) => report.rows.find((row) => row.key === key)?.check?.rms_deg;

const PLOT_IDS = ['plot-circle', 'plot-heading', 'plot-field', 'plot-deviation', 'plot-residuals', 'plot-online',
  'plot-trajectory', 'plot-steps', 'plot-position-error'];

/** Every figure holds a plot (not a blank canvas, not a message in its place). */
async function assertPlotsDrawn(page) {
  for (const id of PLOT_IDS) {
    const { drawn, isPlot } = await plotDrawn(page, id);
    assert.ok(isPlot, `#${id} has ${drawn} drawn pixels, or a message in the plot's place`);
  }
}

/** Every figure holds a message in the plot's place (not a stale plot, not a blank). */
async function assertMessagesDrawn(page) {
  for (const id of PLOT_IDS) {
    assert.ok((await plotDrawn(page, id)).isMessage, `#${id} holds no message`);
  }
}

/** Drops files on the drop zone the way a browser does: a drop event with a DataTransfer. */
async function dropFile(page, name, content) {
  await dropFiles(page, [{ name, content }]);
}

async function dropFiles(page, files) {
  await page.evaluate((files) => {
    const transfer = new DataTransfer();
    for (const { name, content } of files) transfer.items.add(new File([content], name, { type: 'text/csv' }));
    const zone = document.getElementById('drop-zone');
    zone.dispatchEvent(new DragEvent('dragover', { dataTransfer: transfer, bubbles: true, cancelable: true }));
    zone.dispatchEvent(new DragEvent('drop', { dataTransfer: transfer, bubbles: true, cancelable: true }));
  }, files);
}

test('the demo is analysed and drawn on load, with the CLI\'s figures', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  const expected = JSON.parse(readFileSync(join(out, 'demo-walk.json'), 'utf8'));
  await assertStatsMatch(page, expected);
  // The demo shows what calibration is for: tens of degrees before, a few after.
  assert.ok(checkRms(expected, 'raw') > 10, 'large error before');
  assert.ok(checkRms(expected, 'ellipse') < 5, 'small error after the ellipse fit');
  assert.ok(checkRms(expected, 'min_max') < 5, 'small error after min/max');
  await assertPlotsDrawn(page);
  assert.match(await text(page, 'status'), /Analysed demo-walk\.csv: 12,000 magnetometer samples\./);
  // Dated and placed by its GNSS: the World Magnetic Model gives declination and field.
  assert.match(await text(page, 'context'), /Declination: 14\.92° \(WMM2025 on 2026-05-14/);
  assert.match(await text(page, 'context'), /52\.6 µT expected, inclination 68\.8°/);
  // The dead reckoning agrees with `compass-pdr pdr --json`: steps, distance, error.
  const pdr = JSON.parse(readFileSync(join(out, 'demo-walk-pdr.json'), 'utf8'));
  const summary = await text(page, 'pdr-summary');
  assert.ok(summary.includes(`${pdr.n_steps} steps in ${pdr.n_bouts} bouts`), summary);
  assert.ok(summary.includes(`${pdr.pdr_distance_m.toFixed(1)} m dead-reckoned`), summary);
  assert.ok(summary.includes(`RMS ${pdr.position_error.rms_m.toFixed(2)} m`), summary);
  // The minute without GNSS, bridged by the dead reckoning.
  const gap = pdr.gnss_gaps[0];
  assert.ok(summary.includes(`No GNSS fix from ${gap.start_s.toFixed(0)} to ${gap.end_s.toFixed(0)} s`), summary);
  assert.match(summary, /Step model: Weinberg, .*trained on the GNSS speed/);
  assert.match(await text(page, 'status'), new RegExp(`${pdr.n_steps} steps dead-reckoned`));
  assert.equal(await statusBackground(page), 'rgb(244, 246, 249)', 'a good result is not styled as an error');
  assert.match(await text(page, 'context'), /Reference heading: the log's reference-heading column/);
  assert.match(await text(page, 'calibration'), /Hard iron \(/);
  // One pipeline: the page, `compass-pdr calibrate`, `heading` and `pdr` name the same
  // best method and the same device calibration.
  assert.equal(pdr.heading_key, expected.choice.key, 'the dead reckoning takes the best');
  const calibrateLines = readFileSync(join(out, 'demo-walk-calibrate.txt'), 'utf8').split('\n').map((line) => line.trim());
  assert.ok(calibrateLines.some((line) => line.startsWith(`best: ${expected.choice.label}: `)), 'calibrate names the best');
  const deviceCalibration = await text(page, 'calibration');
  for (const prefix of ['From the ', 'Hard iron (', 'Soft iron [[']) {
    const line = calibrateLines.find((candidate) => candidate.startsWith(prefix));
    assert.ok(line && deviceCalibration.includes(line), `the page's device calibration has "${line}"`);
  }
  const ellipseModel = expected.fourier.find((fourier) => fourier.base_key === 'ellipse').fit.model;
  const models = await text(page, 'deviation-model');
  assert.equal(expected.neural.length, 2, 'a network on the raw heading and on the best calibration');
  for (const neural of expected.neural) {
    assert.ok(models.includes(`MLP on ${neural.base_label}: inputs ${neural.inputs.join(', ')}`), models);
  }
  assert.match(await text(page, 'deviation-model'), new RegExp(`ellipse \\(tilt-aware 2D\\): A ${ellipseModel.a_deg.toFixed(2)}°`));
  // The answer's picture (issue 45): the demo walk's track, drawn, and on the first
  // screen on a desktop and on a phone.
  assert.ok((await plotDrawn(page, 'answer-canvas')).isPlot, 'the answer\'s picture is drawn, not a message');
  const viewport = page.viewportSize();
  for (const size of [{ width: 1360, height: 900 }, { width: 390, height: 844 }]) {
    await page.setViewportSize(size);
    await page.evaluate(() => window.scrollTo(0, 0));
    const picture = await page.evaluate(() => {
      const figure = document.getElementById('answer-figure');
      const rect = figure.getBoundingClientRect();
      return { kind: figure.dataset.picture, hidden: figure.hidden, top: rect.top, bottom: rect.bottom, left: rect.left, right: rect.right };
    });
    assert.equal(picture.kind, 'track', 'the demo walk leads with its track');
    assert.ok(!picture.hidden && picture.top >= 0 && picture.bottom <= size.height && picture.left >= 0 && picture.right <= size.width,
      `the demo's picture at ${size.width}×${size.height}: ${JSON.stringify(picture)}`);
    await page.screenshot({ path: join(out, `demo-first-screen-${size.width}.png`) });
  }
  await page.setViewportSize(viewport);
  await page.screenshot({ path: join(out, 'demo-first-screen.png') });
  await openAllDetails(page);
  await page.screenshot({ path: join(out, 'demo.png'), fullPage: true });
  assert.deepEqual(problems, []);
  await close();
});

test('a dropped canonical CSV replaces the demo', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  await dropFile(page, 'drop-walk.csv', readFileSync(join(out, 'drop-walk.csv'), 'utf8'));
  await waitForState(page, 'ready', 'drop-walk.csv');
  const expected = JSON.parse(readFileSync(join(out, 'drop-walk.json'), 'utf8'));
  await assertStatsMatch(page, expected);
  await assertPlotsDrawn(page);
  assert.equal(await text(page, 'result-file'), 'drop-walk.csv');
  await page.screenshot({ path: join(out, 'dropped.png'), fullPage: true });
  assert.deepEqual(problems, []);
  await close();
});

test('phyphox files dropped together are merged into one recording', async (t) => {
  const dir = join(import.meta.dirname, '../../../shared/data/phyphox-hallway-loop');
  if (!existsSync(dir)) { t.skip(`${dir} not found (the real recordings live beside the project; CI has them)`); return; }
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  const names = ['Accelerometer.csv', 'Gyroscope.csv', 'Magnetometer.csv', 'Location.csv'];
  await dropFiles(page, names.map((name) => ({ name, content: readFileSync(join(dir, name), 'utf8') })));
  await waitForState(page, 'ready', names.join(' + '));
  assert.match(await text(page, 'status'), /10,575 magnetometer samples/);
  // What was read, stream by stream, as `compass-pdr inspect` summarises it.
  const streams = await text(page, 'streams');
  assert.match(streams, /Format: delimited text/);
  assert.match(streams, /magnetometer: 10575 samples at \d+\.\d Hz over \d+\.\d s, in µT/);
  // No reference heading in a phyphox walk: the figures say so instead of inventing one.
  assert.equal(await text(page, 'stat-min_max-check-rms'), '—');
  assert.match(await text(page, 'notes'), /no reference heading/);
  // The loop's 168 steps (169 detected); its indoor fixes (22-669 m) are weighted by their
  // accuracy, none refused (issue 42), and the page says the track is smoothed.
  assert.match(await text(page, 'pdr-summary'), /169 steps in 1 bout at/);
  assert.match(await text(page, 'pdr-summary'), /GNSS fixes: 3\d used\./);
  assert.match(await text(page, 'pdr-summary'), /The track is smoothed forward and backward/);
  await assertPlotsDrawn(page);
  await page.screenshot({ path: join(out, 'phyphox.png'), fullPage: true });
  assert.deepEqual(problems, []);
  await close();
});

test('a 50 MB log is read in chunks with a progress bar, and the page keeps answering', async () => {
  const { page, problems, close } = await openPage({ initScript: recordMainThread });
  await waitForState(page, 'ready', 'demo-walk.csv');
  await page.setInputFiles('#file-input', join(out, 'large-walk.csv'));
  const progressSeen = [];
  let slowestAnswerMs = 0;
  for (let poll = 0; poll < 2000; poll += 1) {
    const askedAt = Date.now();
    const now = await page.evaluate(() => {
      const progress = document.getElementById('progress');
      return { state: document.body.dataset.state, file: document.body.dataset.file,
               progress: progress.hidden ? null : Number(progress.value) };
    });
    slowestAnswerMs = Math.max(slowestAnswerMs, Date.now() - askedAt);
    if (now.progress !== null) progressSeen.push(now.progress);
    if (now.state === 'ready' && now.file === 'large-walk.csv') break;
    await new Promise((resolve) => setTimeout(resolve, 20));
  }
  await waitForState(page, 'ready', 'large-walk.csv');
  // The reading and the analysis run on the analysis worker: the page's own thread only
  // draws, in tasks under 100 ms.
  const timing = await lastDropTiming(page);
  writeFileSync(join(out, 'large-timing.json'), JSON.stringify(timing));
  console.log(`large file: drop to summary ${timing.dropToSummaryMs.toFixed(0)} ms, to every figure ${timing.dropToReadyMs.toFixed(0)} ms, ${timing.longTasks} long tasks, longest ${timing.longestTaskMs.toFixed(0)} ms`);
  assert.ok(timing.longestTaskMs <= 100, `a main-thread task took ${timing.longestTaskMs.toFixed(0)} ms`);
  assert.ok(progressSeen.some((fraction) => fraction > 0 && fraction < 1), `progress seen: ${progressSeen.slice(0, 20)}`);
  // Reading never blocks; the synchronous steps are the calibration of 450,000 samples,
  // then (after the browser has painted) the heading models.
  assert.ok(slowestAnswerMs < 2000, `the page took ${slowestAnswerMs} ms to answer`);
  console.log(`large file: ${progressSeen.length} progress readings, slowest answer ${slowestAnswerMs} ms`);
  assert.match(await text(page, 'status'), /Analysed large-walk\.csv: 450,000 magnetometer samples\./);
  assert.equal(await page.getAttribute('#progress', 'hidden'), '', 'the bar is hidden again');
  await assertPlotsDrawn(page);
  await page.screenshot({ path: join(out, 'large.png'), fullPage: true });
  assert.deepEqual(problems, []);
  await close();
});

test('an unknown CSV opens the column-mapping dialog, and the mapping is remembered', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  // A level turn logged in gauss and milliseconds under names no tool could guess.
  let csv = 'when_ms;ch1;ch2;ch3\n';
  for (let step = 0; step < 360; step += 1) {
    const angle = (step * Math.PI) / 180;
    csv += `${step * 20};${(0.1 + 0.22 * Math.cos(angle)).toFixed(4)};${(-0.05 - 0.22 * Math.sin(angle)).toFixed(4)};0.38\n`;
  }
  const chooseLogger = () => page.setInputFiles('#file-input', { name: 'logger.csv', mimeType: 'text/csv', buffer: Buffer.from(csv) });
  await chooseLogger();
  await page.waitForSelector('#mapping-dialog[open]');
  assert.match(await text(page, 'mapping-reason'), /logger\.csv, line 1: the header names no column this tool knows/);
  assert.equal(await page.$eval('#mapping-1', (select) => select.value), 'ignore', 'nothing is guessed for ch1');
  await page.screenshot({ path: join(out, 'mapping-dialog.png') });
  await page.selectOption('#mapping-0', 't_ms');
  await page.selectOption('#mapping-1', 'mag_x_gauss');
  await page.selectOption('#mapping-2', 'mag_y_gauss');
  await page.selectOption('#mapping-3', 'mag_z_gauss');
  await page.click('#mapping-apply');
  await waitForState(page, 'ready', 'logger.csv');
  assert.match(await text(page, 'status'), /Analysed logger\.csv: 360 magnetometer samples\./);
  assert.equal(await page.$eval('#mapping-dialog', (dialog) => dialog.open), false);
  // The hard iron is the offset written into the file, in the file's own unit (gauss),
  // and in µT as MotionCal's packet carries it.
  assert.match(await text(page, 'calibration'), /Hard iron \(0\.100\d, -0\.050\d, [^)]*\) gauss/);
  assert.match(await text(page, 'calibration'), /hard iron \(10\.0\d, -5\.0\d, [^)]*\) µT/);

  // After a reload the same columns are read without asking.
  await page.reload();
  await waitForState(page, 'ready', 'demo-walk.csv');
  await chooseLogger();
  await waitForState(page, 'ready', 'logger.csv');
  assert.match(await text(page, 'status'), /Read with your saved column mapping for logger\.csv\./);
  assert.equal(await page.$eval('#mapping-dialog', (dialog) => dialog.open), false);
  assert.deepEqual(problems, []);
  await close();
});

// Bad files: each gives a clear message naming the file and what to do, the previous
// figures are cleared, the canvases say why, and the page still works afterwards.
const badFiles = [
  { name: 'garbage.bin', buffer: Buffer.from(Array.from({ length: 4096 }, (_, i) => (i * 2654435761) >>> 24)),
    message: /garbage\.bin is not a text log \(binary data near byte \d+\)\. Export the log as CSV/ },
  { name: 'empty.csv', buffer: Buffer.alloc(0), message: /empty\.csv is empty\. Choose a log with a header line/ },
  { name: 'no-mag.csv', buffer: Buffer.from('t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2\n0,0,0,-9.81\n1,0,0,-9.81\n'),
    message: /no-mag\.csv has no magnetometer columns: its header \(line 1\) has t_s, acc_x_mps2, acc_y_mps2, acc_z_mps2\. Name them mag_x_ut/ },
  { name: 'nans.csv', buffer: Buffer.from('t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,NaN,NaN,NaN\n1,NaN,NaN,NaN\n2,nan,nan,nan\n'),
    message: /nans\.csv: none of its 3 data lines has a usable magnetometer sample \(line 2: mag_x_ut is NaN/ },
];

for (const bad of badFiles) {
  test(`choosing ${bad.name} shows what is wrong and what to do`, async () => {
    const { page, problems, close } = await openPage();
    await waitForState(page, 'ready', 'demo-walk.csv');
    await page.setInputFiles('#file-input', { name: bad.name, mimeType: 'application/octet-stream', buffer: bad.buffer });
    await waitForState(page, 'error');
    assert.match(await text(page, 'status'), bad.message);
    assert.equal(await statusBackground(page), 'rgb(251, 233, 230)', 'an error is styled as one');
    assert.equal(await page.$$eval('#methods-body tr', (rows) => rows.length), 0, 'the demo\'s figures are cleared');
    assert.equal(await text(page, 'result-file'), '—');
    // The canvases carry the message instead of a stale or blank plot.
    await assertMessagesDrawn(page);
    await page.screenshot({ path: join(out, `error-${bad.name}.png`), fullPage: true });
    // The page recovers: a good file is analysed again.
    await dropFile(page, 'drop-walk.csv', readFileSync(join(out, 'drop-walk.csv'), 'utf8'));
    await waitForState(page, 'ready', 'drop-walk.csv');
    assert.deepEqual(problems, []);
    await close();
  });
}

test('a file that changes on disk while it is read is named with what to do, and the page goes on', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  // 50 MB, read in chunks: the file is overwritten while (or before) they are read, which
  // the browser refuses to read further.
  const path = join(out, 'vanishing.csv');
  copyFileSync(join(out, 'large-walk.csv'), path);
  await page.setInputFiles('#file-input', path);
  writeFileSync(path, 'changed\n');
  await waitForState(page, 'error');
  assert.match(await text(page, 'status'), /^Could not read vanishing\.csv: .+\. Choose it again/);
  // Not reported as a bug, and the analysis worker still works: a good file is read.
  await dropFile(page, 'drop-walk.csv', readFileSync(join(out, 'drop-walk.csv'), 'utf8'));
  await waitForState(page, 'ready', 'drop-walk.csv');
  assert.deepEqual(problems, []);
  await close();
});

test('on a phone-width, high-density screen the plots are sharp and the page fits', async () => {
  const { page, problems, close } = await openPage({ viewport: { width: 390, height: 844 }, deviceScaleFactor: 2 });
  await waitForState(page, 'ready', 'demo-walk.csv');
  // The backing store has two pixels per CSS pixel; the plot is laid out as before.
  const sizes = await page.$eval('#plot-circle', (canvas) => [canvas.width, canvas.height, canvas.dataset.width, canvas.clientWidth]);
  assert.deepEqual(sizes.slice(0, 3), [1120, 880, '560']);
  assert.ok(sizes[3] <= 390, `the canvas is shown ${sizes[3]} px wide`);
  assert.ok(await drawnPixels(page, 'plot-circle') > 40_000);
  // Nothing is wider than the window.
  const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(overflow <= 0, `the page is ${overflow} px wider than the window`);
  await page.screenshot({ path: join(out, 'phone.png'), fullPage: false });
  assert.deepEqual(problems, []);
  await close();
});
