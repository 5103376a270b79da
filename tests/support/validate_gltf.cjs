// Runs the Khronos glTF validator (npm package gltf-validator) on one .glb/.gltf file.
// usage: node validate_gltf.cjs VALIDATOR_MODULE_DIR FILE
// Prints the report's counts and every message; exit 0 when the file has no errors and no warnings, 1 when it
// has any, 2 when the validator cannot be loaded or the file cannot be read.
'use strict';
const fs = require('fs');
const path = require('path');

const [moduleDir, file] = process.argv.slice(2);
let validator;
try {
  validator = require(path.resolve(moduleDir));
} catch (e) {
  console.error(`cannot load gltf-validator from ${moduleDir}: ${e.message}`);
  process.exit(2);
}
let bytes;
try {
  bytes = new Uint8Array(fs.readFileSync(file));
} catch (e) {
  console.error(`cannot read ${file}: ${e.message}`);
  process.exit(2);
}
validator
  .validateBytes(bytes, {uri: path.basename(file), maxIssues: 100})
  .then((report) => {
    const i = report.issues;
    console.log(`gltf-validator ${report.validatorVersion}: ${i.numErrors} errors, ${i.numWarnings} warnings, ` +
                `${i.numInfos} infos, ${i.numHints} hints`);
    for (const m of i.messages) console.log(`  [severity ${m.severity}] ${m.code} at ${m.pointer || m.offset || ''}: ${m.message}`);
    process.exit(i.numErrors > 0 || i.numWarnings > 0 ? 1 : 0);
  })
  .catch((e) => {
    console.error(`gltf-validator failed on ${file}: ${e}`);
    process.exit(2);
  });
