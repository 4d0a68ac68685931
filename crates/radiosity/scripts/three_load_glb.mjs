#!/usr/bin/env node
// Loads GLB files with three.js's GLTFLoader in Node and prints what a viewer would get:
// meshes, their attributes, material type, emissive map and its UV channel, vertex colours.
// Exits 1 if a file fails to parse or a mesh lacks the lightmap binding.
//
// Usage:
//   npm install three                   # once, in the directory you run this from
//   node crates/radiosity/scripts/three_load_glb.mjs out/scene.glb [more.glb ...]
//
// Node has no DOM: createImageBitmap is stubbed to read the PNG header only (width and height),
// which is all GLTFLoader needs to build the Texture; pixels are not decoded.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node three_load_glb.mjs FILE.glb [FILE.glb ...]');
  process.exit(2);
}
// The ES module build, and the loader beside it (its bare 'three' import then resolves to the
// same module instance).
const base = path.join(path.resolve(process.env.THREE_DIR ?? process.cwd()), 'noop.js');
// require.resolve('three') gives <dir>/build/three.cjs ('package.json' is not exported).
const threeDir = path.dirname(path.dirname(createRequire(base).resolve('three')));
const THREE = await import(pathToFileURL(path.join(threeDir, 'build/three.module.js')).href);
const { GLTFLoader } = await import(
  pathToFileURL(path.join(threeDir, 'examples/jsm/loaders/GLTFLoader.js')).href);

globalThis.self ??= globalThis; // GLTFLoader reads self.URL for blob URLs of embedded images

globalThis.createImageBitmap = async (blob) => {
  const bytes = new Uint8Array(await blob.arrayBuffer());
  const view = new DataView(bytes.buffer);
  // PNG: 8-byte signature, IHDR chunk: length, type, width, height (big-endian).
  return { width: view.getUint32(16), height: view.getUint32(20), close() {} };
};

let failed = false;
for (const file of files) {
  const data = await readFile(file);
  const buffer = data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);
  let gltf;
  try {
    gltf = await new GLTFLoader().parseAsync(buffer, '');
  } catch (e) {
    console.log(`${file}: three.js r${THREE.REVISION} GLTFLoader failed: ${e.message ?? e}`);
    failed = true;
    continue;
  }
  const meshes = [];
  gltf.scene.traverse((o) => { if (o.isMesh) meshes.push(o); });
  console.log(`${file}: three.js r${THREE.REVISION}: ${meshes.length} meshes, ` +
    `${gltf.cameras.length} camera(s), scene '${gltf.scene.name}'`);
  for (const [k, mesh] of meshes.entries()) {
    const g = mesh.geometry;
    const m = mesh.material;
    const attributes = Object.entries(g.attributes)
      .map(([name, a]) => `${name}:${a.itemSize}x${a.array.constructor.name}${a.normalized ? ' norm' : ''}`)
      .join(' ');
    const map = m.emissiveMap;
    const ok = map && map.channel === 1 && 'uv1' in g.attributes && m.color.getHex() === 0;
    if (!ok) failed = true;
    if (k < 3 || !ok) {
      console.log(`  '${mesh.name}': ${g.attributes.position.count} vertices; ${attributes}; ` +
        `${m.type} color #${m.color.getHexString()} emissive #${m.emissive.getHexString()} ` +
        `emissiveMap ${map ? `${map.image.width}x${map.image.height} channel ${map.channel} ` +
        `colorSpace ${map.colorSpace}` : 'MISSING'}; specularIntensity ${m.specularIntensity}; ` +
        `vertexColors ${m.vertexColors}${ok ? '' : '  <-- lightmap not bound'}`);
    }
  }
  if (meshes.length > 3) console.log(`  … and ${meshes.length - 3} more meshes like these`);
}
process.exit(failed ? 1 : 0);
