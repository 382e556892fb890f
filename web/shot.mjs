// Screenshot of a bake in the viewer, as the browser test takes it:
//   node web/shot.mjs FILE.glb OUT.png [WIDTH HEIGHT]
// (`radiosity view FILE` is started and stopped; headless Chromium from
// $CHROMIUM or /usr/bin/chromium). For looking at bakes by hand.
import { spawn } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import { chromium } from 'playwright-core';

const BIN = process.env.RADIOSITY_BIN || new URL('../target/release/radiosity', import.meta.url).pathname;
// As web/test/helpers.mjs (which needs RADIOSITY_BIN set by .ci/web-tests).
const CHROMIUM_ARGS = [
  '--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--ignore-gpu-blocklist', '--disable-quic', '--no-first-run', '--disable-background-networking',
  '--disable-component-update', '--disable-sync', '--force-color-profile=srgb',
];

const [file, out, width = '800', height = '600'] = process.argv.slice(2);
if (!file || !out) throw new Error('usage: node web/shot.mjs FILE.glb OUT.png [WIDTH HEIGHT]');
const server = spawn(BIN, ['view', file, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
const url = await new Promise((resolve, reject) => {
  let text = '';
  server.stdout.on('data', (chunk) => {
    text += chunk;
    const m = text.match(/http:\/\/127\.0\.0\.1:\d+\/\S*/);
    if (m) resolve(m[0]);
  });
  server.on('exit', (code) => reject(new Error(`radiosity view exited (${code})`)));
});
const browser = await chromium.launch({ executablePath: process.env.CHROMIUM || '/usr/bin/chromium', args: CHROMIUM_ARGS });
try {
  const page = await browser.newPage({ viewport: { width: Number(width), height: Number(height) }, deviceScaleFactor: 1 });
  await page.goto(`${url}&ui=0`);
  await page.waitForFunction(() => window.viewer, null, { timeout: 120000 });
  const state = await page.evaluate(() => window.viewer);
  if (!state.ready) throw new Error(state.error);
  writeFileSync(out, await page.locator('canvas').screenshot());
  console.log(`${file}: ${state.mode} ${state.target} bake, screenshot ${out}`);
} finally {
  await browser.close();
  server.kill();
}
