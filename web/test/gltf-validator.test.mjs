// The Khronos glTF-Validator (npm `gltf-validator`) on every kind of glTF
// radiosity writes or reads in its tests: --bake in both modes as .glb and
// .gltf (from the built-in Cornell box, from the hand-written
// tests/data/hierarchy.gltf with its texture, and from the Blender export
// tests/data/blender-cornell.glb), export-scene of both built-in scenes, and
// the hand-written inputs themselves. Any error fails; warnings and infos
// are printed.
import { existsSync, readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import validator from 'gltf-validator';
import { radiosity, tempDir } from './helpers.mjs';

const repo = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const data = join(repo, 'tests', 'data');
const dir = tempDir('validator');
const quick = ['-q', '--width', '160', '--height', '120', '--supersampling', '1', '--converge', '0.05'];

const files = [];
const inputs = ['cornell', join(data, 'hierarchy.gltf')];
if (existsSync(join(data, 'blender-cornell.glb'))) inputs.push(join(data, 'blender-cornell.glb'));
for (const [i, scene] of inputs.entries()) {
  for (const mode of ['lit', 'irradiance']) {
    for (const ext of ['glb', 'gltf']) {
      const out = join(dir, `bake-${i}-${mode}.${ext}`);
      radiosity(['render', scene, ...quick, '--output', join(dir, `bake-${i}.png`), '--bake', out,
        '--bake-mode', mode]);
      files.push(out);
    }
  }
}
for (const scene of ['room', 'cornell']) {
  for (const ext of ['glb', 'gltf']) {
    const out = join(dir, `export-${scene}.${ext}`);
    radiosity(['export-scene', scene, out]);
    files.push(out);
  }
}
files.push(...inputs.filter((s) => s.includes('/')));

let errors = 0;
for (const file of files) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file,
    maxIssues: 0,
    externalResourceFunction: (uri) => Promise.resolve(
      new Uint8Array(readFileSync(join(dirname(file), decodeURIComponent(uri))))),
  });
  const { numErrors, numWarnings, numInfos, messages } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  for (const m of messages.filter((m) => m.severity <= 2)) {
    console.log(`  ${["ERROR", "warning", "info"][m.severity]} ${m.code} ${m.pointer || ''}: ${m.message}`);
  }
  errors += numErrors;
}
console.log(`validated ${files.length} files`);
if (errors > 0) throw new Error(`${errors} validation error(s)`);
