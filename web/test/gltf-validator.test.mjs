// The Khronos glTF-Validator (npm `gltf-validator`) on every kind of glTF
// radiosity writes or reads in its tests: --bake in both modes and both
// targets (vertices, lightmap) as .glb and .gltf (from the built-in Cornell
// box, from the hand-written tests/data/hierarchy.gltf with its texture and
// node hierarchy, from the Blender exports tests/data/blender-*.glb, and
// from the built-in room written by export-scene), export-scene of both
// built-in scenes, and the hand-written inputs themselves. Any error fails;
// warnings and infos are printed.
import { existsSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { validate } from '../validate.mjs';
import { radiosity, tempDir } from './helpers.mjs';

const repo = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
const data = join(repo, 'tests', 'data');
const dir = tempDir('validator');
const quick = ['-q', '--width', '160', '--height', '120', '--supersampling', '1', '--converge', '0.05'];

const files = [];
const room = join(dir, 'room-input.glb');
radiosity(['export-scene', 'room', room]);
const inputs = ['cornell', join(data, 'hierarchy.gltf'), room];
for (const blender of ['blender-cornell.glb', 'blender-lights.glb']) {
  if (existsSync(join(data, blender))) inputs.push(join(data, blender));
}
for (const [i, scene] of inputs.entries()) {
  for (const target of ['vertices', 'lightmap']) {
    for (const mode of ['lit', 'irradiance']) {
      for (const ext of ['glb', 'gltf']) {
        const out = join(dir, `bake-${i}-${target}-${mode}.${ext}`);
        radiosity(['render', scene, ...quick, '--output', join(dir, `bake-${i}.png`), '--bake', out,
          '--bake-mode', mode, '--bake-target', target]);
        files.push(out);
      }
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
for (const file of files) errors += await validate(file);
console.log(`validated ${files.length} files`);
if (errors > 0) throw new Error(`${errors} validation error(s)`);
