// glb_validate.cjs FILE... - the Khronos glTF-Validator on each .glb: prints
// its counts and messages, exits 1 when any has an error or a warning.
const { readFileSync } = require('fs');
const validator = require('gltf-validator');

(async () => {
  let failed = false;
  for (const path of process.argv.slice(2)) {
    const report = await validator.validateBytes(new Uint8Array(readFileSync(path)), { maxIssues: 100 });
    const { numErrors, numWarnings, numInfos, messages } = report.issues;
    console.log(`${path}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
    for (const m of messages) console.log(`  ${['error', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer}: ${m.message}`);
    if (numErrors > 0 || numWarnings > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})();
