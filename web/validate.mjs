// Validates glTF files with the Khronos glTF-Validator (npm
// `gltf-validator`; `npm ci` in web/ installs it):
//   node web/validate.mjs FILE.glb [FILE.gltf ...]
// prints each file's errors, warnings and infos, and exits 1 if any file
// has an error. Also imported by web/test/gltf-validator.test.mjs.
import { readFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { pathToFileURL } from 'node:url';
import validator from 'gltf-validator';

/** Validates one file (external buffers and images read beside it);
 * returns the number of errors. */
export async function validate(file, log = console.log) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file,
    maxIssues: 0,
    externalResourceFunction: (uri) => Promise.resolve(
      new Uint8Array(readFileSync(join(dirname(file), decodeURIComponent(uri))))),
  });
  const { numErrors, numWarnings, numInfos, messages } = report.issues;
  log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  for (const m of messages) {
    log(`  ${['ERROR', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer || ''}: ${m.message}`);
  }
  return numErrors;
}

if (import.meta.url === pathToFileURL(process.argv[1]).href) {
  if (process.argv.length < 3) {
    console.error('usage: node web/validate.mjs FILE.glb|FILE.gltf ...');
    process.exit(2);
  }
  let errors = 0;
  for (const file of process.argv.slice(2)) errors += await validate(file);
  process.exit(errors > 0 ? 1 : 0);
}
