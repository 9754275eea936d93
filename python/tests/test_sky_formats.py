"""The sky formats skylatlong and skyangular (skylibs' upper-hemisphere maps) through the Python module."""
import math

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool


def skylibs_skylatlong2world(u, v):
    """skylibs' envmap/projections.py skylatlong2world, in skylibs' world ((x, y, z) = envkit's (-x, y, -z))."""
    theta, phi = np.pi * (2 * u - 1), np.pi * v / 2
    return np.stack([np.sin(phi) * np.sin(theta), np.cos(phi), -np.sin(phi) * np.cos(theta)], axis=-1)


def skylibs_skyangular2world(u, v):
    """skylibs' skyangular2world: zenith angle pi/2 r, +X right, +Z up in the image; NaN outside the disk."""
    theta = np.arctan2(-2 * v + 1, 2 * u - 1)
    r = np.sqrt((2 * u - 1) ** 2 + (2 * v - 1) ** 2)
    phi = np.pi / 2 * r
    d = np.stack([np.sin(phi) * np.cos(theta), np.cos(phi), np.sin(phi) * np.sin(theta)], axis=-1)
    d[r > 1] = np.nan
    return d


def pixel_centres(h, w):
    """skylibs' imageCoordinates: u, v of the pixel centres in [0, 1]."""
    v, u = np.mgrid[0:h, 0:w]
    return (u + 0.5) / w, (v + 0.5) / h


def test_solid_angles_sum_to_two_pi_and_directions_are_skylibs():
    for kind, shape in (("skylatlong", (16, 64, 3)), ("skylatlong", (3, 12, 1)), ("skyangular", (33, 33, 3))):
        m = envkit.EnvMap(np.ones(shape, np.float32), kind)
        assert m.parameterization == kind
        assert m.solid_angles().sum() == pytest.approx(2 * math.pi, rel=1e-9)
        assert m.power()[0] == pytest.approx(2 * math.pi, rel=1e-9)
        h, w = shape[:2]
        u, v = pixel_centres(h, w)
        skylibs = (skylibs_skylatlong2world if kind == "skylatlong" else skylibs_skyangular2world)(u, v)
        envkit_dirs = m.directions() * np.array([-1.0, 1.0, -1.0])  # envkit's world in skylibs' axes
        inside = ~np.isnan(skylibs[..., 0])
        assert inside.sum() > 0
        assert np.allclose(envkit_dirs[inside], skylibs[inside], atol=1e-12)
    # Known directions: the zenith on the top row, the horizon along +Z at u = 1/2 on the bottom edge.
    sky = envkit.EnvMap(np.zeros((8, 32, 3), np.float32), "skylatlong")
    pos = sky.texel_of(np.array([[0, 1.0, 0], [0, 0, 1.0], [1.0, 0, 0]]))
    assert pos[0][1] == pytest.approx(0) and np.allclose(pos[1], [16, 8]) and np.allclose(pos[2], [8, 8])


def test_convert_to_and_from_sky_formats(probe_dir, tmp_path):
    m = envkit.EnvMap(str(probe_dir / "sky.exr"))  # 256 x 128: the horizon is the edge below row 63
    omega = m.solid_angles()
    upper = (m.data[:64, :, :3] * omega[:64, :, None]).sum(axis=(0, 1), dtype=np.float64)
    # The area filter's power: the sky lat-long's rows are the lat-long's (to float round-off); the disk's rim is
    # within the area filter's bound for any pair of maps (1e-3, test_resample).
    for kind, size, shape, rtol in (("skylatlong", 32, (32, 128, 3), 1e-6), ("skyangular", 64, (64, 64, 3), 1e-3)):
        s = m.convert(kind, size=size)
        assert s.parameterization == kind and s.data.shape == shape
        assert np.allclose(s.power()[:3], upper, rtol=rtol)
        # The same pixels as envconvert.
        out = tmp_path / (kind + ".exr")
        run_tool("envconvert", probe_dir / "sky.exr", "-o", out, "--to", kind, "--size", size, "-q")
        assert np.array_equal(exr_array(out), s.data)
        assert envkit.EnvMap(str(out)).parameterization == kind  # from its metadata
        # Back to a full lat-long: coverage alpha, 0 below the horizon, the power kept above it.
        back = s.convert("latlong", size=64)
        assert back.data.shape == (64, 128, 4)
        assert np.all(back.data[32:, :, 3] == 0) and np.all(back.data[32:, :, :3] == 0)
        assert np.allclose(back.power()[:3], upper, rtol=rtol)


def test_wrong_aspect_is_refused():
    with pytest.raises(ValueError, match="contradicts --from skylatlong \\(expects 4:1\\)"):
        envkit.EnvMap(np.zeros((16, 32, 3), np.float32), "skylatlong")
    with pytest.raises(ValueError, match="expects 1:1"):
        envkit.EnvMap(np.zeros((16, 32, 3), np.float32), "skyangular")
