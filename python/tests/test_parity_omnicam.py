"""EnvMap.from_omnicam against Scaramuzza's published omnidirectional camera model (OCamCalib's cam2world with
the polynomial `pol`, solved here by root finding), on a synthetic calibration whose world2cam polynomial `invpol`
is fitted as OCamCalib fits it. from_omnicam uses only invpol, so the two sides share no code."""

import numpy as np
import pytest

import envkit

H, W = 180, 200
POL = np.array([-60.0, 0.0, 4.0e-3, -1.0e-5])  # ascending powers of the distance r (pixels)
XC, YC = 91.3, 98.6  # centre: row, column
C, D, E = 1.002, 0.003, -0.002  # affine [c d; e 1]


def cam2world(rows, cols):
    """OCamCalib's cam2world: (row, col) pixel positions (centres at integers) -> unit camera-frame directions."""
    invdet = 1.0 / (C - D * E)
    xp = invdet * ((rows - XC) - D * (cols - YC))
    yp = invdet * (-E * (rows - XC) + C * (cols - YC))
    r = np.hypot(xp, yp)
    zp = np.polynomial.polynomial.polyval(r, POL)
    v = np.stack([xp, yp, zp], -1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def fitted_invpol(degree=12):
    """theta -> rho, fitted as OCamCalib's findinvpoly does (theta = atan(z / rho) along the radius)."""
    r = np.linspace(0.0, 160.0, 2000)
    theta = np.arctan2(np.polynomial.polynomial.polyval(r, POL), r)
    coeffs = np.polynomial.polynomial.polyfit(theta, r, degree)
    assert np.max(np.abs(np.polynomial.polynomial.polyval(theta, coeffs) - r)) < 0.01
    return coeffs


CALIB = dict(invpol=fitted_invpol(), pol=POL, xc=XC, yc=YC, c=C, d=D, e=E)


def world_to_camera(d, forward, up):
    """envkit's view frame (view.h): image right = forward x up. OCamCalib's camera: x down the rows, y along the
    columns, the optical axis -z."""
    right = np.cross(forward, up)
    return np.stack([-(d @ up), d @ right, -(d @ forward)], -1)


def project_by_pol(cam):
    """The pixel position seeing camera-frame directions, by solving pol(r) = m r for r (the published forward
    model inverted numerically, not through invpol)."""
    out = np.full(cam.shape[:-1] + (2,), np.nan)
    flat = cam.reshape(-1, 3)
    res = out.reshape(-1, 2)
    for k, (x, y, z) in enumerate(flat):
        rho = np.hypot(x, y)
        if rho < 1e-12:
            res[k] = (XC, YC)
            continue
        m = z / rho
        poly = POL.copy()
        poly[1] -= m
        roots = np.polynomial.polynomial.polyroots(poly)
        roots = roots[(np.abs(roots.imag) < 1e-9) & (roots.real >= 0) & (roots.real < 160)].real
        if roots.size == 0:
            continue
        r = roots.min()
        xp, yp = r * x / rho, r * y / rho
        res[k] = (C * xp + D * yp + XC, E * xp + yp + YC)
    return out


def grid_photo():
    """Each pixel holds its own (row, column)."""
    rows, cols = np.meshgrid(np.arange(H, dtype=np.float32), np.arange(W, dtype=np.float32), indexing="ij")
    return np.stack([rows, cols, np.zeros_like(rows)], -1)


@pytest.mark.parametrize(
    "view_dir,forward,up", [(None, [0, 0, 1.0], [0, 1.0, 0]), ((0, 90), [0, 1.0, 0], [0, 0, -1.0])]
)
def test_from_omnicam_points_where_the_polynomial_model_says(view_dir, forward, up):
    m = envkit.EnvMap.from_omnicam(grid_photo(), CALIB, 24, view_dir=view_dir, filter="nearest")
    assert m.data.shape == (24, 48, 4) and m.channels == ["R", "G", "B", "A"]
    d = m.directions()
    pos = project_by_pol(world_to_camera(d, np.array(forward), np.array(up)))
    inside = (
        (d @ np.array(forward) > 0)
        & np.all(np.isfinite(pos), -1)
        & (pos[..., 0] > 0.5)
        & (pos[..., 0] < H - 1.5)
        & (pos[..., 1] > 0.5)
        & (pos[..., 1] < W - 1.5)
    )
    assert inside.sum() > 200
    covered = m.data[..., 3] > 0
    np.testing.assert_array_equal(covered[inside], True)
    assert not covered[d @ np.array(forward) < -1e-9].any()  # behind the 180-degree lens: no coverage
    got = m.data[..., :2][inside]
    want = np.rint(pos[inside])
    agree = np.all(got == want, -1)
    assert agree.mean() > 0.98  # ties between pixels aside, the nearest pixel is the model's
    assert np.max(np.abs(got - pos[inside])) <= 0.5 + 1e-3


def test_from_omnicam_values_of_a_smooth_scene():
    def scene(d):
        return np.stack([1 + d[..., 0], 1 + 0.5 * d[..., 1], 1 + d[..., 2] ** 2], -1)

    rows, cols = np.meshgrid(np.arange(H, dtype=float), np.arange(W, dtype=float), indexing="ij")
    cam = cam2world(rows, cols)
    # Camera looking along +Z, image up +Y, right -X: world d = -x up + y right - z forward.
    world = -cam[..., :1] * np.array([0, 1.0, 0]) + cam[..., 1:2] * np.array([-1.0, 0, 0]) - cam[..., 2:] * np.array(
        [0, 0, 1.0]
    )
    photo = scene(world).astype(np.float32)
    m = envkit.EnvMap.from_omnicam(photo, CALIB, 32, "cube", fov=120)
    ok = m.data[..., 3] == 1
    assert ok.sum() > 300
    d = m.directions()
    np.testing.assert_allclose(m.data[..., :3][ok], scene(d)[ok], atol=3e-3)
    angle = np.degrees(np.arccos(np.clip(d[..., 2], -1, 1)))
    assert not ok[angle > 60.5].any()


def test_from_omnicam_refusals():
    photo = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(ValueError, match="invpol"):
        envkit.EnvMap.from_omnicam(photo, dict(xc=4, yc=4))
    with pytest.raises(ValueError, match="xc"):
        envkit.EnvMap.from_omnicam(photo, dict(invpol=[1.0]))
    with pytest.raises(ValueError, match="parameterization"):
        envkit.EnvMap.from_omnicam(photo, CALIB, 8, "perspective")
    with pytest.raises(TypeError):
        envkit.EnvMap.from_omnicam(photo, [1, 2, 3])
