// GLSL of the viewer. The split-sum specular of envkit (docs/PREFILTER.md): the prefiltered radiance at the
// reflection direction, read at the mip level of the sphere's roughness, times F0 A + B from the DFG LUT. The cube is
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

export const sphereFragment = /* glsl */ `
precision highp float;
uniform samplerCube ggx;
uniform sampler2D dfg;
uniform vec3 centre;
uniform float roughness;
uniform float lod;
uniform vec3 f0;
in vec3 vWorld;
out vec4 fragColor;
${display}
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
  fragColor = vec4(display(prefiltered * (f0 * ab.x + ab.y)), 1.0);
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

export const backgroundFragment = /* glsl */ `
precision highp float;
uniform samplerCube ggx;
uniform float lod;
in vec3 vWorld;
out vec4 fragColor;
${display}
void main() {
  fragColor = vec4(display(textureLod(ggx, normalize(vWorld - cameraPosition), lod).rgb), 1.0);
}
`;
