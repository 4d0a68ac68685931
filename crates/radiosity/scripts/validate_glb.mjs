#!/usr/bin/env node
// Validates glTF/GLB files with the Khronos glTF Validator and prints a summary per file.
// Exits 1 if any file has an error (warnings, infos and hints are printed but pass), 2 on
// bad usage or when the validator cannot be loaded.
//
// Usage:
//   npm install gltf-validator          # once, in the directory you run this from
//   node crates/radiosity/scripts/validate_glb.mjs out/scene.glb [more.glb ...]
//
// The validator package is resolved from the current directory (its node_modules), or from
// the directory named by GLTF_VALIDATOR_DIR.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate_glb.mjs FILE.glb [FILE.glb ...]');
  process.exit(2);
}
let validator;
try {
  const base = process.env.GLTF_VALIDATOR_DIR ?? process.cwd();
  validator = createRequire(path.join(path.resolve(base), 'noop.js'))('gltf-validator');
} catch (e) {
  console.error(`cannot load gltf-validator (run 'npm install gltf-validator' here): ${e.message}`);
  process.exit(2);
}

const severities = ['error', 'warning', 'info', 'hint'];
let failed = false;
for (const file of files) {
  let report;
  try {
    const bytes = new Uint8Array(await readFile(file));
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0,
      externalResourceFunction: (uri) =>
        readFile(path.resolve(path.dirname(file), decodeURIComponent(uri))).then(
          (data) => new Uint8Array(data)),
    });
  } catch (e) {
    console.error(`${file}: cannot validate: ${e}`);
    failed = true;
    continue;
  }
  const i = report.issues;
  console.log(`${file}: validator ${report.validatorVersion}: ${i.numErrors} errors, ` +
    `${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints`);
  const info = report.info ?? {};
  console.log(`  ${info.version ? 'glTF ' + info.version : ''} generator: ${info.generator ?? '-'}; ` +
    `${info.drawCallCount ?? '?'} draw calls, ${info.totalVertexCount ?? '?'} vertices, ` +
    `${info.totalTriangleCount ?? '?'} triangles, extensions used: ` +
    `${(info.extensionsUsed ?? []).join(', ') || '-'}`);
  for (const m of i.messages) {
    console.log(`  ${severities[m.severity] ?? m.severity} ${m.code} at ${m.pointer ?? '-'}: ${m.message}`);
  }
  if (i.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
