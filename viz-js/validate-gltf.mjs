// Validate glTF/GLB files with the Khronos glTF validator (npm gltf-validator); prints one JSON report
// per file ({file, errors, warnings, infos, messages}) and exits 1 when any file has errors.
// Usage: node viz-js/validate-gltf.mjs FILE...
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

let failed = false;
for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file, maxIssues: 100, externalResourceFunction: () => Promise.reject(new Error('no external files')),
  });
  const i = report.issues;
  const out = { file, validatorVersion: report.validatorVersion, errors: i.numErrors, warnings: i.numWarnings,
    infos: i.numInfos, messages: i.messages.map((m) => `${m.severity}:${m.code}:${m.pointer || ''}:${m.message}`) };
  console.log(JSON.stringify(out));
  if (i.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
