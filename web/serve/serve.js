// The live view of `radiosity serve`: draws the element mesh with the
// vertex radiosities the server streams (message layouts in
// src/serve/mod.rs), tone-mapped like the command's pictures.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const $ = (id) => document.getElementById(id);

// Size of the picture the exposure key is measured on (width; the height
// follows the window's aspect).
const KEY_WIDTH = 160;

const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setClearColor(0x000000, 1);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 100);
const controls = new OrbitControls(camera, canvas);
const keyTarget = new THREE.WebGLRenderTarget(KEY_WIDTH, KEY_WIDTH, { type: THREE.FloatType });
let keyPixels = new Float32Array(0);

// Displayed radiosity = B + rho * ambient (ambient switched on or off),
// interpolated in linear light, then scaled and sRGB-encoded per pixel as
// src/render.rs does; with `encode` off the linear value is written (for
// the exposure key).
const material = new THREE.ShaderMaterial({
  uniforms: {
    ambient: { value: new THREE.Vector3() },
    ambientOn: { value: 1 },
    scale: { value: 1 },
    encode: { value: 1 },
  },
  vertexShader: `
    attribute vec3 radiosity;
    attribute vec3 rho;
    uniform vec3 ambient;
    uniform float ambientOn;
    uniform float scale;
    varying vec3 vColour;
    void main() {
      vColour = (radiosity + ambientOn * rho * ambient) * scale;
      gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
    }`,
  fragmentShader: `
    uniform float encode;
    varying vec3 vColour;
    vec3 srgb(vec3 c) {
      c = clamp(c, 0.0, 1.0);
      return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
    }
    void main() {
      gl_FragColor = vec4(encode > 0.5 ? srgb(vColour) : vColour, 1.0);
    }`,
});

let info = null; // the scene message
let mesh = null;
let radiosity = null; // Float32Array, 3 per vertex, W/m^2
let keyScale = null; // 0.8 / p90, null until measured
let updates = 0; // colour frames drawn
let undrawn = null; // seq of a colour frame not drawn yet
let picked = null;
let status = null;
let frameShown = false; // the final picture has been fetched

// The final picture: the server draws the ended solve from the scene's
// view with the final pass, at the size the page draws at.
function showFrame(on) {
  $('final').checked = on;
  $('frame').hidden = !on;
  if (on && info) {
    setView();
    measureKey();
    draw();
  }
}

function sendViewSize() {
  const ratio = window.devicePixelRatio || 1;
  const w = Math.round(Math.max(1, canvas.clientWidth) * ratio);
  const h = Math.round(Math.max(1, canvas.clientHeight) * ratio);
  fetch(`/api/view/${w}/${h}`, { method: 'POST' }).catch(() => {});
}
const marker = new THREE.Mesh(
  new THREE.SphereGeometry(1, 12, 8),
  new THREE.MeshBasicMaterial({ color: 0xff30ff, depthTest: false }),
);
marker.visible = false;
marker.renderOrder = 1;
scene.add(marker);

// 2^(e - 136) for every exponent byte (Ward's RGBE, as Radiance decodes).
const RGBE_SCALE = new Float32Array(256).map((_, e) => (e === 0 ? 0 : 2 ** (e - 136)));

function setView() {
  const c = info.camera;
  camera.fov = c.fov;
  camera.up.fromArray(c.up).normalize();
  camera.position.fromArray(c.eye);
  controls.target.fromArray(c.target);
  camera.lookAt(controls.target);
  controls.update();
}

function resize() {
  const w = Math.max(1, canvas.clientWidth);
  const h = Math.max(1, canvas.clientHeight);
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  keyTarget.setSize(KEY_WIDTH, Math.max(1, Math.round(KEY_WIDTH * h / w)));
  measureKey();
  draw();
}

// The exposure rule of src/render.rs (Exposure::Auto): the 90th percentile
// of the luminance of covered, lit pixels maps to 0.8. Measured on the
// picture with the ambient term, whether or not it is shown (see the
// module documentation of src/serve/mod.rs).
function measureKey() {
  if (!mesh) return;
  const u = material.uniforms;
  const shown = [u.ambientOn.value, u.scale.value, u.encode.value, marker.visible];
  u.ambientOn.value = 1;
  u.scale.value = 1;
  u.encode.value = 0;
  marker.visible = false;
  renderer.setRenderTarget(keyTarget);
  renderer.setClearColor(0x000000, 0);
  renderer.clear();
  renderer.render(scene, camera);
  const { width, height } = keyTarget;
  if (keyPixels.length !== 4 * width * height) keyPixels = new Float32Array(4 * width * height);
  renderer.readRenderTargetPixels(keyTarget, 0, 0, width, height, keyPixels);
  renderer.setRenderTarget(null);
  renderer.setClearColor(0x000000, 1);
  [u.ambientOn.value, u.scale.value, u.encode.value, marker.visible] = shown;
  const lums = [];
  for (let i = 0; i < keyPixels.length; i += 4) {
    if (keyPixels[i + 3] < 0.5) continue;
    const l = 0.2126 * keyPixels[i] + 0.7152 * keyPixels[i + 1] + 0.0722 * keyPixels[i + 2];
    if (l > 0) lums.push(l);
  }
  if (lums.length === 0) {
    keyScale = null;
    return;
  }
  lums.sort((a, b) => a - b);
  keyScale = 0.8 / lums[Math.floor((lums.length - 1) * 0.9)];
}

let drawPending = false;
let draws = 0;
function draw() {
  if (drawPending) return;
  drawPending = true;
  requestAnimationFrame(() => {
    drawPending = false;
    const ev = Number($('exposure').value);
    material.uniforms.scale.value = (keyScale ?? 1) * 2 ** ev;
    material.uniforms.ambientOn.value = $('ambient').checked ? 1 : 0;
    renderer.render(scene, camera);
    // Counted once drawn with the controls as they are now, so that a
    // test can wait for a change to reach the canvas.
    draws += 1;
    document.body.dataset.draws = String(draws);
    if (undrawn !== null) {
      // Counted once drawn, so that a test reading the count sees the
      // frame on the canvas.
      document.body.dataset.seq = String(undrawn);
      undrawn = null;
      updates += 1;
      document.body.dataset.updates = String(updates);
    }
  });
}

function onScene(message) {
  info = message;
  $('scene-name').textContent = `${info.name}: ${info.vertices.toLocaleString()} vertices`;
  $('ambient').checked = info.ambient;
  $('exposure').value = info.exposure;
  showExposure();
  const [lo, hi] = info.bounds.map((b) => new THREE.Vector3().fromArray(b));
  const size = lo.distanceTo(hi);
  camera.near = 1e-3 * size;
  camera.far = 100 * size;
  marker.scale.setScalar(0.006 * size);
  setView();
  resize();
}

function onMesh(buffer) {
  const header = new Uint32Array(buffer, 4, 2);
  const [v, t] = header;
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(buffer, 12, 3 * v), 3));
  geometry.setAttribute('rho', new THREE.BufferAttribute(new Float32Array(buffer, 12 + 12 * v, 3 * v), 3));
  geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(buffer, 12 + 24 * v, 3 * t), 1));
  radiosity = new Float32Array(3 * v);
  geometry.setAttribute('radiosity', new THREE.BufferAttribute(radiosity, 3));
  geometry.computeBoundingSphere();
  mesh = new THREE.Mesh(geometry, material);
  scene.add(mesh);
}

function onColours(buffer) {
  const [seq, n, flags] = new Uint32Array(buffer, 4, 3);
  material.uniforms.ambient.value.fromArray(new Float32Array(buffer, 16, 3));
  const full = (flags & 1) !== 0;
  const indices = full ? null : new Uint32Array(buffer, 28, n);
  const rgbe = new Uint8Array(buffer, full ? 28 : 28 + 4 * n, 4 * n);
  for (let k = 0; k < n; k++) {
    const i = full ? k : indices[k];
    const f = RGBE_SCALE[rgbe[4 * k + 3]];
    radiosity[3 * i] = f && (rgbe[4 * k] + 0.5) * f;
    radiosity[3 * i + 1] = f && (rgbe[4 * k + 1] + 0.5) * f;
    radiosity[3 * i + 2] = f && (rgbe[4 * k + 2] + 0.5) * f;
  }
  mesh.geometry.attributes.radiosity.needsUpdate = true;
  measureKey();
  undrawn = seq;
  draw();
  if (picked !== null) pickVertex(picked);
}

function formatCount(x) {
  if (x >= 1e9) return `${(x / 1e9).toPrecision(3)} G`;
  if (x >= 1e6) return `${(x / 1e6).toPrecision(3)} M`;
  if (x >= 1e4) return `${(x / 1e3).toPrecision(3)} k`;
  return String(Math.round(x));
}

function formatTime(s) {
  if (s < 60) return `${s.toFixed(1)} s`;
  const m = Math.floor(s / 60);
  return `${m}:${String(Math.floor(s - 60 * m)).padStart(2, '0')} min`;
}

function onStatus(s) {
  status = s;
  document.body.dataset.status = String(s.seq);
  let phase = s.phase;
  if (s.phase === 'finished' && s.stop_reason) phase = `finished (${s.stop_reason})`;
  else if (s.stop_requested && s.phase !== 'finished') phase = 'stopping';
  else if (s.pause_requested) phase = 'pausing';
  else if (s.phase === 'writing' && s.final_pass) {
    const f = s.final_pass;
    phase = f.total > 0
      ? `final pass: ${f.what} ${Math.floor((100 * f.done) / f.total)}%`
      : `final pass: ${f.what}`;
  }
  $('phase').textContent = phase;
  $('shots').textContent = s.shots.toLocaleString();
  $('subsources').textContent = s.subsources.toLocaleString();
  $('unshot').textContent = `${(100 * s.unshot_fraction).toPrecision(3)} %`;
  $('unshot').title = String(s.unshot_fraction);
  $('rays').textContent = formatCount(s.rays_per_second);
  $('elapsed').textContent = formatTime(s.elapsed_seconds);
  $('device').textContent = s.device === 'cpu'
    ? 'CPU'
    : `${s.device}, ${s.device_shots.toLocaleString()} shots`;
  const running = s.phase === 'loading' || s.phase === 'solving' || s.phase === 'paused';
  const holding = s.phase === 'paused' || s.pause_requested;
  $('pause').textContent = holding ? 'Resume' : 'Pause';
  $('pause').disabled = !running || s.stop_requested;
  $('stop').disabled = !running || s.stop_requested;
  if (s.frame && !frameShown) {
    frameShown = true;
    $('frame').src = `/api/frame.png?seq=${s.seq}`;
    $('final-row').hidden = false;
  }
  if (s.written.length > 0) {
    $('written').hidden = false;
    $('written').textContent = `wrote ${s.written.join(', ')}`;
  }
}

// The answer's status is not shown: it can arrive after a newer one from
// the live feed, which reports every change anyway.
async function control(action) {
  try {
    await fetch(`/api/${action}`, { method: 'POST' });
  } catch {
    // The server has gone; the socket's close handler says so.
  }
}

function showExposure() {
  const ev = Number($('exposure').value);
  $('exposure-value').textContent = `${ev >= 0 ? '+' : ''}${ev.toFixed(1)} EV`;
}

const rgb = (a, digits = 4) => a.map((x) => x.toPrecision(digits)).join(', ');

// Vertex queries asked and the one shown: an answer that arrives after a
// later query's is dropped, so the panel never goes back to older values.
let picksAsked = 0;
async function pickVertex(index) {
  picksAsked += 1;
  const asked = picksAsked;
  document.body.dataset.picksAsked = String(asked);
  let v;
  try {
    const response = await fetch(`/api/vertex/${index}`);
    if (!response.ok) return;
    v = await response.json();
  } catch {
    return; // the server has gone
  }
  if (picked !== index || asked !== picksAsked) return;
  $('picked').hidden = false;
  $('picked-index').textContent = String(v.index);
  $('picked-surface').textContent = String(v.surface);
  $('picked-radiosity').textContent = rgb(v.radiosity);
  $('picked-display').textContent = rgb($('ambient').checked ? v.display : v.radiosity);
  $('picked-rho').textContent = rgb(v.reflectance, 3);
  marker.position.fromArray(v.position);
  marker.visible = true;
  document.body.dataset.pickShown = String(asked);
  draw();
}

// The nearest vertex of the front face under the pointer.
function pick(event) {
  if (!mesh) return;
  const rect = canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(
    ((event.clientX - rect.left) / rect.width) * 2 - 1,
    -((event.clientY - rect.top) / rect.height) * 2 + 1,
  );
  const raycaster = new THREE.Raycaster();
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(mesh)[0];
  if (!hit) {
    picked = null;
    $('picked').hidden = true;
    marker.visible = false;
    draw();
    return;
  }
  const position = mesh.geometry.attributes.position;
  const corner = [hit.face.a, hit.face.b, hit.face.c];
  const distance = (i) => hit.point.distanceToSquared(new THREE.Vector3().fromBufferAttribute(position, i));
  picked = corner.reduce((best, i) => (distance(i) < distance(best) ? i : best));
  pickVertex(picked);
}

let pointerDown = null;
canvas.addEventListener('pointerdown', (e) => { pointerDown = [e.clientX, e.clientY]; });
canvas.addEventListener('pointerup', (e) => {
  if (pointerDown && Math.hypot(e.clientX - pointerDown[0], e.clientY - pointerDown[1]) < 5) pick(e);
  pointerDown = null;
});
controls.addEventListener('change', draw);
controls.addEventListener('start', () => { if ($('final').checked) showFrame(false); });
$('final').addEventListener('change', () => showFrame($('final').checked));
controls.addEventListener('end', () => { measureKey(); draw(); });
new ResizeObserver(() => { sendViewSize(); if (info) resize(); }).observe(canvas);
$('pause').addEventListener('click', () => {
  control(status && (status.phase === 'paused' || status.pause_requested) ? 'resume' : 'pause');
});
$('stop').addEventListener('click', () => control('stop'));
$('ambient').addEventListener('change', () => {
  draw();
  if (picked !== null) pickVertex(picked);
});
$('exposure').addEventListener('input', () => { showExposure(); draw(); });
$('reset').addEventListener('click', () => {
  if (!info) return;
  setView();
  measureKey();
  draw();
});

const socket = new WebSocket(`ws://${location.host}/api/live`);
socket.binaryType = 'arraybuffer';
socket.addEventListener('message', (event) => {
  if (typeof event.data === 'string') {
    const message = JSON.parse(event.data);
    if (message.type === 'scene') onScene(message);
    else if (message.type === 'status') onStatus(message);
    return;
  }
  const magic = new TextDecoder().decode(new Uint8Array(event.data, 0, 4));
  if (magic === 'RMSH') onMesh(event.data);
  else if (magic === 'RCOL' && mesh) onColours(event.data);
});
socket.addEventListener('close', () => {
  $('phase').textContent = 'disconnected';
  $('pause').disabled = true;
  $('stop').disabled = true;
});
