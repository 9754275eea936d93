"""py360convert's cube formats 'list' and 'dict' and its non-2:1 c2e outputs, checked against py360convert's own
geometry (its equirectangular angles and its xyzcube face layout, written out here from its documentation)."""

import numpy as np
import pytest

import envkit


def f(xyz):
    """An asymmetric smooth function of a py360convert direction (x right of the panorama's centre, y up, z at
    its centre): a flipped or swapped face would not match it."""
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    return np.stack([2 + x + 0.5 * y, 2 + y - 0.3 * z, 2 + z + 0.2 * x * y], -1)


def equirect(h):
    """An h x 2h panorama in py360convert's layout: column -> longitude u = atan2(x, z) from -pi (left) to pi,
    row -> latitude from pi/2 (top) down."""
    w = 2 * h
    u = ((np.arange(w) + 0.5) / w - 0.5) * 2 * np.pi
    v = -((np.arange(h) + 0.5) / h - 0.5) * np.pi
    uu, vv = np.meshgrid(u, v)
    xyz = np.stack([np.cos(vv) * np.sin(uu), np.sin(vv), np.cos(vv) * np.cos(uu)], -1)
    return f(xyz).astype(np.float32)


def py360_face_xyz(n):
    """py360convert's xyzcube at texel centres: face F R B L U D, texel (row, col) -> (x, y, z)."""
    t = (np.arange(n) + 0.5) / n - 0.5
    gx, gy = np.meshgrid(t, -t)  # grid = meshgrid(rng, -rng)
    h = np.full_like(gx, 0.5)
    faces = {
        "F": (gx, gy, h),
        "R": (h, gy, -gx),  # grid flipped left-right into (z, y)
        "B": (-gx, gy, -h),  # grid flipped left-right into (x, y)
        "L": (-h, gy, gx),
        "U": (gx, h, -gy),  # grid flipped up-down into (x, z)
        "D": (gx, -h, gy),
    }
    return {k: np.stack(v, -1) / np.linalg.norm(np.stack(v, -1), axis=-1, keepdims=True) for k, v in faces.items()}


@pytest.mark.parametrize("layout", ["vstrip", "hcross"])
def test_e2c_dict_faces_match_py360convert_geometry(layout):
    n = 32
    pano = envkit.EnvMap(equirect(64), "latlong")
    cube = pano.convert("cube", size=n, layout=layout)
    faces = cube.faces("dict")
    assert list(faces) == ["F", "R", "B", "L", "U", "D"]
    ref = py360_face_xyz(n)
    for k in faces:
        assert faces[k].shape == (n, n, 3)
        np.testing.assert_allclose(faces[k], f(ref[k]), atol=0.03, err_msg=k)
    as_list = cube.faces("list")
    for k, face in zip("FRBLUD", as_list):
        np.testing.assert_array_equal(face, faces[k])


def test_faces_round_trip_and_c2e():
    n = 16
    pano = envkit.EnvMap(equirect(32), "latlong")
    cube = pano.convert("cube", size=n)
    faces = cube.faces("dict")
    back = envkit.EnvMap.from_faces(faces)
    assert back.parameterization == "cube" and back.layout == "vstrip"
    np.testing.assert_array_equal(back.data, cube.data)
    for a, b in zip(envkit.EnvMap.from_faces(cube.faces("list")).faces("list"), cube.faces("list")):
        np.testing.assert_array_equal(a, b)
    # c2e(cubemap, h, w) for any h, w: size=(w, h).
    wide = back.convert("latlong", size=(96, 24))
    assert wide.data.shape == (24, 96, 3)
    pano_wide = envkit.EnvMap(equirect(24), "latlong").convert("latlong", size=(96, 24))
    np.testing.assert_allclose(wide.data, pano_wide.data, atol=0.05)


def test_faces_refusals():
    with pytest.raises(ValueError, match="cube"):
        envkit.EnvMap.blank(4).faces()
    cube = envkit.EnvMap.blank(4, "cube")
    with pytest.raises(ValueError, match="format"):
        cube.faces("dice")
    with pytest.raises(ValueError, match="lacks"):
        envkit.EnvMap.from_faces({"F": np.zeros((4, 4, 3))})
    with pytest.raises(TypeError):
        envkit.EnvMap.from_faces(np.zeros((6, 4, 4, 3)))
