"""Camera views skylibs' project() and py360convert's e2p make that envkit lacked: perspective views with separate
horizontal and vertical fields of view (non-square pixels), and the planar orthographic projection. Directions are
checked against the camera model written out here (view.h's basis), solid angles against numerical integration."""

import numpy as np
import pytest

import envkit

integrate = pytest.importorskip("scipy.integrate")


def basis(yaw, pitch):
    """view.h: forward from yaw (about +Y, from +Z towards +X) and pitch; up = the part of +Y perpendicular to
    forward; right = forward x up."""
    y, p = np.radians(yaw), np.radians(pitch)
    f = np.array([np.sin(y) * np.cos(p), np.sin(p), np.cos(y) * np.cos(p)])
    up = np.array([0.0, 1.0, 0.0]) - f[1] * f
    up /= np.linalg.norm(up)
    return f, np.cross(f, up), up


def plane_coordinates(w, h, tx, ty):
    a = ((np.arange(w) + 0.5) / w * 2 - 1) * tx
    b = (1 - (np.arange(h) + 0.5) / h * 2) * ty
    return np.meshgrid(a, b)


@pytest.fixture(scope="module")
def sky():
    m = envkit.EnvMap.blank(64, "latlong")
    d = m.directions()
    m.data[...] = np.stack([1 + d[..., 0], 1 + d[..., 1], 1 + d[..., 2]], -1)
    return m


def test_perspective_with_horizontal_and_vertical_fov(sky, tmp_path):
    v = sky.convert("perspective", size=(48, 40), fov=(90, 50), view_dir=(30, 10))
    assert v.data.shape[:2] == (40, 48)
    assert v.view["fov"] == (90.0, 50.0)
    f, r, u = basis(30, 10)
    a, b = plane_coordinates(48, 40, np.tan(np.radians(45)), np.tan(np.radians(25)))
    want = f + a[..., None] * r + b[..., None] * u
    want /= np.linalg.norm(want, axis=-1, keepdims=True)
    np.testing.assert_allclose(v.directions(), want, atol=1e-12)
    total = 4 * np.arcsin(np.sin(np.radians(45)) * np.sin(np.radians(25)))
    np.testing.assert_allclose(v.solid_angles().sum(), total, rtol=1e-7)
    # Written and read back, the view is the same (envkit:view metadata).
    v.write(str(tmp_path / "v.exr"))
    back = envkit.EnvMap(str(tmp_path / "v.exr"))
    assert back.view == v.view
    np.testing.assert_allclose(back.directions(), v.directions(), atol=1e-12)
    with pytest.raises(ValueError, match="fov"):
        sky.convert("perspective", size=16, fov=(90, 0))
    with pytest.raises(ValueError, match="fov"):
        sky.convert("fisheye", size=16, fov=(90, 50))


def orthographic_solid_angle(a0, a1, b0, b1):
    return integrate.dblquad(lambda b, a: 1.0 / np.sqrt(max(1e-300, 1 - a * a - b * b)), a0, a1, b0, b1,
                             epsabs=1e-13, epsrel=1e-11)[0]


def test_orthographic_planar_view(sky):
    w, h = 40, 30
    v = sky.convert("perspective", size=(w, h), fov=(100, 70), lens="orthographic", view_dir=(-20, 35))
    assert v.parameterization == "perspective" and v.view["lens"] == "orthographic"
    tx, ty = np.sin(np.radians(50)), np.sin(np.radians(35))
    f, r, u = basis(-20, 35)
    a, b = plane_coordinates(w, h, tx, ty)
    want = np.sqrt(1 - a**2 - b**2)[..., None] * f + a[..., None] * r + b[..., None] * u
    np.testing.assert_allclose(v.directions(), want, atol=1e-12)
    # What the view shows is what the sky shows in those directions.
    np.testing.assert_allclose(v.data[..., :3], sky.lookup(want), atol=0.02)
    omega = v.solid_angles()
    np.testing.assert_allclose(omega.sum(), 4 * orthographic_solid_angle(0, tx, 0, ty), rtol=1e-7)  # solid_angles() are tabulated as floats
    for i, j in [(0, 0), (w - 1, h - 1), (w // 2, h // 3)]:
        a0, a1 = (2 * i / w - 1) * tx, (2 * (i + 1) / w - 1) * tx
        b0, b1 = (1 - 2 * (j + 1) / h) * ty, (1 - 2 * j / h) * ty
        np.testing.assert_allclose(omega[j, i], orthographic_solid_angle(a0, a1, b0, b1), rtol=1e-6)
    # texel_of inverts it.
    np.testing.assert_allclose(v.texel_of(v.directions()), np.stack(np.meshgrid(np.arange(w) + 0.5,
                                                                               np.arange(h) + 0.5), -1), atol=1e-9)


def test_orthographic_hemisphere_and_refusal(sky):
    # A square orthographic view of 90 x 90 degrees reaches the hemisphere's rim at its corners.
    v = sky.convert("perspective", size=32, fov=(90, 90), lens="orthographic")
    assert v.solid_angles().sum() < 2 * np.pi
    with pytest.raises(ValueError, match="hemisphere"):
        sky.convert("perspective", size=32, fov=(120, 120), lens="orthographic")
