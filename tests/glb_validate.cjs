// glb_validate.cjs FILE... - the Khronos glTF-Validator on each .glb or
// .gltf (its buffers and images read from beside it): prints its counts and
// messages, exits 1 when any has an error or a warning.
const { readFileSync } = require('fs');
const { dirname, join } = require('path');
const validator = require('gltf-validator');

(async () => {
  let failed = false;
  for (const path of process.argv.slice(2)) {
    const options = {
      maxIssues: 100,
      uri: path,
      format: path.endsWith('.gltf') ? 'gltf' : 'glb',
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          try { resolve(new Uint8Array(readFileSync(join(dirname(path), decodeURIComponent(uri))))); }
          catch (e) { reject(e.toString()); }
        }),
    };
    const report = await validator.validateBytes(new Uint8Array(readFileSync(path)), options);
    const { numErrors, numWarnings, numInfos, messages } = report.issues;
    console.log(`${path}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
    for (const m of messages) console.log(`  ${['error', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer}: ${m.message}`);
    if (numErrors > 0 || numWarnings > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})();
