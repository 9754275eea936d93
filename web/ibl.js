// Loading envprefilter's outputs for the viewer: the GGX radiance chain (KTX2 cube, RGBA16F or RGBA32F, every level),
// the DFG lookup table (OpenEXR, scale-bias layout) and the SH irradiance (JSON of envprefilter --sh); and a plain
// lat-long map (.hdr or .exr), shown as the background only.
//
// three's KTX2Loader turns an uncompressed KTX2 file into a DataTexture even when it holds six faces, so the cube is
// built here from the container (read by the ktx-parse copy that ships with three) as a CompressedCubeTexture: three
// uploads an RGBAFormat "compressed" cube with texSubImage2D level by level, which is exactly an uncompressed cube
// with our own mip chain (no PMREM, no generated mipmaps).
import * as THREE from 'three';
import { read } from 'three/addons/libs/ktx-parse.module.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { HDRLoader } from 'three/addons/loaders/HDRLoader.js';

const VK_FORMAT_R16G16B16A16_SFLOAT = 97;
const VK_FORMAT_R32G32B32A32_SFLOAT = 109;

/** The bytes of a URL or of a File (dropped or picked). */
export async function bytesOf(source) {
  if (typeof source !== 'string') return new Uint8Array(await source.arrayBuffer());
  const response = await fetch(source);
  if (!response.ok) throw new Error(`${source}: HTTP ${response.status}`);
  return new Uint8Array(await response.arrayBuffer());
}

const nameOf = (source) => (typeof source === 'string' ? source : source.name);

// Magnification of level 0 and the blend between levels must be linear: nearest magnification shows the texels of
// the background as blocks. WebGL2 filters half floats always, 32-bit floats only with OES_texture_float_linear;
// without it a float chain is uploaded as half floats (three's DataUtils.toHalfFloat, which clamps at 65504).
function filterableType(type, data, floatLinear) {
  if (type !== THREE.FloatType || floatLinear) return { type, data };
  const half = new Uint16Array(data.length);
  for (let i = 0; i < data.length; i++) half[i] = THREE.DataUtils.toHalfFloat(data[i]);
  return { type: THREE.HalfFloatType, data: half };
}

function keyValueText(value) {
  return typeof value === 'string' ? value : new TextDecoder().decode(value).replace(/\0$/, '');
}

/**
 * Loads a KTX2 GGX chain written by envprefilter (cube, RGBA16F or RGBA32F) from a URL or a File.
 * `floatLinear`: whether the context filters 32-bit float textures (OES_texture_float_linear).
 * @returns {{texture: THREE.CompressedCubeTexture, size: number, roughness: number[], mapping: string,
 *   halved: boolean}} roughness[m] is the perceptual roughness of level m (the file's envkit:ibl_roughness);
 *   halved says a float chain was uploaded as half floats.
 */
export async function loadGgxCube(source, floatLinear = true) {
  const url = nameOf(source);
  const container = read(await bytesOf(source));
  if (container.faceCount !== 6) throw new Error(`${url}: not a cube map (faceCount ${container.faceCount})`);
  let type;
  let Array_;
  if (container.vkFormat === VK_FORMAT_R16G16B16A16_SFLOAT) {
    type = THREE.HalfFloatType;
    Array_ = Uint16Array;
  } else if (container.vkFormat === VK_FORMAT_R32G32B32A32_SFLOAT) {
    type = THREE.FloatType;
    Array_ = Float32Array;
  } else {
    throw new Error(`${url}: vkFormat ${container.vkFormat} is not rgba16f or rgba32f (use envprefilter --format rgba16f)`);
  }
  const faces = [];
  for (let f = 0; f < 6; f++) faces.push({ mipmaps: [], width: container.pixelWidth, height: container.pixelHeight });
  const fileType = type;
  container.levels.forEach((level, m) => {
    const n = Math.max(1, container.pixelWidth >> m);
    // A copy: the level's bytes need not be aligned to the element size inside the file's buffer.
    let data;
    ({ type, data } = filterableType(fileType, new Array_(level.levelData.slice().buffer), floatLinear));
    const faceLength = data.length / 6;
    for (let f = 0; f < 6; f++) {
      faces[f].mipmaps.push({ data: data.subarray(f * faceLength, (f + 1) * faceLength), width: n, height: n });
    }
  });
  const texture = new THREE.CompressedCubeTexture(faces, THREE.RGBAFormat, type);
  texture.minFilter = THREE.LinearMipmapLinearFilter;
  texture.magFilter = THREE.LinearFilter; // ENVKIT_CUBE_MAG_FILTER
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace; // linear radiance, no conversion
  texture.needsUpdate = true;
  const kv = container.keyValue;
  const roughness = kv['envkit:ibl_roughness']
    ? keyValueText(kv['envkit:ibl_roughness']).split(',').map(Number)
    : container.levels.map((_, m, all) => (all.length > 1 ? m / (all.length - 1) : 0));
  const mapping = kv['envkit:ibl_roughness_mapping'] ? keyValueText(kv['envkit:ibl_roughness_mapping']) : 'gltf';
  return { texture, size: container.pixelWidth, roughness, mapping, halved: type !== fileType };
}

/**
 * The fractional mip level whose roughness is `r`: linear between the two levels around it (what the GPU's trilinear
 * lookup then blends), clamped to the chain.
 */
export function lodForRoughness(levelRoughness, r) {
  const last = levelRoughness.length - 1;
  if (last <= 0 || r <= levelRoughness[0]) return 0;
  for (let m = 0; m < last; m++) {
    const r0 = levelRoughness[m];
    const r1 = levelRoughness[m + 1];
    if (r <= r1) return r1 > r0 ? m + (r - r0) / (r1 - r0) : m;
  }
  return last;
}

/**
 * Loads the DFG LUT (envprefilter --lut dfg.exr, layout scale-bias: R = A, G = B). three's EXRLoader stores the
 * file's last row first (GL's bottom-up rows), so row j of the file (roughness (j + 0.5) / H) is at t = 1 - (j + 0.5) / H.
 */
export async function loadDfgLut(source) {
  const texture = await loadExr(source);
  texture.minFilter = THREE.LinearFilter;
  texture.magFilter = THREE.LinearFilter;
  texture.wrapS = THREE.ClampToEdgeWrapping;
  texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace;
  texture.needsUpdate = true;
  return texture;
}

async function loadExr(source) {
  const loader = new EXRLoader();
  loader.setDataType(THREE.HalfFloatType);
  if (typeof source === 'string') return loader.loadAsync(source);
  const data = loader.parse((await bytesOf(source)).buffer);
  const texture = new THREE.DataTexture(data.data, data.width, data.height, data.format, data.type);
  texture.flipY = false; // EXRLoader already put the file's last row first
  return texture;
}

/**
 * Loads a lat-long map (.hdr through three's HDRLoader, .exr through EXRLoader) as a half-float 2D texture, linear
 * filtering, no mipmaps. Both loaders leave the file's first row at t = 1 (HDRLoader by flipY, EXRLoader by storing
 * the rows bottom-up), so the shader reads envkit's v (0 on the first row) at t = 1 - v.
 */
export async function loadLatLong(source) {
  let texture;
  if (/\.hdr$/i.test(nameOf(source))) {
    const loader = new HDRLoader();
    loader.setDataType(THREE.HalfFloatType);
    if (typeof source === 'string') texture = await loader.loadAsync(source);
    else {
      const data = loader.parse((await bytesOf(source)).buffer);
      texture = new THREE.DataTexture(data.data, data.width, data.height, data.format, data.type);
      texture.flipY = true;
    }
  } else {
    texture = await loadExr(source);
  }
  texture.wrapS = THREE.RepeatWrapping; // longitude wraps around
  texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.minFilter = THREE.LinearFilter;
  texture.magFilter = THREE.LinearFilter;
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace;
  texture.needsUpdate = true;
  return texture;
}

/** Coefficients the shader holds: up to order 3. */
export const SH_MAX = 16;

/**
 * Reads envprefilter's SH JSON (--sh): the `irradiance_over_pi` coefficients of R, G and B (E(n) / pi =
 * sum c_i Y_i(n), index i = l (l + 1) + m, envkit's basis: real, orthonormal, no Condon-Shortley phase).
 * Files of a higher order (--sh-order 4..16) are truncated to order 3: the basis is orthonormal, so the first
 * SH_MAX coefficients are the order-3 irradiance, and the clamped cosine leaves little past it (A_4 = pi / 24,
 * odd bands 0).
 * @returns {THREE.Vector3[]} SH_MAX coefficients (RGB each), zero past the file's order.
 */
export async function loadShIrradiance(source) {
  const url = nameOf(source);
  const json = JSON.parse(new TextDecoder().decode(await bytesOf(source)));
  const c = json?.irradiance_over_pi?.coefficients;
  const channels = json?.channels;
  if (!c || !Array.isArray(channels) || channels.length < 3)
    throw new Error(`${url}: not envprefilter's SH JSON (no irradiance_over_pi coefficients of 3 channels)`);
  const rgb = channels.slice(0, 3).map((name) => c[name]);
  const count = Array.isArray(rgb[0]) ? rgb[0].length : 0;
  const square = Math.round(Math.sqrt(count)) ** 2 === count && count > 0;
  if (!square || rgb.some((v) => !Array.isArray(v) || v.length !== count || v.some((x) => !Number.isFinite(x))))
    throw new Error(`${url}: SH coefficients must be (order + 1)^2 finite numbers per channel`);
  const out = [];
  for (let i = 0; i < SH_MAX; i++) {
    out.push(i < count ? new THREE.Vector3(rgb[0][i], rgb[1][i], rgb[2][i]) : new THREE.Vector3());
  }
  return out;
}
