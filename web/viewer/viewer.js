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
//
// Lightmap bakes (`--bake-target lightmap`, the scene's extras holding
// `radiosity.lightmap`): lit ones need nothing (each material is unlit, its
// base colour the lightmap on texCoord 1); irradiance ones keep the input's
// materials, and the lightmap texture the extras name becomes each
// material's lightMap on uv channel 1, sRGB-decoded, at the intensity
// pi x (pi x exposure / color_scale) that the ambient light has above (three.js
// adds lightMap x intensity to the irradiance).
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

/** Shows the loaded document. */
async function show(gltf) {
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
  const target = info.lightmap ? 'lightmap' : 'vertices';
  if (info.bake_mode === 'irradiance') {
    const exposure = info.picture_exposure || 1;
    const scale = info.color_scale || Math.PI * exposure;
    const intensity = Math.PI * (Math.PI * exposure / scale);
    if (target === 'lightmap') {
      const lightMap = await gltf.parser.getDependency('texture', info.lightmap.texture);
      lightMap.channel = info.lightmap.texCoord ?? 1;
      lightMap.colorSpace = THREE.SRGBColorSpace;
      gltf.scene.traverse((object) => {
        if (!object.isMesh) return;
        for (const material of [object.material].flat()) {
          material.lightMap = lightMap;
          material.lightMapIntensity = intensity;
          material.needsUpdate = true;
        }
      });
    } else {
      scene.add(new THREE.AmbientLight(0xffffff, intensity));
    }
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
  status.textContent = `${modelUrl.split('/').pop()}: ${info.bake_mode ? `${info.bake_mode} ${target} bake` : 'glTF'} — drag to orbit, wheel to zoom`;
  window.viewer = { ready: true, mode: info.bake_mode || null, target };
}

new GLTFLoader().load(
  modelUrl,
  (gltf) => show(gltf).catch((error) => fail(`cannot show ${modelUrl}: ${error.message || error}`)),
  undefined,
  (error) => fail(`cannot load ${modelUrl}: ${error.message || error}`),
);

window.addEventListener('resize', () => {
  renderer.setSize(window.innerWidth, window.innerHeight);
  if (camera) {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
  }
  draw();
});
