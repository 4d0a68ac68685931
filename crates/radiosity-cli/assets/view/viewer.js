// radiosity view: the page's script. Draws the solver's display mesh with three.js and keeps
// it up to date from the server's event stream.
//
// Colour: pixel = sRGB_encode(clamp(L · 2^exposure, 0, 1)) with the standard sRGB transfer
// curve (IEC 61966-2-1: 12.92·v for v ≤ 0.0031308, else 1.055·v^(1/2.4) − 0.055), L the
// radiance in W·m⁻²·sr⁻¹ linearly (perspective-correctly) interpolated across each triangle:
// the project's renderer's formula. It is done in our own RawShaderMaterial, so three.js
// adds no tone mapping and no colour-space conversion; the canvas has no antialiasing, so
// each pixel is the value at its centre. Triangles seen from behind are black unless their
// element is two-sided.
//
// Test hooks on <body>: data-status (connecting, running, converged, stopped, failed,
// loaded (a saved solution), disconnected), data-frame (the frame number last drawn), data-available (the newest frame
// the server announced), data-mesh-version, data-settled="true" once the solve has ended and
// its last frame is on screen, data-error (a script error, if any).
//
// URL parameters: mode=gouraud|flat|radiosity|lux, exposure=<stops>, wireframe=1, log=0,
// ui=0 (hide the panels, e.g. for screenshots).

import * as THREE from 'three';
import { OrbitControls } from './OrbitControls.js';

const $ = (id) => document.getElementById(id);
const body = document.body;
const params = new URLSearchParams(location.search);

// Photometry comes from the server (the library's radiosity::units), so the page holds no
// photometric constant: the mesh names the luminance weights w (Y = w·RGB, ITU-R BT.709),
// and each frame carries every element's illuminance in lx.
const luma = (a, i) => {
  const w = view.mesh.header.luminance_weights;
  return w[0] * a[3 * i] + w[1] * a[3 * i + 1] + w[2] * a[3 * i + 2];
};

// False-colour ramp, as sRGB-coded colours (used as is, not encoded again); the shader and
// the legend both interpolate these stops linearly.
const RAMP = [
  [0.0, 0.0, 0.0], [0.25, 0.0, 0.55], [0.0, 0.3, 0.95], [0.0, 0.75, 0.8],
  [0.3, 0.85, 0.15], [0.98, 0.86, 0.0], [1.0, 0.35, 0.0], [1.0, 1.0, 1.0],
];

function rampColour(t) {
  const x = Math.min(Math.max(t, 0), 1) * (RAMP.length - 1);
  const i = Math.min(Math.floor(x), RAMP.length - 2);
  const f = x - i;
  return RAMP[i].map((c, k) => c + (RAMP[i + 1][k] - c) * f);
}

function fail(message) {
  body.dataset.error = message;
  $('status').textContent = message;
}

window.addEventListener('error', (e) => fail('page error: ' + e.message));
window.addEventListener('unhandledrejection', (e) => fail('page error: ' + e.reason));

if (new Uint8Array(new Uint32Array([1]).buffer)[0] !== 1) {
  fail('this browser is big-endian; the viewer reads little-endian data');
  throw new Error('big-endian');
}

if (params.get('ui') === '0') body.classList.add('no-ui');

// ---------------------------------------------------------------- three.js set-up

THREE.ColorManagement.enabled = false;
const canvas = $('view');
const renderer = new THREE.WebGLRenderer({
  canvas,
  antialias: false,
  alpha: false,
  powerPreference: 'high-performance',
});
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
renderer.toneMapping = THREE.NoToneMapping;
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setClearColor(0x000000, 1);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
let controls = null;
let controlsUp = null;

const VERTEX_SHADER = `
precision highp float;
precision highp int;
uniform mat4 modelViewMatrix;
uniform mat4 projectionMatrix;
in vec3 position;
in vec3 vertexRadiance;
in vec3 elementRadiance;
in float scalar;
in float twoSided;
out vec3 vVertexL;
flat out vec3 vElementL;
flat out float vScalar;
flat out float vTwoSided;
void main() {
  vVertexL = vertexRadiance;
  vElementL = elementRadiance;
  vScalar = scalar;
  vTwoSided = twoSided;
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;

const FRAGMENT_SHADER = `
precision highp float;
precision highp int;
uniform float uScale;
uniform int uMode;
uniform float uLo;
uniform float uHi;
uniform int uLog;
uniform vec3 uRamp[${RAMP.length}];
in vec3 vVertexL;
flat in vec3 vElementL;
flat in float vScalar;
flat in float vTwoSided;
out vec4 outColor;

// clamp to [0, 1] (NaN to 0), then the sRGB transfer curve.
float encode(float v) {
  v = v >= 0.0 ? min(v, 1.0) : 0.0;
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

vec3 ramp(float t) {
  float x = clamp(t, 0.0, 1.0) * float(${RAMP.length - 1});
  int i = min(int(floor(x)), ${RAMP.length - 2});
  return mix(uRamp[i], uRamp[i + 1], x - float(i));
}

void main() {
  bool lit = gl_FrontFacing || vTwoSided > 0.5;
  if (!lit) {
    outColor = vec4(0.0, 0.0, 0.0, 1.0);
  } else if (uMode == 2) {
    float t = uLog == 1
      ? (vScalar > 0.0 ? log(vScalar / uLo) / log(uHi / uLo) : 0.0)
      : (vScalar - uLo) / (uHi - uLo);
    outColor = vec4(ramp(t), 1.0);
  } else {
    vec3 L = (uMode == 0 ? vVertexL : vElementL) * uScale;
    outColor = vec4(encode(L.r), encode(L.g), encode(L.b), 1.0);
  }
}`;

const surfaceMaterial = new THREE.RawShaderMaterial({
  glslVersion: THREE.GLSL3,
  vertexShader: VERTEX_SHADER,
  fragmentShader: FRAGMENT_SHADER,
  uniforms: {
    uScale: { value: 1 },
    uMode: { value: 0 },
    uLo: { value: 0 },
    uHi: { value: 1 },
    uLog: { value: 1 },
    uRamp: { value: RAMP.map((c) => new THREE.Vector3(...c)) },
  },
  side: THREE.DoubleSide,
  // Push the surfaces back a little so that the element edges drawn on them stay visible.
  polygonOffset: true,
  polygonOffsetFactor: 1,
  polygonOffsetUnits: 1,
});

const edgeMaterial = new THREE.RawShaderMaterial({
  glslVersion: THREE.GLSL3,
  vertexShader: `
precision highp float;
uniform mat4 modelViewMatrix;
uniform mat4 projectionMatrix;
in vec3 position;
void main() { gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }`,
  fragmentShader: `
precision highp float;
uniform vec3 uColour;
out vec4 outColor;
void main() { outColor = vec4(uColour, 1.0); }`,
  uniforms: { uColour: { value: new THREE.Vector3(0.55, 0.55, 0.6) } },
});

// ---------------------------------------------------------------- state

const view = {
  mesh: null, // parsed mesh: header and typed arrays
  frame: null, // parsed frame
  surface: null, // THREE.Mesh
  edges: null, // THREE.LineSegments
  centre: new THREE.Vector3(),
  radius: 1,
  notice: null, // latest state notice from the server
  drawnFrame: null, // frame number whose data is uploaded
  markFrame: null, // frame number to publish in data-frame after the next draw
  needsRender: true,
};

const ui = {
  mode: params.get('mode') || 'gouraud',
  exposure: Number(params.get('exposure') || 0),
  wireframe: params.get('wireframe') === '1',
  log: params.get('log') !== '0',
};
if (!['gouraud', 'flat', 'radiosity', 'lux'].includes(ui.mode)) ui.mode = 'gouraud';
if (!Number.isFinite(ui.exposure)) ui.exposure = 0;

const requestRender = () => { view.needsRender = true; };

// ---------------------------------------------------------------- data

function parseContainer(buffer, kind) {
  const bytes = new Uint8Array(buffer);
  const magic = String.fromCharCode(...bytes.subarray(0, 4));
  if (buffer.byteLength < 8 || magic !== 'RVW1') throw new Error(`${kind}: not an RVW1 body`);
  const n = new DataView(buffer).getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + n)));
  if (header.kind !== kind) throw new Error(`expected a ${kind}, got ${header.kind}`);
  const start = 8 + n;
  const arrays = {};
  for (const [name, a] of Object.entries(header.arrays)) {
    const length = a.count * a.components;
    const Type = { f32: Float32Array, u32: Uint32Array, u8: Uint8Array }[a.type];
    if (!Type) throw new Error(`${kind}: array ${name} has unknown type ${a.type}`);
    arrays[name] = new Type(buffer, start + a.offset, length);
  }
  return { header, arrays };
}

async function fetchBinary(path, kind) {
  const response = await fetch(path, { cache: 'no-store' });
  if (response.status === 404) return null;
  if (!response.ok) throw new Error(`${path}: HTTP ${response.status}`);
  return parseContainer(await response.arrayBuffer(), kind);
}

function applyMesh(mesh) {
  const { positions, triangles, element_two_sided: twoSided, element_edges: edges } = mesh.arrays;
  const triangleElement = mesh.arrays.triangle_element;
  const T = triangles.length / 3;
  // Non-indexed: each triangle gets its own three vertices, so that per-element values
  // (flat shading, false colour, two-sidedness) need no texture look-ups.
  const position = new Float32Array(9 * T);
  const sided = new Float32Array(3 * T);
  for (let t = 0; t < T; t++) {
    const e = triangleElement[t];
    for (let k = 0; k < 3; k++) {
      const v = triangles[3 * t + k];
      position.set(positions.subarray(3 * v, 3 * v + 3), 9 * t + 3 * k);
      sided[3 * t + k] = twoSided[e];
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(position, 3));
  geometry.setAttribute('vertexRadiance', new THREE.BufferAttribute(new Float32Array(9 * T), 3));
  geometry.setAttribute('elementRadiance', new THREE.BufferAttribute(new Float32Array(9 * T), 3));
  geometry.setAttribute('scalar', new THREE.BufferAttribute(new Float32Array(3 * T), 1));
  geometry.setAttribute('twoSided', new THREE.BufferAttribute(sided, 1));
  geometry.computeBoundingSphere();

  const edgeGeometry = new THREE.BufferGeometry();
  edgeGeometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  edgeGeometry.setIndex(new THREE.BufferAttribute(edges, 1));

  if (view.surface) {
    scene.remove(view.surface, view.edges);
    view.surface.geometry.dispose();
    view.edges.geometry.dispose();
  }
  view.surface = new THREE.Mesh(geometry, surfaceMaterial);
  view.edges = new THREE.LineSegments(edgeGeometry, edgeMaterial);
  view.edges.visible = ui.wireframe;
  view.surface.frustumCulled = false;
  view.edges.frustumCulled = false;
  scene.add(view.surface, view.edges);

  const first = view.mesh === null;
  view.mesh = mesh;
  view.frame = null;
  view.drawnFrame = null;
  view.centre.copy(geometry.boundingSphere.center);
  view.radius = Math.max(geometry.boundingSphere.radius, 1e-6);
  body.dataset.meshVersion = String(mesh.header.version);
  const up = new THREE.Vector3(...mesh.header.camera.up).normalize();
  if (first || !controlsUp || !controlsUp.equals(up)) resetCamera();
  requestRender();
}

function applyFrame(frame) {
  const mesh = view.mesh;
  if (!mesh || frame.header.mesh_version !== mesh.header.version) return false;
  view.frame = frame;
  const { triangles, triangle_element: triangleElement } = mesh.arrays;
  const { vertex_radiance: vertexL, element_radiosity: B } = frame.arrays;
  const geometry = view.surface.geometry;
  const vr = geometry.getAttribute('vertexRadiance');
  const er = geometry.getAttribute('elementRadiance');
  const T = triangles.length / 3;
  for (let t = 0; t < T; t++) {
    const e = triangleElement[t];
    for (let k = 0; k < 3; k++) {
      const v = triangles[3 * t + k];
      const o = 9 * t + 3 * k;
      for (let c = 0; c < 3; c++) {
        vr.array[o + c] = vertexL[3 * v + c];
        er.array[o + c] = B[3 * e + c] / Math.PI;
      }
    }
  }
  vr.needsUpdate = true;
  er.needsUpdate = true;
  updateScalars();
  view.drawnFrame = frame.header.frame;
  view.markFrame = frame.header.frame;
  requestRender();
  return true;
}

// The per-element value shown in false colour: Y(B) in W·m⁻², or 683·Y(E) in lx.
function elementScalars() {
  const frame = view.frame;
  if (!frame) return null;
  const n = view.mesh.header.element_count;
  const out = new Float32Array(n);
  if (ui.mode === 'lux') {
    out.set(frame.arrays.element_illuminance);
  } else {
    const B = frame.arrays.element_radiosity;
    for (let e = 0; e < n; e++) out[e] = luma(B, e);
  }
  return out;
}

function updateScalars() {
  const falseColour = ui.mode === 'radiosity' || ui.mode === 'lux';
  const u = surfaceMaterial.uniforms;
  u.uMode.value = ui.mode === 'gouraud' ? 0 : ui.mode === 'flat' ? 1 : 2;
  u.uLog.value = ui.log ? 1 : 0;
  $('legend').hidden = !falseColour || !view.frame;
  if (!falseColour || !view.frame) return;
  const values = elementScalars();
  const positive = values.filter((v) => v > 0).sort((a, b) => a - b);
  const hi = positive.length ? positive[positive.length - 1] : 1;
  // Logarithmic: from the smallest positive value (at most four decades below the largest,
  // so that one near-black element does not squeeze the rest); linear: from zero.
  const low = positive.length ? positive[0] : hi / 1000;
  const lo = ui.log ? Math.min(Math.max(low, hi / 1e4), hi / 1.001) : 0;
  u.uLo.value = lo;
  u.uHi.value = hi;
  const { triangle_element: triangleElement } = view.mesh.arrays;
  const attribute = view.surface.geometry.getAttribute('scalar');
  for (let t = 0; t < triangleElement.length; t++) {
    attribute.array.fill(values[triangleElement[t]], 3 * t, 3 * t + 3);
  }
  attribute.needsUpdate = true;
  drawLegend(lo, hi);
  requestRender();
}

function drawLegend(lo, hi) {
  $('legend-title').textContent = ui.mode === 'lux'
    ? 'illuminance, lx'
    : 'radiosity Y(B), W·m⁻²';
  const bar = $('legend-bar');
  const g = bar.getContext('2d');
  for (let x = 0; x < bar.width; x++) {
    const [r, gr, b] = rampColour(x / (bar.width - 1)).map((c) => Math.round(c * 255));
    g.fillStyle = `rgb(${r},${gr},${b})`;
    g.fillRect(x, 0, 1, bar.height);
  }
  const ticks = $('legend-ticks');
  ticks.replaceChildren();
  for (let i = 0; i <= 4; i++) {
    const t = i / 4;
    const value = ui.log ? lo * Math.pow(hi / lo, t) : lo + (hi - lo) * t;
    const span = document.createElement('span');
    span.style.left = `${t * 100}%`;
    span.textContent = Number(value.toPrecision(3)).toString();
    ticks.append(span);
  }
}

// ---------------------------------------------------------------- camera

function resetCamera() {
  const c = view.mesh.header.camera;
  camera.fov = c.fov_deg;
  camera.up.set(...c.up).normalize();
  camera.position.set(...c.eye);
  const target = new THREE.Vector3(...c.target);
  camera.lookAt(target);
  if (!controls || !controlsUp.equals(camera.up)) {
    // OrbitControls takes its orbit axis from camera.up when it is made.
    if (controls) controls.dispose();
    controls = new OrbitControls(camera, canvas);
    controls.addEventListener('change', requestRender);
    controlsUp = camera.up.clone();
  }
  controls.enabled = !fly.active;
  controls.target.copy(target);
  controls.update();
  resize();
  requestRender();
}

function resize() {
  const w = Math.max(window.innerWidth, 1);
  const h = Math.max(window.innerHeight, 1);
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  requestRender();
}
window.addEventListener('resize', resize);

// Near and far planes around the mesh's bounding sphere, for depth precision.
function fitClipPlanes() {
  const d = camera.position.distanceTo(view.centre);
  const near = Math.max((d - view.radius) * 0.9, view.radius * 1e-4);
  const far = Math.max(d + view.radius * 1.1, near * 2);
  if (near !== camera.near || far !== camera.far) {
    camera.near = near;
    camera.far = far;
    camera.updateProjectionMatrix();
  }
}

// Fly mode: drag to look, WASD to move, Q/E down and up, Shift four times faster.
const fly = { active: false, keys: new Set(), last: 0, distance: 1 };

function setFly(active) {
  if (!view.mesh || fly.active === active) return;
  fly.active = active;
  $('fly').classList.toggle('active', active);
  if (active) {
    fly.distance = controls.target.distanceTo(camera.position);
    controls.enabled = false;
  } else {
    const forward = camera.getWorldDirection(new THREE.Vector3());
    controls.target.copy(camera.position).addScaledVector(forward, fly.distance);
    controls.enabled = true;
    controls.update();
  }
  requestRender();
}

function flyStep(dt) {
  if (!fly.active || fly.keys.size === 0) return;
  const forward = camera.getWorldDirection(new THREE.Vector3());
  const right = new THREE.Vector3().crossVectors(forward, camera.up).normalize();
  const move = new THREE.Vector3();
  const axis = { w: [forward, 1], s: [forward, -1], d: [right, 1], a: [right, -1], e: [camera.up, 1], q: [camera.up, -1] };
  for (const key of fly.keys) if (axis[key]) move.addScaledVector(axis[key][0], axis[key][1]);
  if (move.lengthSq() === 0) return;
  const speed = view.radius * 0.6 * (fly.keys.has('shift') ? 4 : 1);
  camera.position.addScaledVector(move.normalize(), speed * dt);
  requestRender();
}

function flyLook(dx, dy) {
  const k = (camera.fov * Math.PI / 180) / Math.max(window.innerHeight, 1);
  const yaw = new THREE.Quaternion().setFromAxisAngle(camera.up, -dx * k);
  const pitch = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(1, 0, 0), -dy * k);
  const before = camera.quaternion.clone();
  camera.quaternion.premultiply(yaw).multiply(pitch);
  const forward = camera.getWorldDirection(new THREE.Vector3());
  if (Math.abs(forward.dot(camera.up)) > 0.995) camera.quaternion.copy(before);
  requestRender();
}

window.addEventListener('keydown', (e) => {
  if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
  const key = e.key.toLowerCase();
  if (key === 'f' && !e.repeat) setFly(!fly.active);
  else if (key === 'r' && !e.repeat && view.mesh) { setFly(false); resetCamera(); }
  else if (fly.active && 'wasdqe'.includes(key)) { fly.keys.add(key); e.preventDefault(); }
  if (e.shiftKey) fly.keys.add('shift');
});
window.addEventListener('keyup', (e) => {
  fly.keys.delete(e.key.toLowerCase());
  if (!e.shiftKey) fly.keys.delete('shift');
});
window.addEventListener('blur', () => fly.keys.clear());

// ---------------------------------------------------------------- picking

const pointer = { x: 0, y: 0, down: false, lastX: 0, lastY: 0 };
canvas.addEventListener('pointerdown', (e) => {
  Object.assign(pointer, { x: e.clientX, y: e.clientY, lastX: e.clientX, lastY: e.clientY, down: true });
  canvas.focus();
});
canvas.addEventListener('pointermove', (e) => {
  if (fly.active && pointer.down) flyLook(e.clientX - pointer.lastX, e.clientY - pointer.lastY);
  pointer.lastX = e.clientX;
  pointer.lastY = e.clientY;
});
canvas.addEventListener('pointerup', (e) => {
  pointer.down = false;
  if (e.button === 0 && Math.hypot(e.clientX - pointer.x, e.clientY - pointer.y) < 4) pick(e.clientX, e.clientY);
});

const raycaster = new THREE.Raycaster();

function pick(x, y) {
  if (!view.surface) return;
  const rect = canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(((x - rect.left) / rect.width) * 2 - 1, -((y - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(view.surface, false)[0];
  if (!hit) { $('pick').hidden = true; return; }
  showElement(hit.faceIndex, hit.face.normal.dot(raycaster.ray.direction) > 0);
}

function showElement(triangle, fromBehind) {
  const mesh = view.mesh;
  const e = mesh.arrays.triangle_element[triangle];
  const object = mesh.header.object_names[mesh.arrays.element_object[e]] ?? '?';
  const rgb = (a) => a ? `(${formatNumber(a[3 * e])}, ${formatNumber(a[3 * e + 1])}, ${formatNumber(a[3 * e + 2])})` : '–';
  const rows = [['element', `${e}${fromBehind ? ' (seen from behind)' : ''}`]];
  const f = view.frame;
  if (f) {
    const B = f.arrays.element_radiosity;
    const E = f.arrays.element_irradiance;
    rows.push(
      ['radiosity B', `${rgb(B)} W·m⁻²`],
      ['radiance B/π', `(${[0, 1, 2].map((c) => formatNumber(B[3 * e + c] / Math.PI)).join(', ')}) W·m⁻²·sr⁻¹`],
      ['irradiance E', `${rgb(E)} W·m⁻²`],
      ['illuminance', `${formatNumber(f.arrays.element_illuminance[e])} lx`],
    );
  }
  rows.push(
    ['reflectance ρ', rgb(mesh.arrays.element_reflectance)],
    ['two-sided', mesh.arrays.element_two_sided[e] ? 'yes' : 'no'],
  );
  $('pick-title').textContent = object;
  const table = $('pick-table');
  table.replaceChildren(...rows.map(([k, v]) => {
    const tr = document.createElement('tr');
    for (const text of [k, v]) {
      const td = document.createElement('td');
      td.textContent = text;
      tr.append(td);
    }
    return tr;
  }));
  $('pick').hidden = false;
  body.dataset.pickedElement = String(e);
}

// ---------------------------------------------------------------- controls panel

function formatNumber(x) {
  if (x === null || x === undefined || !Number.isFinite(x)) return '–';
  if (x === 0) return '0';
  const a = Math.abs(x);
  return a >= 1e5 || a < 1e-3 ? x.toExponential(2) : String(Number(x.toPrecision(4)));
}

function setExposure(stops) {
  ui.exposure = Math.min(Math.max(Math.round(stops * 10) / 10, -12), 12);
  surfaceMaterial.uniforms.uScale.value = Math.pow(2, ui.exposure);
  $('exposure').value = String(ui.exposure);
  $('exposure-value').textContent = `${ui.exposure >= 0 ? '+' : ''}${ui.exposure.toFixed(1)} EV`;
  requestRender();
}

// Exposure that maps the 99th percentile of the elements' luminance Y(B/π) to 1.
function autoExposure() {
  if (!view.frame) return;
  const B = view.frame.arrays.element_radiosity;
  const n = B.length / 3;
  const values = [];
  for (let e = 0; e < n; e++) { const y = luma(B, e) / Math.PI; if (y > 0) values.push(y); }
  if (values.length === 0) return;
  values.sort((a, b) => a - b);
  setExposure(-Math.log2(values[Math.min(values.length - 1, Math.floor(0.99 * values.length))]));
}

$('mode').value = ui.mode;
$('mode').addEventListener('change', (e) => { ui.mode = e.target.value; updateScalars(); requestRender(); });
$('exposure').addEventListener('input', (e) => setExposure(Number(e.target.value)));
$('exposure-auto').addEventListener('click', autoExposure);
$('exposure-zero').addEventListener('click', () => setExposure(0));
$('wireframe').checked = ui.wireframe;
$('wireframe').addEventListener('change', (e) => {
  ui.wireframe = e.target.checked;
  if (view.edges) view.edges.visible = ui.wireframe;
  requestRender();
});
$('log-scale').checked = ui.log;
$('log-scale').addEventListener('change', (e) => { ui.log = e.target.checked; updateScalars(); });
$('fly').addEventListener('click', () => setFly(!fly.active));
$('reset').addEventListener('click', () => { if (view.mesh) { setFly(false); resetCamera(); } });
setExposure(ui.exposure);
updateScalars();

// ---------------------------------------------------------------- progress and updates

const FINAL = ['converged', 'stopped', 'failed', 'loaded'];

function showProgress(p) {
  $('stage').textContent = p.stage;
  const plural = p.steps === 1 ? '' : 's';
  const word = p.step_word ? ` ${p.step_word}${plural}` : '';
  $('steps').textContent = `${p.steps}${word}${p.total_steps != null ? ` of ${p.total_steps}` : ''}`;
  $('quantity-name').textContent = p.quantity || 'convergence';
  $('quantity').textContent = p.value == null ? '–'
    : `${formatNumber(p.value)}${p.tolerance != null ? ` (tolerance ${formatNumber(p.tolerance)})` : ''}`;
  const eta = p.eta_s != null && !p.done ? `, about ${formatSeconds(p.eta_s)} left` : '';
  $('elapsed').textContent = `${formatSeconds(p.elapsed_s)}${eta}`;
  if (!body.dataset.error) $('status').textContent = p.done ? p.message : (p.message || 'running');
  body.dataset.status = p.status;
}

function formatSeconds(s) {
  if (!Number.isFinite(s)) return '–';
  if (s < 60) return `${s.toFixed(1)} s`;
  const m = Math.floor(s / 60);
  return m < 60 ? `${m} min ${Math.round(s % 60)} s` : `${Math.floor(m / 60)} h ${m % 60} min`;
}

function onNotice(notice) {
  if (view.notice && notice.revision <= view.notice.revision) return;
  view.notice = notice;
  body.dataset.available = notice.frame == null ? '' : String(notice.frame);
  showProgress(notice.progress);
  pump();
  settle();
}

// Fetches whatever the latest notice announces that the page lacks; one fetch at a time,
// always of the newest, so that a slow page skips frames rather than queueing them.
let pumping = false;
async function pump() {
  if (pumping) return;
  pumping = true;
  try {
    for (let round = 0; round < 4; round++) {
      const n = view.notice;
      if (n.mesh_version != null && n.mesh_version !== view.mesh?.header.version) {
        const mesh = await fetchBinary('/api/mesh', 'mesh');
        if (mesh) applyMesh(mesh);
      } else if (n.frame != null && view.mesh && n.frame !== view.drawnFrame) {
        const frame = await fetchBinary('/api/frame', 'frame');
        if (!frame || !applyFrame(frame)) break;
      } else {
        break;
      }
    }
  } catch (e) {
    console.error(e);
    setTimeout(pump, 1000);
  } finally {
    pumping = false;
  }
  settle();
}

// data-settled: the solve has ended and the newest frame is on screen.
function settle() {
  const n = view.notice;
  const final = n && FINAL.includes(n.progress.status);
  const shown = n && (n.frame == null || String(n.frame) === body.dataset.frame);
  body.dataset.settled = String(Boolean(final && shown));
}

let events = null;
let polling = null;
function connect() {
  events = new EventSource('/events');
  events.addEventListener('state', (e) => onNotice(JSON.parse(e.data)));
  events.addEventListener('error', () => {
    const n = view.notice;
    if (n && FINAL.includes(n.progress.status)) {
      // Nothing more will come; do not keep reconnecting to a server that may be gone.
      events.close();
    } else if (events.readyState === EventSource.CLOSED) {
      // Refused (e.g. too many streams): fall back to polling.
      if (!polling) polling = setInterval(poll, 1000);
    } else {
      body.dataset.status = 'disconnected';
      $('status').textContent = 'connection lost, retrying';
    }
  });
}

async function poll() {
  try {
    const r = await fetch('/api/progress', { cache: 'no-store' });
    if (r.ok) onNotice(await r.json());
    if (view.notice && FINAL.includes(view.notice.progress.status)) clearInterval(polling);
  } catch (e) {
    body.dataset.status = 'disconnected';
  }
}

// ---------------------------------------------------------------- drawing

let lastTime = performance.now();
function loop(now) {
  requestAnimationFrame(loop);
  flyStep(Math.min((now - lastTime) / 1000, 0.1));
  lastTime = now;
  if (!view.needsRender || !view.surface) return;
  view.needsRender = false;
  fitClipPlanes();
  renderer.render(scene, camera);
  if (view.markFrame !== null) {
    body.dataset.frame = String(view.markFrame);
    view.markFrame = null;
    settle();
  }
}

resize();
requestAnimationFrame(loop);
connect();
