// wavrad's 3-D view of a finished bake (served at /view?job=ID).
//
// Loads the job's scene.glb (fetched with the dashboard's API token), gives every material its
// MOZ_lightmap (the atlas page as lightMap on TEXCOORD_1, with its intensity) and shows the bake
// alone: each material becomes a Lambert material and the scene has no lights, so a pixel is
// lightmap x intensity x base colour / pi + emission, the radiance wavrad solved for, times the
// exposure (linear tone mapping, then sRGB). `window.wavradView` lets tests read pixels and the
// surface points under them.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const status = document.getElementById('status');
const canvas = document.getElementById('view');
const view = { ready: false, error: null, exposure: 1, lightmappedMaterials: 0 };
window.wavradView = view;

function fail(message) {
  view.error = message;
  status.textContent = message;
  status.className = 'error';
}

function authHeaders() {
  const token = (localStorage.getItem('wavrad-token') || '').trim();
  return token ? { Authorization: 'Bearer ' + token } : {};
}

/// The MOZ_lightmap extension: {index: texture, texCoord: 1, intensity}.
class MozLightmap {
  constructor(parser) { this.parser = parser; this.name = 'MOZ_lightmap'; }
  extendMaterialParams(materialIndex, params) {
    const ext = this.parser.json.materials?.[materialIndex]?.extensions?.MOZ_lightmap;
    if (!ext) return Promise.resolve();
    return this.parser.getDependency('texture', ext.index).then((texture) => {
      texture.channel = ext.texCoord ?? 1;
      texture.colorSpace = THREE.SRGBColorSpace;
      texture.needsUpdate = true;
      params.lightMap = texture;
      params.lightMapIntensity = ext.intensity ?? 1;
    });
  }
}

/// The same surface lit by its lightmap only.
function bakedMaterial(m) {
  const baked = new THREE.MeshLambertMaterial({
    name: m.name, color: m.color, map: m.map, vertexColors: m.vertexColors,
    emissive: m.emissive, emissiveMap: m.emissiveMap, emissiveIntensity: m.emissiveIntensity,
    lightMap: m.lightMap, lightMapIntensity: m.lightMapIntensity,
    side: m.side, transparent: m.transparent, opacity: m.opacity, alphaTest: m.alphaTest,
  });
  if (m.lightMap) view.lightmappedMaterials += 1;
  return baked;
}

/// An exposure that puts the brighter faces (90th percentile of area-weighted mean radiance,
/// emitters left out) at 0.7 of white.
function defaultExposure(result) {
  const faces = (result && result.faces) || [];
  const lum = (c) => 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
  const rows = faces.map((f) => [lum(f.mean_radiance || [0, 0, 0]), f.area || 0]).filter((r) => r[0] > 0);
  if (rows.length === 0) return 1;
  rows.sort((a, b) => a[0] - b[0]);
  const total = rows.reduce((s, r) => s + r[1], 0);
  let acc = 0;
  for (const [l, a] of rows) {
    acc += a;
    if (acc >= 0.9 * total) return 0.7 / l;
  }
  return 0.7 / rows[rows.length - 1][0];
}

async function main() {
  const job = new URLSearchParams(location.search).get('job');
  if (!job || !/^[0-9a-f]+$/.test(job)) return fail('no job: open this page as /view?job=ID');
  document.getElementById('title').textContent = 'job ' + job;
  const [glb, result] = await Promise.all([
    fetch(`/v1/jobs/${job}/scene.glb`, { headers: authHeaders() }),
    fetch(`/v1/jobs/${job}/result`, { headers: authHeaders() }),
  ]);
  if (!glb.ok) return fail(`scene.glb: ${glb.status} ${(await glb.text()).slice(0, 200)}`);
  const resultJson = result.ok ? await result.json() : null;
  const loader = new GLTFLoader();
  loader.register((parser) => new MozLightmap(parser));
  const gltf = await loader.parseAsync(await glb.arrayBuffer(), '');
  const scene = gltf.scene;
  const lights = [];
  scene.traverse((o) => {
    if (o.isLight) lights.push(o);
    if (o.isMesh) o.material = Array.isArray(o.material) ? o.material.map(bakedMaterial) : bakedMaterial(o.material);
  });
  // The bake already holds the punctual lights' contribution.
  for (const l of lights) l.parent.remove(l);

  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  renderer.toneMapping = THREE.LinearToneMapping;
  renderer.setClearColor(0x202124);
  view.exposure = defaultExposure(resultJson);
  const slider = document.getElementById('exposure');
  const applyExposure = () => { renderer.toneMappingExposure = view.exposure * Math.pow(2, Number(slider.value)); };
  applyExposure();

  // Framed on the surfaces that do not emit (a sky panel far above a model would shrink it),
  // or on everything when all emit.
  scene.updateMatrixWorld(true);
  const box = new THREE.Box3();
  scene.traverse((o) => {
    if (o.isMesh && !(o.material.emissive && o.material.emissive.getHex() !== 0)) box.expandByObject(o);
  });
  if (box.isEmpty()) box.setFromObject(scene);
  const centre = box.getCenter(new THREE.Vector3());
  const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-3);
  // The glTF's first camera (its world pose, copied onto an unparented camera the orbit controls
  // can move), else a raised diagonal view of the whole scene.
  const camera = new THREE.PerspectiveCamera(45, 1, radius / 1000, radius * 100);
  const target = centre.clone();
  const own = gltf.cameras.find((c) => c.isPerspectiveCamera);
  if (own) {
    own.updateWorldMatrix(true, false);
    camera.fov = own.fov;
    camera.position.copy(own.getWorldPosition(new THREE.Vector3()));
    camera.quaternion.copy(own.getWorldQuaternion(new THREE.Quaternion()));
    const forward = own.getWorldDirection(new THREE.Vector3());
    const along = Math.max(centre.clone().sub(camera.position).dot(forward), radius * 0.1);
    target.copy(camera.position).addScaledVector(forward, along);
  } else {
    camera.position.copy(centre).add(new THREE.Vector3(1, 0.8, 1.4).normalize().multiplyScalar(radius * 2.6));
  }
  camera.lookAt(target);
  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(target);
  controls.update();

  const render = () => {
    const w = canvas.clientWidth, h = canvas.clientHeight;
    if (canvas.width !== w || canvas.height !== h) {
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
    }
    renderer.render(scene, camera);
  };
  controls.addEventListener('change', render);
  slider.addEventListener('input', () => { applyExposure(); render(); });
  window.addEventListener('resize', render);
  render();

  const raycaster = new THREE.Raycaster();
  /// Pixels at canvas points [[x, y], ...] (CSS pixels from the top left) with the surface point
  /// and its front normal under each (null over the background), read from one fresh render.
  view.sample = (points) => {
    render();
    const gl = renderer.getContext();
    const px = new Uint8Array(4);
    return points.map(([x, y]) => {
      gl.readPixels(Math.floor(x), canvas.height - 1 - Math.floor(y), 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
      const ndc = new THREE.Vector2(((Math.floor(x) + 0.5) / canvas.width) * 2 - 1, 1 - ((Math.floor(y) + 0.5) / canvas.height) * 2);
      raycaster.setFromCamera(ndc, camera);
      const hit = raycaster.intersectObject(scene, true)[0];
      let surface = null;
      if (hit && hit.face) {
        const normal = hit.face.normal.clone().transformDirection(hit.object.matrixWorld);
        surface = { point: hit.point.toArray(), normal: normal.toArray(), material: hit.object.material.name || '' };
      }
      return { x, y, rgb: [px[0], px[1], px[2]], surface };
    });
  };
  view.exposureNow = () => renderer.toneMappingExposure;
  view.ready = true;
  status.textContent = `${view.lightmappedMaterials} lightmapped material(s); drag to orbit, wheel to zoom`;
}

main().catch((e) => fail(String(e && e.message ? e.message : e)));
