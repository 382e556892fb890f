// The bake viewer: shows a glTF baked by `radiosity render --bake` from the
// scene's camera (the camera the bake carries), with orbit controls.
//
// Query parameters: model (URL of the .glb/.gltf, default model.glb),
// ui=0 hides the status line. When the first frame is drawn the page sets
// window.viewer = { ready: true, mode } (or { error }) for tests.
//
// Lit bakes (KHR_materials_unlit) show COLOR_0 as it is: the colours already
// hold the lighting. Irradiance bakes keep the input's materials; an ambient
// light of intensity pi x (pi x exposure / color_scale) turns three.js's
// Lambert term (irradiance x base / pi) into base x COLOR_0 at the
// picture's exposure.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const params = new URLSearchParams(location.search);
const modelUrl = params.get('model') || 'model.glb';
const status = document.getElementById('status');
if (params.get('ui') === '0') status.style.display = 'none';

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.outputColorSpace = THREE.SRGBColorSpace;
renderer.toneMapping = THREE.NoToneMapping;
document.body.appendChild(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x000000);
let camera = null;
let controls = null;

function draw() {
  if (camera) renderer.render(scene, camera);
}

function fail(message) {
  status.textContent = message;
  status.className = 'error';
  window.viewer = { ready: false, error: message };
}

new GLTFLoader().load(modelUrl, (gltf) => {
  scene.add(gltf.scene);
  gltf.scene.updateMatrixWorld(true);
  const info = gltf.scene.userData.radiosity || {};
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const centre = box.getCenter(new THREE.Vector3());
  if (gltf.cameras.length > 0) {
    camera = gltf.cameras[0];
  } else {
    const radius = box.getSize(new THREE.Vector3()).length() / 2 || 1;
    camera = new THREE.PerspectiveCamera(45, 1, radius / 1000, radius * 100);
    camera.position.copy(centre).add(new THREE.Vector3(0.35, 0.3, 1).normalize().multiplyScalar(radius * 2.6));
    camera.lookAt(centre);
    scene.add(camera);
  }
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  if (info.bake_mode === 'irradiance') {
    const exposure = info.picture_exposure || 1;
    const scale = info.color_scale || Math.PI * exposure;
    scene.add(new THREE.AmbientLight(0xffffff, Math.PI * (Math.PI * exposure / scale)));
  }
  // Orbit about the point of the scene straight ahead of the camera.
  const forward = new THREE.Vector3();
  camera.getWorldDirection(forward);
  const eye = camera.getWorldPosition(new THREE.Vector3());
  const depth = Math.max(centre.clone().sub(eye).dot(forward), 1e-3);
  controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(eye).addScaledVector(forward, depth);
  controls.update();
  controls.addEventListener('change', draw);
  draw();
  status.textContent = `${modelUrl.split('/').pop()}: ${info.bake_mode || 'glTF'} — drag to orbit, wheel to zoom`;
  window.viewer = { ready: true, mode: info.bake_mode || null };
}, undefined, (error) => fail(`cannot load ${modelUrl}: ${error.message || error}`));

window.addEventListener('resize', () => {
  renderer.setSize(window.innerWidth, window.innerHeight);
  if (camera) {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
  }
  draw();
});
