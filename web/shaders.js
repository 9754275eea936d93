// GLSL of the viewer. The split-sum specular of envkit (docs/PREFILTER.md): the prefiltered radiance at the
// reflection direction, read at the mip level of the sphere's roughness, times F0 A + B from the DFG LUT; plus a
// Lambertian term, albedo times E(n) / pi from envprefilter's SH irradiance (irradiance_over_pi). The cube is
// sampled with the world direction as it is (envkit's frame is GL's: +Y up, GL/KTX face table), so unlike three's
// own environment maps there is no x flip.

// Shared display transform: exposure, Reinhard per channel (keeps a sun's reflection from clipping), sRGB encoding.
// tests/tools/test_viewer.cpp applies the same transform to envkit's own shading.
const display = /* glsl */ `
uniform float exposure;
vec3 display(vec3 radiance) {
  vec3 x = exposure * max(radiance, vec3(0.0));
  x = x / (1.0 + x);
  return mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x));
}
`;

export const sphereVertex = /* glsl */ `
out vec3 vWorld;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vWorld = world.xyz;
  gl_Position = projectionMatrix * viewMatrix * world;
}
`;

// envkit's SH basis (libenv/ibl/include/envkit/ibl/sh.h): real, orthonormal, no Condon-Shortley phase, index
// l (l + 1) + m, in the world direction (x, y, z), up to order 3. Returns sum c_i Y_i(n).
const shIrradiance = /* glsl */ `
uniform vec3 sh[16];
vec3 shIrradiance(vec3 n) {
  float x = n.x, y = n.y, z = n.z;
  vec3 e = sh[0] * 0.282095;
  e += 0.488603 * (sh[1] * y + sh[2] * z + sh[3] * x);
  e += sh[4] * (1.092548 * x * y) + sh[5] * (1.092548 * y * z) + sh[6] * (0.315392 * (3.0 * z * z - 1.0)) +
       sh[7] * (1.092548 * x * z) + sh[8] * (0.546274 * (x * x - y * y));
  e += sh[9] * (0.590044 * y * (3.0 * x * x - y * y)) + sh[10] * (2.890611 * x * y * z) +
       sh[11] * (0.457046 * y * (4.0 * z * z - x * x - y * y)) +
       sh[12] * (0.373176 * z * (2.0 * z * z - 3.0 * x * x - 3.0 * y * y)) +
       sh[13] * (0.457046 * x * (4.0 * z * z - x * x - y * y)) + sh[14] * (1.445306 * z * (x * x - y * y)) +
       sh[15] * (0.590044 * x * (x * x - 3.0 * y * y));
  return max(e, vec3(0.0));
}
`;

export const sphereFragment = /* glsl */ `
precision highp float;
uniform samplerCube ggx;
uniform sampler2D dfg;
uniform vec3 centre;
uniform float roughness;
uniform float lod;
uniform vec3 f0;
uniform float specular;  // 1: split-sum specular of colour f0; 0: none (a Lambertian sphere)
uniform vec3 albedo;     // diffuse albedo, times the SH irradiance / pi
in vec3 vWorld;
out vec4 fragColor;
${display}
${shIrradiance}
void main() {
  // The exact sphere normal at the rasterised point (not the interpolated normal of the tessellation).
  vec3 n = normalize(vWorld - centre);
  vec3 v = isOrthographic ? normalize(vec3(viewMatrix[0][2], viewMatrix[1][2], viewMatrix[2][2]))
                          : normalize(cameraPosition - vWorld);
  float nv = clamp(dot(n, v), 0.0, 1.0);
  vec3 r = reflect(-v, n);
  vec3 prefiltered = textureLod(ggx, r, lod).rgb;
  // LUT texel (i, j): n.v = (i + 0.5) / W, roughness = (j + 0.5) / H, rows bottom-up after EXRLoader.
  vec2 ab = texture(dfg, vec2(nv, 1.0 - roughness)).rg;  // ENVKIT_LUT_LOOKUP
  vec3 radiance = specular * prefiltered * (f0 * ab.x + ab.y) + albedo * shIrradiance(n);
  fragColor = vec4(display(radiance), 1.0);
}
`;

export const backgroundVertex = /* glsl */ `
out vec3 vWorld;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vWorld = world.xyz;
  gl_Position = projectionMatrix * viewMatrix * world;
  gl_Position.z = gl_Position.w;  // at the far plane, behind everything
}
`;

// The background: level `lod` of the cube (linear filtering, see ibl.js), or, when latlongMode is 1, a lat-long
// map in envkit's layout: u = (pi - atan(x, z)) / 2 pi, v = 1/2 - latitude / pi, v = 0 on the file's first row,
// which three's loaders put at t = 1.
export const backgroundFragment = /* glsl */ `
precision highp float;
uniform samplerCube ggx;
uniform sampler2D latlong;
uniform float latlongMode;
uniform float lod;
in vec3 vWorld;
out vec4 fragColor;
${display}
const float PI = 3.14159265358979;
void main() {
  vec3 d = normalize(vWorld - cameraPosition);
  vec3 radiance;
  if (latlongMode > 0.5) {
    float u = (PI - atan(d.x, d.z)) / (2.0 * PI);
    float v = 0.5 - atan(d.y, length(d.xz)) / PI;
    radiance = textureLod(latlong, vec2(u, 1.0 - v), 0.0).rgb;
  } else {
    radiance = textureLod(ggx, d, lod).rgb;
  }
  fragColor = vec4(display(radiance), 1.0);
}
`;
