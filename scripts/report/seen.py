"""Accuracy of a converted map as a renderer or an engine sees it, against a reference map.

A per-texel metric such as relMSE = mean((I - R)^2 / (R^2 + 0.01)) charges a sky texel that receives part of a sun's
flux (which the source's own resolution spread there) up to ~1e5, and a sun lost altogether at most 1 per texel: it
ranks a filter that loses the sun above one that keeps it. What a surface sees is the map convolved with its lobe, so
errors are measured after the same convolution of output and reference:
  power        max over channels of |P - P_ref| / P_ref, P = sum of L x texel solid angle
  ggx <alpha>  relative RMS over the texels of a GGX-prefiltered level (envkit.prefilter, glTF mapping: a chain of
               LEVELS levels from a SIZE face, so level m has roughness m / (LEVELS - 1), alpha its square, and face
               SIZE >> m): what a glossy surface of that alpha sees, and what real-time IBL stores
  irradiance   relative RMS of the irradiance map (envkit.irradiance, E / pi at every texel of a 32 face): what a
               diffuse surface sees
relative RMS = sqrt(sum_t w_t (C_t - R_t)^2 / sum_t w_t R_t^2) over texels t and colour channels, w_t the texel's
solid angle. The prefilter's own error (0.27% of the brute-force sum at its default accuracy, docs/PREFILTER.md) is
the same linear operator on both maps, so their difference is what the lobe sees.
"""
import numpy as np

SIZE = 128
LEVELS = 5  # roughness 0, 0.25, 0.5, 0.75, 1: alpha 0.0625 (face 64), 0.25 (32), 0.5625 (16)
MEASURED_LEVELS = (1, 2, 3)
IRRADIANCE_SIZE = 32


def _cube_weights(envkit, face, channels):
    """Solid angle of each texel of a vertical-strip cube of that face, broadcast over channels."""
    w = np.asarray(envkit.EnvMap.blank(face, "cube").solid_angles(), np.float64)
    return np.repeat(w[..., None], channels, axis=-1)


def _rel_rms(c, r, w):
    c, r = np.asarray(c, np.float64)[..., :3], np.asarray(r, np.float64)[..., :3]
    w = w[..., : c.shape[-1]]
    den = float(np.sum(w * r * r))
    return float(np.sqrt(np.sum(w * (c - r) ** 2) / den)) if den > 0 else 0.0


def seen_columns():
    alphas = [(m / (LEVELS - 1)) ** 2 for m in MEASURED_LEVELS]
    return ["power"] + [f"ggx {a:g}" for a in alphas] + ["irradiance"]


def seen_errors(out_path, ref_path, size=SIZE):
    """{column: error} (seen_columns()) of the map at out_path against the one at ref_path; size: level 0 of the
    prefiltered chains (smaller is faster; the levels' alphas do not depend on it)."""
    import envkit  # the module built with the tools (report.sh puts BUILD/python on PYTHONPATH)

    out_map, ref_map = envkit.EnvMap(out_path), envkit.EnvMap(ref_path)
    p_out, p_ref = np.asarray(out_map.power()[:3], np.float64), np.asarray(ref_map.power()[:3], np.float64)
    result = {"power": float(np.max(np.abs(p_out - p_ref) / np.maximum(p_ref, 1e-300)))}
    chains = [envkit.prefilter(m, size=size, levels=LEVELS, mapping="gltf") for m in (out_map, ref_map)]
    for m in MEASURED_LEVELS:
        a, r = np.asarray(chains[0][m]), np.asarray(chains[1][m])
        alpha = float(chains[1].alpha[m])
        result[f"ggx {alpha:g}"] = _rel_rms(a, r, _cube_weights(envkit, max(1, size >> m), a.shape[-1]))
    irr_size = min(IRRADIANCE_SIZE, size)
    irr = [np.asarray(envkit.irradiance(m, size=irr_size)[0]) for m in (out_map, ref_map)]
    result["irradiance"] = _rel_rms(irr[0], irr[1], _cube_weights(envkit, irr_size, irr[0].shape[-1]))
    return result
