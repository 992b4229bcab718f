// End-to-end tests of the analysis controls: a change re-runs only what depends on it,
// outages can be brushed on the timeline with the mouse or typed, and the time plots and
// the trajectory zoom, pan and read the value under the pointer.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { canvasDigest, drawnPixels, openAllDetails, openPage, out, text, waitForRedraw, waitForState } from './common.mjs';

const runs = (page) => page.evaluate(() => ({
  calibration: Number(document.body.dataset.calibrationRuns),
  pdr: Number(document.body.dataset.pdrRuns),
}));

test('the controls re-run only what depends on them; an outage is brushed on the timeline', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  await page.setInputFiles('#file-input', join(out, 'pdr-walk.csv'));
  await waitForState(page, 'ready', 'pdr-walk.csv');
  await openAllDetails(page);
  assert.ok(await drawnPixels(page, 'timeline') > 2_000, 'the timeline is drawn');
  const before = await runs(page);
  // Every fix weighted (issue 42): none refused, none in an outage yet.
  const fixesBefore = await text(page, 'pdr-summary');
  assert.match(fixesBefore, /GNSS fixes: \d+ used/);
  assert.doesNotMatch(fixesBefore, /in outages|too inaccurate/);

  // The step model: only the dead reckoning runs again.
  await page.selectOption('#control-step-model', 'linear');
  await page.waitForFunction((n) => Number(document.body.dataset.pdrRuns) === n, before.pdr + 1);
  await waitForState(page, 'ready', 'pdr-walk.csv');
  assert.equal((await runs(page)).calibration, before.calibration, 'the calibration did not run again');
  assert.match(await text(page, 'pdr-summary'), /Step model: linear, SL = /);

  // An outage dragged on the timeline, from 30 % to 55 % of the walk.
  await page.locator('#timeline').scrollIntoViewIfNeeded();
  const box = await page.locator('#timeline').boundingBox();
  // The canvas is 1200 px wide inside a 1 px border; its time axis runs from 70 px to 20 px short of the end.
  const at = (fraction) => box.x + 1 + (70 + fraction * (1200 - 90)) * ((box.width - 2) / 1200);
  await page.mouse.move(at(0.30), box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(at(0.55), box.y + box.height / 2, { steps: 5 });
  await page.mouse.up();
  await page.waitForFunction((n) => Number(document.body.dataset.pdrRuns) === n, before.pdr + 2);
  await waitForState(page, 'ready', 'pdr-walk.csv');
  const outages = await page.inputValue('#control-outages');
  const match = outages.match(/^(\d+)-(\d+)$/);
  assert.ok(match, `one outage typed into the field: "${outages}"`);
  const [start, end] = [Number(match[1]), Number(match[2])];
  assert.ok(Math.abs(start - 0.30 * 240) < 6 && Math.abs(end - 0.55 * 240) < 6, `${start}-${end} s`);
  const summary = await text(page, 'pdr-summary');
  assert.match(summary, /GNSS fixes: \d+ used, .*[1-9]\d* in outages/);
  assert.match(summary, new RegExp(`In the outage ${start}-${end} s: RMS \\d+\\.\\d\\d m`));
  assert.equal((await runs(page)).calibration, before.calibration);
  await page.locator('#controls').screenshot({ path: join(out, 'controls.png') });

  // A click on the outage removes it; a typed list works as well.
  await page.mouse.click(at(0.42), box.y + box.height / 2);
  await page.waitForFunction((n) => Number(document.body.dataset.pdrRuns) === n, before.pdr + 3);
  assert.equal(await page.inputValue('#control-outages'), '');
  await page.fill('#control-outages', '20-40, nonsense');
  await page.press('#control-outages', 'Tab');
  await page.waitForFunction((n) => Number(document.body.dataset.pdrRuns) === n, before.pdr + 4);
  assert.match(await text(page, 'controls-status'), /GNSS outages: "nonsense" is not an outage/);

  // The declination: the calibration and everything after it run again.
  await page.fill('#control-declination', '10');
  await page.press('#control-declination', 'Tab');
  await page.waitForFunction((n) => Number(document.body.dataset.calibrationRuns) === n, before.calibration + 1);
  await waitForState(page, 'ready', 'pdr-walk.csv');
  assert.match(await text(page, 'context'), /Declination: 10\.00° \(given by the user\)/);
  assert.ok((await runs(page)).pdr >= before.pdr + 5, 'the dead reckoning follows the calibration');

  // Methods: the ellipsoid left out is not in the table.
  await page.uncheck('#control-method-ellipsoid');
  await page.waitForFunction((n) => Number(document.body.dataset.calibrationRuns) === n, before.calibration + 2);
  await waitForState(page, 'ready', 'pdr-walk.csv');
  assert.equal(await page.$('#row-ellipsoid'), null);
  assert.ok(await page.$('#row-ellipse'));
  assert.deepEqual(problems, []);
  await close();
});

test('the time plots and the trajectory zoom, pan and read the value under the pointer', async () => {
  const { page, problems, close } = await openPage();
  await waitForState(page, 'ready', 'demo-walk.csv');
  await openAllDetails(page);
  for (const id of ['plot-heading', 'plot-field', 'plot-trajectory']) {
    const canvas = page.locator(`#${id}`);
    await canvas.scrollIntoViewIfNeeded();
    const box = await canvas.boundingBox();
    const at = (fx, fy) => [box.x + fx * box.width, box.y + fy * box.height];
    const whole = await canvasDigest(page, id);
    assert.match(await text(page, `${id}-readout`), /Ctrl \+ wheel/, 'says how to zoom');
    // The value under the pointer, in the axes' units.
    await page.mouse.move(...at(0.5, 0.5));
    const readout = await text(page, `${id}-readout`);
    const units = id === 'plot-trajectory' ? /^east \(m\) -?[\d.]+, north \(m\) -?[\d.]+$/ : /^time \(s\) [\d.]+, /;
    assert.match(readout, units, `${id}: ${readout}`);
    // A plain wheel scrolls the page; Ctrl + wheel zooms about the pointer.
    await page.keyboard.down('Control');
    await page.mouse.wheel(0, -300);
    await page.keyboard.up('Control');
    await waitForRedraw(page, id, whole);
    await page.mouse.move(...at(0.5, 0.5));
    const zoomedReadout = await text(page, `${id}-readout`);
    // Zoomed in, the readout resolves finer: more decimals on the x value.
    const decimals = (text) => (text.split(',')[0].split('.')[1] ?? '').length;
    assert.ok(decimals(zoomedReadout) >= decimals(readout), `${readout} → ${zoomedReadout}`);
    // A drag pans; a double click shows the whole plot again.
    const zoomed = await canvasDigest(page, id);
    await page.mouse.move(...at(0.6, 0.5));
    await page.mouse.down();
    await page.mouse.move(...at(0.3, 0.5), { steps: 5 });
    await page.mouse.up();
    assert.notEqual(await canvasDigest(page, id), zoomed, `${id}: the drag panned`);
    await page.locator(`#${id}`).screenshot({ path: join(out, `zoomed-${id}.png`) });
    await page.mouse.dblclick(...at(0.5, 0.5));
    assert.equal(await canvasDigest(page, id), whole, `${id}: a double click shows the whole plot`);
  }
  assert.deepEqual(problems, []);
  await close();
});
