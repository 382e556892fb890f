// The baked Cornell box in a real browser: `radiosity render cornell
// --bake` writes the picture and the .glb; `radiosity view` serves the
// viewer page (web/viewer/, three.js GLTFLoader); headless Chromium draws
// the .glb from the bake's camera at the picture's size, and the screenshot
// is compared with our own PNG. Both targets (vertices: the element mesh
// with COLOR_0; lightmap: the input's meshes with a lightmap on TEXCOORD_1,
// at 128 texels per metre, LIGHTMAP_DENSITY to change) and both bake
// modes: lit (unlit material,
// COLOR_0 shown as is) and irradiance (the input's materials, base colour x
// COLOR_0 under the ambient light the viewer derives from the bake's
// extras), which must both look like the picture.
//
// Tolerance: mean absolute difference over all pixels and channels of at
// most 2 levels (of 255) for lit, 3 for irradiance, for either target;
// measured here 0.43 and 1.74 (vertices, against an --final-gather off
// picture), 0.64 and 1.80 (lightmap, both under the default final pass:
// the direct light at each texel and at each picture sample; 0.55 and 1.75
// before the final pass; 1.15 and 2.10 at the default 32 texels per metre,
// 1.7 cm texels on this 0.55 m box, before it). Both pictures interpolate the same vertex colours
// linearly and encode sRGB, so inside faces they agree to a level or two
// (8-bit rounding, float precision); the difference concentrates on
// silhouettes, where our 3x3 supersampling and Chromium's 4x multisampling
// (SwiftShader) cover edge pixels differently. A wrong camera, a wrong
// colour space (sRGB decoded twice: about 40 levels darker), missing vertex
// colours or a lit PBR material instead of unlit each cost tens of levels.
// Irradiance goes through three.js's physical material, which keeps the
// specular lobe's share (F0 = 0.04: a few percent at roughness 1) from the
// diffuse layer, so it shows slightly darker than base x COLOR_0: one more
// level of allowance.
import { spawn } from 'node:child_process';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { chromium } from 'playwright-core';
import { BIN, CHROMIUM_ARGS, PATIENCE, decodePng, radiosity, tempDir } from './helpers.mjs';

const WIDTH = 400;
const HEIGHT = 400;
const TOLERANCE = { lit: 2, irradiance: 3 };
const DENSITY = process.env.LIGHTMAP_DENSITY || '128';

const dir = tempDir('viewer');
// Vertex bakes hold the mesh's values, so they are compared with a picture
// of the mesh alone (--final-gather off); lightmaps take the final pass's
// direct light at each texel as the picture does at each sample, so they
// are compared with the default picture.
const FINAL_GATHER = { vertices: 'off', lightmap: 'direct' };
const ours = {};
const bakes = {};
for (const target of ['vertices', 'lightmap']) {
  const png = join(dir, `cornell-${target}.png`);
  for (const mode of ['lit', 'irradiance']) {
    const file = join(dir, `cornell-${target}-${mode}.glb`);
    bakes[`${target} ${mode}`] = { file, mode, target };
    radiosity(['render', 'cornell', '-q', '--output', png, '--bake', file, '--bake-mode', mode,
      '--bake-target', target, '--lightmap-density', DENSITY,
      '--final-gather', FINAL_GATHER[target],
      '--width', String(WIDTH), '--height', String(HEIGHT)]);
  }
  ours[target] = decodePng(readFileSync(png));
}

/** Serves `file` with `radiosity view`; resolves to [url, process]. */
function serve(file) {
  const server = spawn(BIN, ['view', file, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
  return new Promise((resolve, reject) => {
    let out = '';
    const guard = setTimeout(() => {
      server.kill();
      reject(new Error(`radiosity view printed no address in ${PATIENCE / 1000} s`));
    }, PATIENCE);
    server.stdout.on('data', (chunk) => {
      out += chunk;
      const m = out.match(/http:\/\/127\.0\.0\.1:\d+\/\S*/);
      if (m) {
        clearTimeout(guard);
        resolve([m[0], server]);
      }
    });
    server.on('exit', (code) => {
      clearTimeout(guard);
      reject(new Error(`radiosity view exited (${code}): ${out}`));
    });
  });
}

// Redness (R - G) of a band of columns at mid height.
function redness(image, x0, x1) {
  let total = 0; let n = 0;
  for (let y = Math.floor(0.3 * image.height); y < Math.floor(0.7 * image.height); y++) {
    for (let x = Math.floor(x0 * image.width); x < Math.floor(x1 * image.width); x++) {
      const i = 3 * (y * image.width + x);
      total += image.rgb[i] - image.rgb[i + 1];
      n++;
    }
  }
  return total / n;
}

const browser = await chromium.launch({ executablePath: process.env.CHROMIUM, args: CHROMIUM_ARGS });
const failures = [];
try {
  for (const [name, { file, mode, target }] of Object.entries(bakes)) {
    const [url, server] = await serve(file);
    let shot;
    try {
      const page = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT }, deviceScaleFactor: 1 });
      page.setDefaultTimeout(PATIENCE);
      const logs = [];
      page.on('console', (m) => logs.push(m.text()));
      page.on('pageerror', (e) => logs.push(String(e)));
      await page.goto(`${url}&ui=0`);
      await page.waitForFunction(() => window.viewer, null, { timeout: PATIENCE });
      const state = await page.evaluate(() => window.viewer);
      if (!state.ready) throw new Error(`${name}: the viewer failed: ${state.error}\n${logs.join('\n')}`);
      if (state.mode !== mode) throw new Error(`the bake's mode is ${state.mode}, expected ${mode}`);
      if (state.target !== target) throw new Error(`the bake's target is ${state.target}, expected ${target}`);
      shot = await page.locator('canvas').screenshot();
      await page.close();
    } finally {
      server.kill();
    }
    const screenshot = join(dir, `browser-${target}-${mode}.png`);
    writeFileSync(screenshot, shot);
    const theirs = decodePng(shot);
    const picture = ours[target];
    if (theirs.width !== picture.width || theirs.height !== picture.height) {
      throw new Error(`screenshot ${theirs.width}x${theirs.height}, picture ${picture.width}x${picture.height}`);
    }
    let sum = 0;
    for (let i = 0; i < picture.rgb.length; i++) sum += Math.abs(picture.rgb[i] - theirs.rgb[i]);
    const mad = sum / picture.rgb.length;
    // The red wall (x = 0.55) is seen on the left, the green wall (x = 0) on the right.
    const left = redness(theirs, 0.04, 0.14);
    const right = redness(theirs, 0.86, 0.96);
    console.log(`${name} bake in three.js vs our picture: mean absolute difference ${mad.toFixed(2)} levels `
      + `(tolerance ${TOLERANCE[mode]}); redness (R-G) left wall ${left.toFixed(1)}, right wall ${right.toFixed(1)}; `
      + `screenshot ${screenshot}`);
    if (!(mad <= TOLERANCE[mode])) failures.push(`${name}: mean absolute difference ${mad.toFixed(2)} > ${TOLERANCE[mode]}`);
    if (!(left > 0 && right < 0 && left - right > 100)) {
      failures.push(`${name}: the red wall (redness ${left.toFixed(1)}) is not clearly redder than the green (${right.toFixed(1)})`);
    }
  }
} finally {
  await browser.close();
}
if (failures.length > 0) throw new Error(failures.join('\n'));
