// The envkit IBL viewer: a row of spheres of increasing roughness lit by envprefilter's GGX chain and DFG LUT with
// the split-sum, in front of the map itself (level 0 of the chain).
//
// URL parameters (all optional):
//   map=URL        GGX chain, KTX2 cube in rgba16f or rgba32f (default data/sky_ggx.ktx2)
//   lut=URL        DFG LUT, OpenEXR, scale-bias layout (default data/dfg.exr)
//   roughness=LIST perceptual roughness of each sphere (default 0,0.25,0.5,0.75,1)
//   f0=R,G,B       specular colour F0 of the spheres, linear (default 0.95,0.64,0.54: copper)
//   exposure=X     multiplies radiance before the display transform (default 1)
//   background=LOD mip level shown behind the spheres (default 0: the map itself)
//   size=WxH       canvas size in pixels at device pixel ratio 1 (default: the window, at the device's ratio)
//   fov=DEG, camera=X,Y,Z   perspective camera looking at the origin (default: 30 and a distance that fits the row)
//   static=1       no orbit controls (for captures)
// Spheres have radius 1, centres (k - (n - 1) / 2) * 2.5 on the x axis.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { loadDfgLut, loadGgxCube, lodForRoughness } from './ibl.js';
import { backgroundFragment, backgroundVertex, sphereFragment, sphereVertex } from './shaders.js';

export const SPHERE_SPACING = 2.5;

function numbers(text, count, name) {
  const v = text.split(',').map(Number);
  if ((count && v.length !== count) || v.some((x) => !Number.isFinite(x))) throw new Error(`bad ${name}: '${text}'`);
  return v;
}

function parameters(search) {
  const q = new URLSearchParams(search);
  const p = {
    map: q.get('map') ?? 'data/sky_ggx.ktx2',
    lut: q.get('lut') ?? 'data/dfg.exr',
    roughness: numbers(q.get('roughness') ?? '0,0.25,0.5,0.75,1', 0, 'roughness'),
    f0: numbers(q.get('f0') ?? '0.95,0.64,0.54', 3, 'f0'),
    exposure: Number(q.get('exposure') ?? '1'),
    background: Number(q.get('background') ?? '0'),
    fov: Number(q.get('fov') ?? '30'),
    camera: q.get('camera') ? numbers(q.get('camera'), 3, 'camera') : null,
    size: q.get('size') ? q.get('size').split('x').map(Number) : null,
    static: q.get('static') === '1',
  };
  return p;
}

function status(state, message = '') {
  window.envkitViewer.state = state;
  window.envkitViewer.message = message;
  const el = document.getElementById('status');
  if (el) el.textContent = state === 'ready' ? '' : message || state;
}

async function main() {
  const p = parameters(window.location.search);
  const canvas = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false });
  renderer.setPixelRatio(p.size ? 1 : window.devicePixelRatio);
  const width = p.size ? p.size[0] : window.innerWidth;
  const height = p.size ? p.size[1] : window.innerHeight;
  renderer.setSize(width, height, !p.size);

  const [chain, dfg] = await Promise.all([loadGgxCube(p.map), loadDfgLut(p.lut)]);

  const scene = new THREE.Scene();
  const n = p.roughness.length;
  const aspect = width / height;
  const halfFov = THREE.MathUtils.degToRad(p.fov) / 2;
  const camera = new THREE.PerspectiveCamera(p.fov, aspect, 0.1, 1000);
  const halfRow = ((n - 1) / 2) * SPHERE_SPACING + SPHERE_SPACING / 2;
  const distance = Math.max(halfRow / (aspect * Math.tan(halfFov)), SPHERE_SPACING / 2 / Math.tan(halfFov));
  camera.position.fromArray(p.camera ?? [0, 0, distance + 1]);
  camera.lookAt(0, 0, 0);

  const background = new THREE.Mesh(
    new THREE.BoxGeometry(100, 100, 100),
    new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3,
      vertexShader: backgroundVertex,
      fragmentShader: backgroundFragment,
      uniforms: { ggx: { value: chain.texture }, lod: { value: p.background }, exposure: { value: p.exposure } },
      side: THREE.BackSide,
      depthTest: false,
      depthWrite: false,
    }),
  );
  background.renderOrder = -1;
  background.frustumCulled = false;
  scene.add(background);

  const geometry = new THREE.SphereGeometry(1, 128, 64);
  p.roughness.forEach((r, k) => {
    const centre = new THREE.Vector3((k - (n - 1) / 2) * SPHERE_SPACING, 0, 0);
    const material = new THREE.ShaderMaterial({
      glslVersion: THREE.GLSL3,
      vertexShader: sphereVertex,
      fragmentShader: sphereFragment,
      uniforms: {
        ggx: { value: chain.texture },
        dfg: { value: dfg },
        centre: { value: centre },
        roughness: { value: r },
        lod: { value: lodForRoughness(chain.roughness, r) },
        f0: { value: new THREE.Vector3(...p.f0) },
        exposure: { value: p.exposure },
      },
    });
    const sphere = new THREE.Mesh(geometry, material);
    sphere.position.copy(centre);
    scene.add(sphere);
  });

  const render = () => renderer.render(scene, camera);
  if (!p.static) {
    const controls = new OrbitControls(camera, canvas);
    controls.addEventListener('change', render);
    window.addEventListener('resize', () => {
      if (p.size) return;
      camera.aspect = window.innerWidth / window.innerHeight;
      camera.updateProjectionMatrix();
      renderer.setSize(window.innerWidth, window.innerHeight);
      render();
    });
  }
  // Renders and reads the canvas back in the same task (no preserveDrawingBuffer needed): RGBA8 rows top to bottom,
  // base64, and a PNG data URL. Used by tests/js/viewer_capture.mjs.
  window.envkitViewer.capture = () => {
    render();
    const gl = renderer.getContext();
    const w = gl.drawingBufferWidth;
    const h = gl.drawingBufferHeight;
    const bottomUp = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, bottomUp);
    const rows = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; y++) rows.set(bottomUp.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    let binary = '';
    for (let i = 0; i < rows.length; i += 0x8000) binary += String.fromCharCode(...rows.subarray(i, i + 0x8000));
    return { width: w, height: h, rgba: btoa(binary), png: canvas.toDataURL('image/png') };
  };
  render();
  window.envkitViewer.levels = chain.roughness.length;
  window.envkitViewer.mapping = chain.mapping;
  status('ready');
}

window.envkitViewer = { state: 'loading' };
main().catch((e) => {
  console.error(e);
  status('error', String(e && e.message ? e.message : e));
});
