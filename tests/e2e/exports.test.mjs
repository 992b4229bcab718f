// End-to-end tests of the exports: every file the page offers is downloaded and read
// back, and agrees with what the page shows.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync } from 'node:fs';
import { join } from 'node:path';
import { download, openAllDetails, openPage, out, text, waitForState } from './common.mjs';

/** The floats of a C initialiser, in order (`1.5f`, `-2e-3f`, `7`). */
const cFloats = (source) => [...source.matchAll(/-?\d+(?:\.\d+)?(?:e-?\d+)?f?(?=[,\s}])/gi)].map((m) => parseFloat(m[0]));

test('every export of the demo analysis downloads and reads back', async () => {
  const { page, problems, close } = await openPage({ acceptDownloads: true });
  await waitForState(page, 'ready', 'demo-walk.csv');
  const pdr = JSON.parse(readFileSync(join(out, 'demo-walk-pdr.json'), 'utf8'));

  // Calibration JSON: the device calibration the page lists.
  const json = await download(page, '#export-calibration');
  assert.equal(json.name, 'demo-walk-calibration.json');
  const calibration = JSON.parse(json.bytes.toString('utf8'));
  // In the log's own axes and unit: the demo's canonical columns, in µT.
  assert.equal(calibration.axes, 'sensor');
  assert.equal(calibration.unit, 'µT');
  assert.equal(calibration.ut_per_unit, 1);
  assert.match(calibration.axes_description, /the log's x, y, z columns/);
  assert.match(calibration.formula, /corrected = soft_iron · \(raw − hard_iron\)/);
  assert.equal(calibration.hard_iron.length, 3);
  assert.equal(calibration.soft_iron.flat().length, 9);
  assert.ok(calibration.field > 20 && calibration.field < 70, `${calibration.field}`);
  const shown = (await text(page, 'calibration')).match(/Hard iron \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) µT/);
  assert.ok(shown, 'the page lists the hard iron');
  calibration.hard_iron.forEach((ut, i) => assert.equal(ut.toFixed(2), shown[i + 1]));

  // C snippet: the same numbers as C declarations.
  const snippet = (await download(page, '#export-snippet')).bytes.toString('utf8');
  assert.match(snippet, /float hard_iron\[3\] = \{/);
  assert.match(snippet, /\/\/ Axes: the log's x, y, z columns as written/);
  assert.match(snippet, /\/\/ Unit: µT|\/\/ Unit: uT/);
  const hard = cFloats(snippet.match(/float hard_iron\[3\] = (\{[^}]*\})/)[1]);
  const soft = cFloats(snippet.match(/float soft_iron\[3\]\[3\] = \{([\s\S]*?)\};/)[1]);
  const field = parseFloat(snippet.match(/float mag_field = (-?[\d.e-]+)f?;/)[1]);
  hard.forEach((value, i) => assert.ok(Math.abs(value - calibration.hard_iron[i]) < 1e-5, `hard ${i}`));
  soft.forEach((value, i) => assert.ok(Math.abs(value - calibration.soft_iron.flat()[i]) < 1e-6, `soft ${i}`));
  assert.ok(Math.abs(field - calibration.field) < 1e-4);

  // Corrected data: one row per magnetometer sample used, every row as wide as the header.
  const csv = (await download(page, '#export-csv')).bytes.toString('utf8').trimEnd().split('\n');
  const header = csv[0].split(',');
  assert.deepEqual(header.slice(0, 6), ['t_s', 'level_raw_x_ut', 'level_raw_y_ut', 'level_corrected_x_ut', 'level_corrected_y_ut', 'raw_heading_deg']);
  assert.ok(header.includes('ellipse_heading_deg') && header.includes('ref_heading_deg'), header.join(','));
  assert.equal(csv.length - 1, 12000);
  assert.ok(csv.slice(1).every((row) => row.split(',').length === header.length));
  const refColumn = header.indexOf('ref_heading_deg');
  const ellipseColumn = header.indexOf('ellipse_heading_deg');
  const errors = csv.slice(1).map((row) => row.split(',')).filter((cells) => cells[refColumn] !== '')
    .map((cells) => ((Number(cells[ellipseColumn]) - Number(cells[refColumn]) + 540) % 360) - 180);
  const rms = Math.sqrt(errors.reduce((sum, e) => sum + e * e, 0) / errors.length);
  assert.ok(rms < 5, `the corrected headings follow the reference (RMS ${rms.toFixed(2)}°)`);

  // The attitude filter's headings: the CLI's `--attitude-out` file, one row per gyroscope
  // sample, its yaw from true north following the demo's true heading.
  const attitude = await download(page, '#export-attitude');
  assert.equal(attitude.name, 'demo-walk-attitude.csv');
  const attitudeLines = attitude.bytes.toString('utf8').trimEnd().split('\n');
  assert.match(attitudeLines[1], /^# yaw_deg: heading of the body x axis, clockwise from true north/);
  const columnsAt = attitudeLines.findIndex((line) => !line.startsWith('#'));
  assert.equal(attitudeLines[columnsAt], 't_s,yaw_deg,pitch_deg,roll_deg,yaw_sigma_deg');
  const attitudeRows = attitudeLines.slice(columnsAt + 1).map((row) => row.split(',').map(Number));
  assert.ok(attitudeRows.length >= 11900, `${attitudeRows.length} rows`);
  const refAt = new Map(csv.slice(1).map((row) => row.split(','))
    .filter((cells) => cells[refColumn] !== '').map((cells) => [Number(cells[0]).toFixed(2), Number(cells[refColumn])]));
  const yawErrors = attitudeRows.filter(([t]) => refAt.has(t.toFixed(2)))
    .map(([t, yaw]) => ((yaw - refAt.get(t.toFixed(2)) + 540) % 360) - 180);
  assert.ok(yawErrors.length > 10000, `${yawErrors.length} rows with a reference`);
  const yawRms = Math.sqrt(yawErrors.reduce((sum, e) => sum + e * e, 0) / yawErrors.length);
  assert.ok(yawRms < 4, `the filter's yaw follows the true heading (RMS ${yawRms.toFixed(2)}°)`);
  assert.ok(attitudeRows.every((cells) => cells.length === 5 && cells[4] > 0), 'every row has a positive yaw σ');

  // The HTML report: self-contained, with the table, the figures and the PDR summary.
  const report = await download(page, '#export-report');
  assert.equal(report.name, 'demo-walk-report.html');
  const reportPage = await page.context().newPage();
  const requests = [];
  reportPage.on('request', (request) => { if (!request.url().startsWith('data:')) requests.push(request.url()); });
  await reportPage.setContent(report.bytes.toString('utf8'));
  assert.match(await reportPage.title(), /compass-pdr report: demo-walk\.csv/);
  assert.ok(await reportPage.$$eval('tbody tr', (rows) => rows.length) >= 8, 'the comparison table');
  assert.equal(await reportPage.$$eval('img', (images) => images.filter((image) => image.complete && image.naturalWidth > 0).length), 10, 'the answer\'s picture and the nine plots, as PNG');
  // The answer's picture first, under the verdict.
  assert.match(await reportPage.$eval('img', (image) => image.alt), /^The answer's picture/);
  assert.match(await reportPage.textContent('body'), new RegExp(`${pdr.n_steps} steps in ${pdr.n_bouts} bouts`));
  assert.deepEqual(requests, [], 'the report loads nothing');
  await reportPage.screenshot({ path: join(out, 'report.png'), fullPage: false });
  await reportPage.close();

  // Any plot as PNG, at the canvas's size (its section opened, as a person does).
  await openAllDetails(page);
  for (const id of ['plot-circle', 'plot-trajectory']) {
    const png = await download(page, `#png-${id}`);
    assert.equal(png.name, `${id}.png`);
    assert.deepEqual([...png.bytes.subarray(0, 8)], [137, 80, 78, 71, 13, 10, 26, 10], 'a PNG signature');
    const size = [png.bytes.readUInt32BE(16), png.bytes.readUInt32BE(20)];
    assert.deepEqual(size, await page.$eval(`#${id}`, (canvas) => [canvas.width, canvas.height]));
  }
  // The demo's GNSS: its track as GeoJSON (RFC 7946 [lon, lat]) and GPX, in Seattle.
  const geojson = JSON.parse((await download(page, '#export-geojson')).bytes.toString('utf8'));
  assert.equal(geojson.type, 'FeatureCollection');
  const line = geojson.features.find((feature) => feature.geometry.type === 'LineString');
  assert.ok(line, 'a LineString');
  const [lon, lat] = line.geometry.coordinates[0];
  assert.ok(Math.abs(lat - 47.606) < 0.01 && Math.abs(lon + 122.332) < 0.01, `${lat}, ${lon}`);
  const gpxText = (await download(page, '#export-gpx')).bytes.toString('utf8');
  const gpx = await page.evaluate((source) => {
    const doc = new DOMParser().parseFromString(source, 'application/xml');
    return { error: doc.querySelector('parsererror')?.textContent ?? null, points: doc.getElementsByTagName('trkpt').length };
  }, gpxText);
  assert.equal(gpx.error, null);
  assert.equal(gpx.points, line.geometry.coordinates.length);
  assert.ok(gpx.points >= pdr.n_steps, `${gpx.points} track points for ${pdr.n_steps} steps`);

  // A walk without GNSS: its track has no latitude and longitude, and the buttons say why.
  await page.setInputFiles('#file-input', join(out, 'drop-walk.csv'));
  await waitForState(page, 'ready', 'drop-walk.csv');
  assert.equal(await page.isDisabled('#export-geojson'), true);
  assert.equal(await page.isDisabled('#export-attitude'), false, 'a walk with a gyroscope has an attitude');
  assert.match(await page.getAttribute('#export-geojson', 'title'), /no latitude and longitude/);

  assert.deepEqual(problems, []);
  await close();
});

/** The id of the summary's first download on the screen (its flex order, then its place). */
async function firstShownExport(page) {
  return page.evaluate(() => {
    const shown = [...document.querySelectorAll('#summary .exports button')]
      .filter((button) => button.offsetParent !== null);
    shown.sort((a, b) => a.getBoundingClientRect().left - b.getBoundingClientRect().left);
    return shown[0]?.id;
  });
}

test('an ArduPilot log gives its compass parameters, and the .param download says what the page shows', async (t) => {
  const log = join(import.meta.dirname, '../../../shared/data/ardupilot-copter-log171/log171.bin');
  if (!existsSync(log)) { t.skip(`${log} not found (the real recordings live beside the project; CI has them)`); return; }
  const { page, problems, close } = await openPage({ acceptDownloads: true });
  await waitForState(page, 'ready', 'demo-walk.csv');
  assert.equal(await page.isDisabled('#export-param'), true, 'the demo walk is no autopilot log');
  await page.setInputFiles('#file-input', log);
  await waitForState(page, 'ready', 'log171.bin');
  const streams = await text(page, 'streams');
  assert.match(streams, /ArduPilot DataFlash log/);
  // The answer for a drone: each compass's sentence, written or kept, against the
  // parameters in force.
  const calibration = await text(page, 'calibration');
  assert.match(calibration, /ArduPilot compass calibration/);
  const summary = await text(page, 'summary');
  assert.equal(await page.isDisabled('#export-param'), false);
  // The parameter file is what a drone log is for: the first download shown, also on
  // a phone, where the downloads are one row that scrolls (real.test.mjs checks that
  // the first is inside the screen).
  assert.equal(await firstShownExport(page), 'export-param');
  await page.setViewportSize({ width: 390, height: 844 });
  assert.equal(await firstShownExport(page), 'export-param');
  await page.setViewportSize({ width: 1360, height: 1000 });
  const { bytes, name } = await download(page, '#export-param');
  assert.equal(name, 'log171-compass.param');
  const file = bytes.toString('utf8');
  const params = Object.fromEntries(file.split('\n')
    .filter((line) => line && !line.startsWith('#')).map((line) => line.split(',')).map(([k, v]) => [k, parseFloat(v)]));
  // The file, the details and the summary say the same of every compass, and the file
  // sets a compass's parameters exactly where it says "written".
  const sentences = file.split('\n').filter((line) => /^# (Compass \d|CAL_MAG\d)/.test(line)).map((line) => line.slice(2));
  assert.equal(sentences.length, 3, file);
  for (const [index, sentence] of sentences.entries()) {
    assert.ok(calibration.includes(sentence), `details: ${sentence}`);
    assert.ok(summary.includes(sentence.slice(sentence.indexOf(': ') + 2)), `summary: ${sentence}`);
    const suffix = index === 0 ? '_' : `${index + 1}_`;
    const lines = Object.keys(params).filter((key) => key.startsWith(`COMPASS_OFS${suffix}`));
    assert.equal(lines.length, / written \(/.test(sentence) ? 3 : 0, sentence);
  }
  // The figures the page lists are the file's.
  if (Number.isFinite(params.COMPASS_OFS_X)) {
    const shown = parseFloat(calibration.match(/COMPASS_OFS_X (-?\d+\.\d+)/)[1]);
    assert.ok(Math.abs(shown - params.COMPASS_OFS_X) < 1e-3, `${shown} shown, ${params.COMPASS_OFS_X} written`);
  }
  await page.screenshot({ path: join(out, 'ardupilot.png'), fullPage: false });
  // The text log and PX4's logs are read too, with the autopilot's heading as reference.
  const data = join(import.meta.dirname, '../../../shared/data');
  for (const [file, format] of [['ardupilot-text-log/nan.log', /ArduPilot DataFlash text log/],
    ['px4-ulog/sample.ulg', /PX4 ULog/], ['px4-ulog/sample_log_small.ulg', /PX4 ULog/]]) {
    await page.setInputFiles('#file-input', join(data, file));
    await waitForState(page, 'ready', file.split('/')[1]);
    assert.match(await text(page, 'streams'), format, file);
    assert.match(await text(page, 'context'), /autopilot's own heading/, file);
    // nan.log's second compass beats its parameters in force and is written; PX4's
    // sample.ulg has no position for the model's field and barely turns, and 6.5 s of
    // sample_log_small.ulg are too few: nothing is offered, and the button says why.
    const offered = !(await page.isDisabled('#export-param'));
    assert.equal(offered, file === 'ardupilot-text-log/nan.log', file);
    if (!offered) {
      const why = await page.getAttribute('#export-param', 'title');
      assert.match(why, /^Nothing to write: .*parameters in force kept/, `${file}: ${why}`);
    }
  }
  assert.deepEqual(problems, []);
  await close();
});
