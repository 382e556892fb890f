// `radiosity serve` in headless Chromium: the page shows the Cornell box
// converging (the canvas brightens and the unshot fraction shown falls
// between updates), pause holds the solve, the ambient switch and the
// exposure slider change the picture, the picker shows the solver's value,
// and Stop writes the outputs asked for on the command line. Run by
// .ci/web-tests with RADIOSITY_BIN and CHROMIUM set; exits non-zero on
// failure. SERVE_SCREENSHOT=FILE.png also saves the page (docs/serve.png).
//
// The default preset converges the Cornell box in well under a second, too
// fast to watch. Here the paper's method (--preset wong-tsang93, one patch
// a shot, as in its Figure 5.1), elements half the default size (four times
// the vertices) and 8 x 8 subsources make a shot take about a tenth of a
// second here, and --converge 1e-9 puts the end thousands of shots away.
// Nothing in the test depends on how fast the machine is: --pause-at holds
// the solve at shots 1, 8, 16 and 40 (the unshot fraction there is the
// same on any machine), the test acts while it is held or before the next
// hold, and it waits for events the page marks (a frame drawn, a vertex
// shown) rather than for time to pass. --no-ambient makes the page start
// without the ambient term, so the picture shows B itself brightening.

import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, readdirSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { createInterface } from 'node:readline';
import { chromium } from 'playwright-core';
import { PATIENCE } from './helpers.mjs';

const bin = process.env.RADIOSITY_BIN;
const executablePath = process.env.CHROMIUM;
assert.ok(bin, 'RADIOSITY_BIN is not set');
assert.ok(executablePath, 'CHROMIUM is not set');

const WAIT = PATIENCE; // longest wait for one condition, ms
let browser;
const dir = mkdtempSync(join(tmpdir(), 'radiosity-serve-'));
const out = { png: join(dir, 'box.png'), csv: join(dir, 'box.csv'), json: join(dir, 'box.json') };

// The browser starts first, so the page opens as soon as the server does.
browser = await chromium.launch({
  executablePath,
  args: [
    '--headless', '--no-sandbox', '--no-first-run', '--disable-quic',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  ],
});
const server = spawn(bin, [
  'serve', 'cornell', '--port', '0', '--no-ambient', '--preset', 'wong-tsang93',
  '--element-size', '0.012', '--subsources', '8', '--converge', '1e-9', '--threads', '1',
  '--pause-at', '1,8,16,40',
  '--output', out.png, '--vertices', out.csv, '--stats', out.json,
  '--width', '200', '--height', '150',
], { stdio: ['ignore', 'pipe', 'inherit'] });
const exited = new Promise((resolve) => server.on('exit', (code, signal) => resolve({ code, signal })));
const guard = setTimeout(() => {
  console.error('serve.test: timed out');
  server.kill('SIGKILL');
  process.exit(1);
}, 4 * WAIT);

try {
  const url = await new Promise((resolve, reject) => {
    const lines = createInterface({ input: server.stdout });
    lines.once('line', (line) => {
      const m = /^serving (http:\/\/127\.0\.0\.1:\d+\/)$/.exec(line);
      if (m) resolve(m[1]);
      else reject(new Error(`unexpected first line: ${line}`));
    });
    server.once('exit', () => reject(new Error('radiosity serve exited before serving')));
  });
  // Keep reading so the server never blocks on a full pipe.
  server.stdout.resume();

  const page = await browser.newPage({ viewport: { width: 1000, height: 640 } });
  page.setDefaultTimeout(WAIT);
  const problems = [];
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console: ${m.text()}`); });
  // A blank page of our own decodes screenshots with the browser's PNG
  // decoder.
  const decoder = await browser.newPage();

  const updates = () => page.evaluate(() => Number(document.body.dataset.updates ?? 0));
  const text = (id) => page.textContent(`#${id}`);
  const unshotShown = async () => {
    const t = await text('unshot');
    const m = /^([0-9.e+-]+) %$/.exec(t);
    assert.ok(m, `unshot fraction shown as ${t}`);
    return Number(m[1]) / 100;
  };
  const count = async (id) => Number((await text(id)).replace(/[^0-9]/g, ''));

  // Mean sRGB luma (0-255) of the canvas as shown.
  async function brightness() {
    const png = await page.locator('#view').screenshot();
    return decoder.evaluate(async (b64) => {
      const img = new Image();
      img.src = `data:image/png;base64,${b64}`;
      await img.decode();
      const c = new OffscreenCanvas(img.width, img.height);
      const g = c.getContext('2d');
      g.drawImage(img, 0, 0);
      const d = g.getImageData(0, 0, img.width, img.height).data;
      let sum = 0;
      for (let i = 0; i < d.length; i += 4) sum += 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2];
      return sum / (d.length / 4);
    }, png.toString('base64'));
  }

  const waitFor = (what, fn, arg) => page.waitForFunction(fn, arg, { timeout: WAIT })
    .catch((e) => { throw new Error(`waiting for ${what}: ${e.message}`); });

  const draws = () => page.evaluate(() => Number(document.body.dataset.draws ?? 0));

  // Waits until the page has drawn the solve held at `shots` by
  // --pause-at; returns its update count, unshot fraction shown and
  // brightness.
  async function held(shots) {
    await waitFor(`the hold at shot ${shots}`, (n) => document.getElementById('phase').textContent === 'paused'
      && Number(document.getElementById('shots').textContent.replace(/[^0-9]/g, '')) === n
      && document.body.dataset.seq === document.body.dataset.status, shots);
    assert.equal(await text('pause'), 'Resume');
    return { updates: await updates(), unshot: await unshotShown(), luma: await brightness() };
  }

  async function resume() {
    const shots = await count('shots');
    await page.click('#pause');
    await waitFor('shots after resume',
      (n) => Number(document.getElementById('shots').textContent.replace(/[^0-9]/g, '')) > n, shots);
  }

  // Changes a control and waits until the canvas has been drawn since.
  async function redrawn(change) {
    const before = await draws();
    await change();
    await waitFor('a redraw', (n) => Number(document.body.dataset.draws ?? 0) > n, before);
  }

  await page.goto(url);
  await waitFor('a first update', () => Number(document.body.dataset.updates ?? 0) >= 1);
  assert.match(await text('scene-name'), /^cornell: [0-9,]+ vertices$/);
  assert.equal(await page.isChecked('#ambient'), false, '--no-ambient starts with the ambient term off');

  // The first shot, and two holds later (two more updates at least), with
  // the unshot power well down.
  const first = await held(1);
  await resume();
  await held(8);
  await resume();
  const later = await held(16);
  console.log(`update ${first.updates}: unshot ${first.unshot}, luma ${first.luma.toFixed(1)}; ` +
    `update ${later.updates}: unshot ${later.unshot}, luma ${later.luma.toFixed(1)}`);
  assert.ok(later.updates >= first.updates + 2);
  assert.ok(later.unshot <= 0.5 * first.unshot, 'the unshot fraction shown fell');
  assert.ok(later.luma > 1.05 * first.luma, 'the canvas brightened');

  // While held (the picture holds still): the ambient term adds light
  // that is not shot yet, and a stop of exposure brightens.
  const off = later.luma;
  await redrawn(() => page.check('#ambient'));
  const on = await brightness();
  assert.ok(on > 1.02 * off, `ambient on ${on} vs off ${off}`);
  await redrawn(() => page.uncheck('#ambient'));
  await redrawn(() => page.locator('#exposure').fill('1'));
  assert.equal(await text('exposure-value'), '+1.0 EV');
  const brighter = await brightness();
  assert.ok(brighter > 1.1 * off, `+1 EV ${brighter} vs ${off}`);
  await page.locator('#exposure').fill('0');
  console.log(`paused: luma ${off.toFixed(1)}, with the ambient term ${on.toFixed(1)}, ` +
    `at +1 EV ${brighter.toFixed(1)}`);
  // No shot while paused, through all of that.
  assert.equal(await count('shots'), 16, 'no shot while paused');
  assert.equal(await text('phase'), 'paused');
  await resume();

  // The picker while the solve runs (and the README's picture).
  const box = await page.locator('#view').boundingBox();
  const centre = [box.x + box.width / 2, box.y + box.height / 2];
  await page.mouse.click(...centre);
  await waitFor('the picked vertex', () => !document.getElementById('picked').hidden);
  assert.match(await text('picked-radiosity'), /^[0-9.e+-]+, [0-9.e+-]+, [0-9.e+-]+$/);
  if (process.env.SERVE_SCREENSHOT) {
    await redrawn(() => page.check('#ambient'));
    await page.screenshot({ path: process.env.SERVE_SCREENSHOT });
    await page.uncheck('#ambient');
  }

  // Stop: the solve ends, the outputs are written.
  await page.click('#stop');
  await waitFor('the end', () => document.getElementById('phase').textContent === 'finished (stopped)');
  const written = await text('written');
  for (const file of Object.values(out)) assert.ok(written.includes(file), `${written} lists ${file}`);
  assert.ok(await page.isDisabled('#stop'));
  assert.ok(await page.isDisabled('#pause'));
  // The paper's preset has no final pass: no final picture is offered
  // (tests/serve.rs checks the server's picture under the default).
  assert.equal(await page.evaluate(() => document.getElementById('final-row').hidden), true);

  // The picker, now on the final state: the vertex nearest the click,
  // with the solver's value (once the page shows the answer to this
  // click's query).
  const asked = await page.evaluate(() => Number(document.body.dataset.picksAsked ?? 0));
  await page.mouse.click(...centre);
  await waitFor('the picked vertex on the final state', (n) => {
    const shown = Number(document.body.dataset.pickShown ?? 0);
    return shown > n && shown === Number(document.body.dataset.picksAsked);
  }, asked);
  const index = Number(await text('picked-index'));
  const shown = (await text('picked-radiosity')).split(', ').map(Number);

  // The outputs: a picture of the size asked for, one CSV row per vertex,
  // statistics saying the solve was stopped at the shot count shown.
  const png = readFileSync(out.png);
  assert.deepEqual([...png.subarray(0, 8)], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
  assert.equal(png.readUInt32BE(16), 200);
  assert.equal(png.readUInt32BE(20), 150);
  const rows = readFileSync(out.csv, 'utf8').trim().split('\n');
  assert.equal(rows[0], 'x,y,z,nx,ny,nz,surface,r,g,b');
  const vertices = Number((await text('scene-name')).replace(/[^0-9]/g, ''));
  assert.equal(rows.length - 1, vertices);
  const stats = JSON.parse(readFileSync(out.json, 'utf8'));
  assert.equal(stats.stop_reason, 'stopped');
  assert.equal(stats.vertices, vertices);
  assert.equal(stats.shots, await count('shots'));
  assert.ok(stats.unshot_fraction > 0);
  assert.deepEqual(readdirSync(dir).sort(), ['box.csv', 'box.json', 'box.png']);
  const solved = rows[index + 1].split(',').slice(7).map(Number);
  for (let k = 0; k < 3; k++) {
    assert.ok(Math.abs(shown[k] - solved[k]) <= 1e-3 * Math.abs(solved[k]) + 1e-12,
      `picked vertex ${index}: shown ${shown}, solved ${solved}`);
  }

  assert.deepEqual(problems, []);
  await browser.close();
  browser = undefined;

  // The final state is served until Ctrl-C, which ends the command cleanly.
  server.kill('SIGINT');
  const { code, signal } = await exited;
  assert.equal(signal, null);
  assert.equal(code, 0);
  console.log('serve.test: 1 passed, 0 failed');
} catch (error) {
  console.error(error);
  process.exitCode = 1;
} finally {
  if (browser) await browser.close();
  if (server.exitCode === null && server.signalCode === null) server.kill('SIGKILL');
  clearTimeout(guard);
  rmSync(dir, { recursive: true, force: true });
}
