// Loading envprefilter's outputs for the viewer: the GGX radiance chain (KTX2 cube, RGBA16F or RGBA32F, every level)
// and the DFG lookup table (OpenEXR, scale-bias layout).
//
// three's KTX2Loader turns an uncompressed KTX2 file into a DataTexture even when it holds six faces, so the cube is
// built here from the container (read by the ktx-parse copy that ships with three) as a CompressedCubeTexture: three
// uploads an RGBAFormat "compressed" cube with texSubImage2D level by level, which is exactly an uncompressed cube
// with our own mip chain (no PMREM, no generated mipmaps).
import * as THREE from 'three';
import { read } from 'three/addons/libs/ktx-parse.module.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

const VK_FORMAT_R16G16B16A16_SFLOAT = 97;
const VK_FORMAT_R32G32B32A32_SFLOAT = 109;

async function fetchBytes(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return new Uint8Array(await response.arrayBuffer());
}

function keyValueText(value) {
  return typeof value === 'string' ? value : new TextDecoder().decode(value).replace(/\0$/, '');
}

/**
 * Loads a KTX2 GGX chain written by envprefilter (cube, RGBA16F or RGBA32F).
 * @returns {{texture: THREE.CompressedCubeTexture, size: number, roughness: number[], mapping: string}}
 *   roughness[m] is the perceptual roughness of level m (the file's envkit:ibl_roughness).
 */
export async function loadGgxCube(url) {
  const container = read(await fetchBytes(url));
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
  container.levels.forEach((level, m) => {
    const n = Math.max(1, container.pixelWidth >> m);
    // A copy: the level's bytes need not be aligned to the element size inside the file's buffer.
    const data = new Array_(level.levelData.slice().buffer);
    const faceLength = data.length / 6;
    for (let f = 0; f < 6; f++) {
      faces[f].mipmaps.push({ data: data.subarray(f * faceLength, (f + 1) * faceLength), width: n, height: n });
    }
  });
  const texture = new THREE.CompressedCubeTexture(faces, THREE.RGBAFormat, type);
  texture.minFilter = THREE.LinearMipmapLinearFilter;
  texture.magFilter = THREE.LinearFilter;
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace; // linear radiance, no conversion
  texture.needsUpdate = true;
  const kv = container.keyValue;
  const roughness = kv['envkit:ibl_roughness']
    ? keyValueText(kv['envkit:ibl_roughness']).split(',').map(Number)
    : container.levels.map((_, m, all) => (all.length > 1 ? m / (all.length - 1) : 0));
  const mapping = kv['envkit:ibl_roughness_mapping'] ? keyValueText(kv['envkit:ibl_roughness_mapping']) : 'gltf';
  return { texture, size: container.pixelWidth, roughness, mapping };
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
export async function loadDfgLut(url) {
  const loader = new EXRLoader();
  loader.setDataType(THREE.HalfFloatType);
  const texture = await loader.loadAsync(url);
  texture.minFilter = THREE.LinearFilter;
  texture.magFilter = THREE.LinearFilter;
  texture.wrapS = THREE.ClampToEdgeWrapping;
  texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace;
  texture.needsUpdate = true;
  return texture;
}
