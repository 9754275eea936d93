// The envkit IBL viewer: a row of spheres of increasing roughness lit by envprefilter's GGX chain and DFG LUT with
// the split-sum, and (with envprefilter's SH JSON) a Lambertian sphere at the end of the row lit by the SH
// irradiance, in front of the map itself (level 0 of the chain, filtered linearly). The canvas fills the window.
// Files can be dropped onto the page or picked in the panel: a .ktx2 chain, a .json of SH, a DFG .exr, or a
// lat-long .hdr/.exr, which is shown as the background only (the browser does not prefilter; web/README.md).
//
// URL parameters (all optional):
//   map=URL        GGX chain, KTX2 cube in rgba16f or rgba32f (default data/sky_ggx.ktx2)
//   lut=URL        DFG LUT, OpenEXR, scale-bias layout (default data/dfg.exr)
//   sh=URL         envprefilter --sh JSON: adds the Lambertian sphere and the dielectrics' diffuse term (default none)
//   roughness=LIST perceptual roughness of each sphere (default 0,0.25,0.5,0.75,1)
//   material=NAME  metal (specular colour f0, no diffuse; default) or dielectric (f0 0.04 and the diffuse albedo)
//   f0=R,G,B       specular colour F0 of metal spheres, linear (default 0.95,0.64,0.54: copper)
//   albedo=R,G,B   diffuse albedo of the Lambertian sphere and of dielectrics, linear (default 0.8,0.8,0.8)
//   exposure=X     multiplies radiance before the display transform (default 1)
//   background=LOD mip level shown behind the spheres (default 0: the map itself)
//   size=WxH       canvas size in pixels at device pixel ratio 1 (default: the window, at the device's ratio)
//   fov=DEG, camera=X,Y,Z   perspective camera looking at the origin (default: 30 and a distance that fits the row)
//   static=1       no orbit controls and no panel (for captures)
// Spheres have radius 1, centres (k - (n - 1) / 2) * 2.5 on the x axis, the Lambertian one last.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { SH_MAX, loadDfgLut, loadGgxCube, loadLatLong, loadShIrradiance, lodForRoughness } from './ibl.js';
import { backgroundFragment, backgroundVertex, sphereFragment, sphereVertex } from './shaders.js';

export const SPHERE_SPACING = 2.5;
const DIELECTRIC_F0 = 0.04;

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
    sh: q.get('sh'),
    roughness: numbers(q.get('roughness') ?? '0,0.25,0.5,0.75,1', 0, 'roughness'),
    material: q.get('material') ?? 'metal',
    f0: numbers(q.get('f0') ?? '0.95,0.64,0.54', 3, 'f0'),
    albedo: numbers(q.get('albedo') ?? '0.8,0.8,0.8', 3, 'albedo'),
    exposure: Number(q.get('exposure') ?? '1'),
    background: Number(q.get('background') ?? '0'),
    fov: Number(q.get('fov') ?? '30'),
    camera: q.get('camera') ? numbers(q.get('camera'), 3, 'camera') : null,
    size: q.get('size') ? q.get('size').split('x').map(Number) : null,
    static: q.get('static') === '1',
  };
  if (!['metal', 'dielectric'].includes(p.material)) {
    throw new Error(`bad material: '${p.material}' (metal or dielectric)`);
  }
  return p;
}

function status(state, message = '') {
  window.envkitViewer.state = state;
  window.envkitViewer.message = message;
  const el = document.getElementById('status');
  if (el) el.textContent = state === 'ready' ? '' : message || state;
}

function note(text) {
  const el = document.getElementById('note');
  if (el) el.textContent = text;
}

// Linear RGB of an <input type=color> (sRGB hex) and back.
const linearOf = (hex) => new THREE.Color().setStyle(hex, THREE.SRGBColorSpace);
const hexOf = (rgb) =>
  `#${new THREE.Color().setRGB(...rgb, THREE.LinearSRGBColorSpace).getHexString(THREE.SRGBColorSpace)}`;

class Viewer {
  constructor(p, canvas) {
    this.p = p;
    this.canvas = canvas;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false });
    this.floatLinear = this.renderer.extensions.has('OES_texture_float_linear');
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(p.fov, 1, 0.1, 1000);
    this.geometry = new THREE.SphereGeometry(1, 128, 64);
    this.spheres = [];
    this.chain = null;
    this.moved = false; // the user has orbited: resizes keep the camera
    // Uniform objects shared by every material, so that a control changes them all at once.
    this.shared = {
      ggx: { value: null },
      dfg: { value: null },
      latlong: { value: null },
      latlongMode: { value: 0 },
      exposure: { value: p.exposure },
      lod: { value: p.background },
      sh: { value: Array.from({ length: SH_MAX }, () => new THREE.Vector3()) },
    };
    this.hasSh = false;
    this.f0 = new THREE.Vector3(...p.f0);
    this.albedo = new THREE.Vector3(...p.albedo);
    this.background = this.makeBackground();
    this.scene.add(this.background);
  }

  makeBackground() {
    const s = this.shared;
    const mesh = new THREE.Mesh(
      new THREE.BoxGeometry(100, 100, 100),
      new THREE.ShaderMaterial({
        glslVersion: THREE.GLSL3,
        vertexShader: backgroundVertex,
        fragmentShader: backgroundFragment,
        uniforms: { ggx: s.ggx, latlong: s.latlong, latlongMode: s.latlongMode, lod: s.lod, exposure: s.exposure },
        side: THREE.BackSide,
        depthTest: false,
        depthWrite: false,
      }),
    );
    mesh.renderOrder = -1;
    mesh.frustumCulled = false;
    return mesh;
  }

  // The canvas's drawing buffer follows its CSS box (which fills the window), unless size= fixes it.
  resize() {
    const r = this.renderer;
    if (this.p.size) {
      r.setPixelRatio(1);
      r.setSize(this.p.size[0], this.p.size[1], true);
    } else {
      r.setPixelRatio(window.devicePixelRatio);
      r.setSize(Math.max(1, this.canvas.clientWidth), Math.max(1, this.canvas.clientHeight), false);
    }
    const size = r.getSize(new THREE.Vector2());
    this.camera.aspect = size.x / size.y;
    this.camera.updateProjectionMatrix();
    if (!this.moved) this.frame();
  }

  // Places the camera on +z at a distance where the whole row fits (unless camera= fixes it).
  frame() {
    const n = this.spheres.length || 1;
    const halfFov = THREE.MathUtils.degToRad(this.camera.fov) / 2;
    const halfRow = ((n - 1) / 2) * SPHERE_SPACING + SPHERE_SPACING / 2;
    const distance = Math.max(
      halfRow / (this.camera.aspect * Math.tan(halfFov)),
      SPHERE_SPACING / 2 / Math.tan(halfFov),
    );
    this.camera.position.fromArray(this.p.camera ?? [0, 0, distance + 1]);
    this.camera.lookAt(0, 0, 0);
  }

  // The row: one sphere per roughness (metal or dielectric), then the Lambertian sphere when SH is loaded.
  buildRow() {
    for (const s of this.spheres) {
      this.scene.remove(s);
      s.material.dispose();
    }
    this.spheres = [];
    const kinds = this.p.roughness.map((r) => ({ roughness: r, lambertian: false }));
    if (this.hasSh) kinds.push({ roughness: 1, lambertian: true });
    const n = kinds.length;
    kinds.forEach((kind, k) => {
      const centre = new THREE.Vector3((k - (n - 1) / 2) * SPHERE_SPACING, 0, 0);
      const material = new THREE.ShaderMaterial({
        glslVersion: THREE.GLSL3,
        vertexShader: sphereVertex,
        fragmentShader: sphereFragment,
        uniforms: {
          ...this.shared,
          lod: { value: 0 },
          centre: { value: centre },
          roughness: { value: kind.roughness },
          f0: { value: new THREE.Vector3() },
          specular: { value: 1 },
          albedo: { value: new THREE.Vector3() },
        },
      });
      const sphere = new THREE.Mesh(this.geometry, material);
      sphere.position.copy(centre);
      sphere.userData = kind;
      sphere.visible = !this.shared.latlongMode.value;
      this.scene.add(sphere);
      this.spheres.push(sphere);
    });
    this.updateMaterials();
    this.frame();
  }

  updateMaterials() {
    const dielectric = this.p.material === 'dielectric';
    for (const s of this.spheres) {
      const u = s.material.uniforms;
      const { lambertian, roughness } = s.userData;
      u.specular.value = lambertian ? 0 : 1;
      u.f0.value.copy(dielectric ? new THREE.Vector3().setScalar(DIELECTRIC_F0) : this.f0);
      u.albedo.value.copy(lambertian || dielectric ? this.albedo : new THREE.Vector3());
      u.lod.value = this.chain ? lodForRoughness(this.chain.roughness, roughness) : 0;
    }
  }

  setChain(chain) {
    this.chain = chain;
    this.shared.ggx.value = chain.texture;
    this.shared.latlongMode.value = 0;
    this.shared.lod.value = Math.min(this.shared.lod.value, chain.roughness.length - 1);
    for (const s of this.spheres) s.visible = true;
    this.updateMaterials();
  }

  setSh(coefficients) {
    coefficients.forEach((c, i) => this.shared.sh.value[i].copy(c));
    if (!this.hasSh) {
      this.hasSh = true;
      this.buildRow();
    }
  }

  setLatLong(texture) {
    this.shared.latlong.value = texture;
    this.shared.latlongMode.value = 1;
    for (const s of this.spheres) s.visible = false;
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }

  notes() {
    const lines = [];
    if (this.shared.latlongMode.value) {
      lines.push(
        'A lat-long map is shown as the background only: the browser does not prefilter it. ' +
          "envprefilter's KTX2 chain gives the glossy levels (drop it here), its --sh JSON the diffuse sphere.",
      );
    }
    if (!this.hasSh) {
      lines.push('No SH irradiance: drop envprefilter --sh JSON for the Lambertian sphere and the diffuse term.');
    }
    if (this.chain?.halved) {
      lines.push('This GPU does not filter 32-bit floats: the chain was uploaded as half floats.');
    }
    return lines.join(' ');
  }
}

// What a dropped or picked file is, from its name (and, for .exr, its shape: a 2:1 image is a lat-long map,
// anything else the DFG LUT).
async function openFile(viewer, file) {
  const name = file.name.toLowerCase();
  if (name.endsWith('.ktx2')) viewer.setChain(await loadGgxCube(file, viewer.floatLinear));
  else if (name.endsWith('.json')) viewer.setSh(await loadShIrradiance(file));
  else if (name.endsWith('.hdr')) viewer.setLatLong(await loadLatLong(file));
  else if (name.endsWith('.exr')) {
    const texture = await loadLatLong(file);
    if (texture.image.width === 2 * texture.image.height) viewer.setLatLong(texture);
    else {
      texture.dispose();
      viewer.shared.dfg.value = await loadDfgLut(file);
    }
  } else throw new Error(`${file.name}: not a .ktx2, .json, .hdr or .exr file`);
}

function panel(viewer, render) {
  const p = viewer.p;
  const el = document.getElementById('panel');
  if (p.static) {
    el.hidden = true;
    return;
  }
  const $ = (id) => document.getElementById(id);
  const exposure = $('exposure');
  exposure.value = String(Math.log2(p.exposure));
  const showExposure = () => ($('exposure-value').textContent = `${Number(exposure.value).toFixed(1)} EV`);
  showExposure();
  exposure.addEventListener('input', () => {
    viewer.shared.exposure.value = 2 ** Number(exposure.value);
    showExposure();
    render();
  });
  const background = $('background');
  background.value = String(p.background);
  background.addEventListener('input', () => {
    viewer.shared.lod.value = Number(background.value);
    render();
  });
  const roughness = $('roughness');
  roughness.value = p.roughness.join(',');
  roughness.addEventListener('change', () => {
    try {
      p.roughness = numbers(roughness.value, 0, 'roughness').map((r) => Math.min(1, Math.max(0, r)));
      viewer.buildRow();
      render();
    } catch (e) {
      note(e.message);
    }
  });
  const material = $('material');
  material.value = p.material;
  material.addEventListener('change', () => {
    p.material = material.value;
    viewer.updateMaterials();
    render();
  });
  const f0 = $('f0');
  f0.value = hexOf(p.f0);
  f0.addEventListener('input', () => {
    const c = linearOf(f0.value);
    viewer.f0.set(c.r, c.g, c.b);
    viewer.updateMaterials();
    render();
  });
  const albedo = $('albedo');
  albedo.value = hexOf(p.albedo);
  albedo.addEventListener('input', () => {
    const c = linearOf(albedo.value);
    viewer.albedo.set(c.r, c.g, c.b);
    viewer.updateMaterials();
    render();
  });
  const open = async (files) => {
    for (const file of files) {
      try {
        await openFile(viewer, file);
      } catch (e) {
        note(String(e.message ?? e));
        return;
      }
    }
    background.max = String(viewer.chain ? viewer.chain.roughness.length - 1 : 0);
    note(viewer.notes());
    status('ready');
    render();
  };
  $('files').addEventListener('change', (e) => open([...e.target.files]));
  window.addEventListener('dragover', (e) => e.preventDefault());
  window.addEventListener('drop', (e) => {
    e.preventDefault();
    open([...e.dataTransfer.files]);
  });
  return () => {
    background.max = String(viewer.chain ? viewer.chain.roughness.length - 1 : 0);
    note(viewer.notes());
  };
}

async function main() {
  const p = parameters(window.location.search);
  const canvas = document.getElementById('view');
  if (!p.size) canvas.classList.add('fill');
  const viewer = new Viewer(p, canvas);
  viewer.resize();
  const render = () => viewer.render();
  const refreshPanel = panel(viewer, render);
  // Whatever changes the canvas's box (window resizes, device metrics) resizes the drawing buffer.
  new ResizeObserver(() => {
    viewer.resize();
    render();
  }).observe(canvas);

  // Whatever loads is shown; a file that does not load is reported (and files can still be dropped).
  const [chain, dfg, sh] = await Promise.allSettled([
    loadGgxCube(p.map, viewer.floatLinear),
    loadDfgLut(p.lut),
    p.sh ? loadShIrradiance(p.sh) : null,
  ]);
  if (dfg.status === 'fulfilled') viewer.shared.dfg.value = dfg.value;
  if (chain.status === 'fulfilled') viewer.setChain(chain.value);
  if (sh.status === 'fulfilled' && sh.value) sh.value.forEach((c, i) => viewer.shared.sh.value[i].copy(c));
  viewer.hasSh = sh.status === 'fulfilled' && Boolean(sh.value);
  viewer.buildRow();
  const failed = [chain, dfg, sh]
    .filter((r) => r.status === 'rejected')
    .map((r) => String(r.reason?.message ?? r.reason));

  if (!p.static) {
    const controls = new OrbitControls(viewer.camera, canvas);
    controls.addEventListener('start', () => (viewer.moved = true));
    controls.addEventListener('change', render);
  }
  if (refreshPanel) refreshPanel();
  // Renders and reads the canvas back in the same task (no preserveDrawingBuffer needed): RGBA8 rows top to bottom,
  // base64, and a PNG data URL. Used by tests/js/viewer_capture.mjs, with the camera it rendered from.
  window.envkitViewer.capture = () => {
    render();
    const gl = viewer.renderer.getContext();
    const w = gl.drawingBufferWidth;
    const h = gl.drawingBufferHeight;
    const bottomUp = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, bottomUp);
    const rows = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; y++) rows.set(bottomUp.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    let binary = '';
    for (let i = 0; i < rows.length; i += 0x8000) binary += String.fromCharCode(...rows.subarray(i, i + 0x8000));
    const camera = { position: viewer.camera.position.toArray(), fov: viewer.camera.fov };
    return { width: w, height: h, camera, rgba: btoa(binary), png: canvas.toDataURL('image/png') };
  };
  render();
  if (failed.length) throw new Error(`${failed.join('; ')} (files can be dropped on the page)`);
  window.envkitViewer.levels = chain.value.roughness.length;
  window.envkitViewer.mapping = chain.value.mapping;
  status('ready');
}

window.envkitViewer = { state: 'loading' };
main().catch((e) => {
  console.error(e);
  status('error', String(e && e.message ? e.message : e));
});
