"""EnvMap against the CLIs (bit for bit) and against closed forms."""
import json
import math

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool


@pytest.mark.parametrize(
    "args",
    [
        dict(to="cube", size=32),
        dict(to="octahedral", size=48, filter="bilinear"),
        dict(to="latlong", size=40, convention="blender", rotate="90,10,0"),
        dict(to="cube", size=24, convention="openexr"),
        dict(to="mirrorball", size=50),
        dict(to="cube", layout="hcross", size=16, filter="nearest"),
        dict(to="latlong"),  # size from the texel density, as envconvert chooses it
    ],
)
def test_convert_equals_envconvert(probe_dir, tmp_path, args):
    src = probe_dir / "sky.exr"
    cli = ["--to", args["to"], "-q"]
    for k in ("size", "filter", "convention", "rotate", "layout"):
        if k in args:
            cli += ["--" + k, str(args[k])]
    out = tmp_path / "cli.exr"
    run_tool("envconvert", src, "-o", out, *cli)
    py = envkit.EnvMap(str(src)).convert(**args)
    expected = exr_array(out)
    assert py.data.shape == expected.shape
    assert np.array_equal(py.data, expected)  # bit for bit
    # And what the module writes is what envconvert wrote, pixels and parameterization.
    py.write(str(tmp_path / "py.exr"))
    again = envkit.EnvMap(str(tmp_path / "py.exr"))
    assert again.describe() == envkit.EnvMap(str(out)).describe()
    assert np.array_equal(again.data, expected)


def test_data_is_a_view(probe_dir):
    m = envkit.EnvMap(str(probe_dir / "sun.exr"))
    a, b = m.data, m.data
    assert np.shares_memory(a, b)
    assert a.flags.c_contiguous and a.dtype == np.float32 and a.shape == (64, 128, 3)
    p0 = m.power()[0]
    a[:, :, 0] = 1.0  # writes go to the map
    assert m.power()[0] == pytest.approx(4 * math.pi, rel=1e-12)
    assert p0 != pytest.approx(4 * math.pi)
    del m
    assert np.all(a[:, :, 0] == 1.0)  # the view keeps the map alive


def test_from_array_and_solid_angles():
    h, w = 16, 32
    arr = np.ones((h, w, 3), np.float32)
    m = envkit.EnvMap(arr, parameterization="latlong")
    omega = m.solid_angles()
    assert omega.sum() == pytest.approx(4 * math.pi, rel=1e-13)
    # Row j of a centre-sampled lat-long: (2 pi / W)(cos theta0 - cos theta1), theta = pi j / H.
    rows = [(2 * math.pi / w) * (math.cos(math.pi * j / h) - math.cos(math.pi * (j + 1) / h)) for j in range(h)]
    assert np.allclose(omega[:, 0], rows, rtol=1e-12, atol=0)
    assert m.power() == pytest.approx([4 * math.pi] * 3, rel=1e-12)
    with pytest.raises(ValueError, match="^array: .*non-finite"):
        envkit.EnvMap(np.full((8, 16, 3), np.nan, np.float32), parameterization="latlong")
    with pytest.raises(ValueError, match="^array: 5 channels"):
        envkit.EnvMap(np.zeros((8, 16, 5), np.float32), parameterization="latlong")


def test_directions_and_texel_of(probe_dir):
    for kind, conv in (("latlong", "envkit"), ("cube", "gl"), ("octahedral", "envkit"), ("latlong", "blender")):
        m = envkit.EnvMap(str(probe_dir / "sky.exr")).convert(kind, size=16, convention=conv)
        d = m.directions()
        assert d.shape == (m.height, m.width, 3)
        assert np.allclose(np.linalg.norm(d, axis=-1), 1.0)
        pos = m.texel_of(d)
        jj, ii = np.mgrid[0 : m.height, 0 : m.width]
        assert np.allclose(pos[..., 0], ii + 0.5, atol=1e-9) and np.allclose(pos[..., 1], jj + 0.5, atol=1e-9)
    # Known directions of the envkit lat-long: the centre sees +Z, u = 1/4 sees +X, the top row +Y.
    ll = envkit.EnvMap(np.zeros((8, 16, 3), np.float32), parameterization="latlong")
    pos = ll.texel_of(np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]]))
    assert np.allclose(pos[0], [8, 4]) and np.allclose(pos[1], [4, 4]) and pos[2][1] == pytest.approx(0)
    with pytest.raises(ValueError, match="^directions: .*zero or non-finite"):
        ll.texel_of(np.zeros((1, 3)))


def test_resize_conserves_power(probe_dir):
    m = envkit.EnvMap(str(probe_dir / "sun.exr"))
    p = np.array(m.power())
    for n in (8, 13, 200):
        r = m.resize(n)
        assert (r.width, r.height) == (2 * n, n)
        assert np.allclose(r.power(), p, rtol=1e-6)
    cube = m.convert("cube", size=16, layout="hcross")
    assert cube.resize(8).layout == "hcross"
    assert np.allclose(cube.resize(8).power()[:3], cube.power()[:3], rtol=1e-5)


def test_rotate_moves_directions():
    m = envkit.probes.sun([0, 0, 1], 2.0, [1e3] * 3, [0.0] * 3).rasterize("latlong", 64)
    r = m.rotate("90,0,0")  # yaw 90 deg about +Y: what was seen along +Z is seen along +X
    assert (r.width, r.height, r.parameterization) == (m.width, m.height, "latlong")
    lum = r.data.sum(axis=-1)
    j, i = np.unravel_index(np.argmax(lum), lum.shape)
    assert np.allclose(r.directions()[j, i], [1, 0, 0], atol=0.05)
    assert np.allclose(r.power(), m.power(), rtol=1e-6)
    assert np.array_equal(m.rotate([90, 0, 0]).data, r.data)


def test_info_equals_envinfo(probe_dir):
    src = probe_dir / "sky.exr"
    cli = json.loads(run_tool("envinfo", src, "--json").stdout)
    py = envkit.EnvMap(str(src)).info()
    assert py["statistics"] == cli["statistics"]
    assert py["solid_angle"] == cli["solid_angle"]


def test_sun_equals_envinfo(probe_dir):
    src = probe_dir / "sky.exr"
    cli = json.loads(run_tool("envinfo", src, "--json").stdout)["sun"]
    py = envkit.EnvMap(str(src)).sun()
    for k in ("direction", "angular_radius_deg", "solid_angle", "texels", "radiance", "power", "power_share",
              "clipped", "clipped_texels"):
        assert py[k] == pytest.approx(cli[k], rel=1e-12), k
    # The default probe's sun: elevation 35 deg, azimuth 40 deg (0 = +Z, 90 = +X), within a texel (1.4 deg).
    e, a = np.radians(35.0), np.radians(40.0)
    expected = [np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)]
    assert np.degrees(np.arccos(np.clip(np.dot(py["direction"], expected), -1, 1))) < 0.7
    blank = envkit.probes.constant([1.0] * 3).rasterize("latlong", 32)
    assert blank.sun() is None


def test_diff_equals_envdiff(probe_dir, tmp_path):
    a = probe_dir / "sky.exr"
    b = tmp_path / "b.exr"
    run_tool("envconvert", a, "-o", b, "--to", "cube", "--size", "24", "-q")
    cli = json.loads(run_tool("envdiff", a, b, "--json", "--metric", "power").stdout)
    py = envkit.EnvMap(str(a)).diff(envkit.EnvMap(str(b)), metric="power")
    for k in ("rmse", "relmse", "compared_solid_angle", "power_max_relative_difference", "value", "power"):
        assert py[k] == cli[k], k
    assert py["max_abs_error"]["value"] == cli["max_abs_error"]["value"]
    assert list(py["max_abs_error"]["texel"]) == cli["max_abs_error"]["texel"]


def test_errors_carry_the_cli_message(tmp_path):
    bad = tmp_path / "broken.exr"
    bad.write_bytes(b"not an image")
    p = run_tool("envconvert", bad, "-o", tmp_path / "o.exr", "--to", "cube", check=False)
    assert p.returncode == 1
    line = p.stderr.strip().splitlines()[-1]
    with pytest.raises(envkit.Error) as e:
        envkit.EnvMap(str(bad))
    assert line == "envconvert: " + str(e.value)
    assert isinstance(e.value, RuntimeError)
    with pytest.raises(envkit.Error, match="unknown"):
        envkit.EnvMap(np.zeros((8, 16, 3), np.float32), parameterization="nope")


def test_array_input_is_borrowed_and_blank_maps_are_filled_in_place():
    arr = np.random.default_rng(1).random((16, 32, 3)).astype(np.float32)
    m = envkit.EnvMap(arr, parameterization="latlong")
    # A writable C-contiguous float32 array is borrowed, not copied (docs/PYTHON.md, "Arrays in and out").
    assert np.shares_memory(m.data, arr) and np.array_equal(m.data, arr)
    before = np.asarray(m.power())
    arr[...] *= 2.0  # the map is a view of the array
    assert np.allclose(np.asarray(m.power()), 2.0 * before, rtol=1e-6)
    arr[...] *= 0.5
    del arr  # the map keeps the floats alive
    import gc
    gc.collect()
    assert np.array_equal(m.power(), before)
    # Results own their storage: a conversion of a borrowed map does not alias it.
    conv = m.convert("latlong")
    assert not np.shares_memory(conv.data, m.data)
    # Anything else is converted once and not aliased: float64, strided, read-only arrays.
    base = np.random.default_rng(2).random((16, 32, 3))
    unaligned = np.zeros(base.size * 4 + 1, np.uint8)[1:].view(np.float32).reshape(base.shape)
    unaligned[...] = base
    for other in (base, base.astype(np.float32)[:, ::-1], base.astype(np.float32), unaligned):
        if other.dtype == np.float32 and other.flags.c_contiguous:
            other.flags.writeable = False
        o = envkit.EnvMap(other, parameterization="latlong")
        assert not np.shares_memory(o.data, other)
        assert np.array_equal(o.data, other.astype(np.float32))
    # The NaN check reads the borrowed array too.
    bad = np.ones((8, 16, 3), np.float32)
    bad[3, 4, 1] = np.inf
    with pytest.raises(ValueError, match="^array: 1 non-finite"):
        envkit.EnvMap(bad, parameterization="latlong")
    arr = np.asarray(m.data).copy()
    b = envkit.EnvMap.blank(16, "latlong")
    assert (b.width, b.height, b.channels, b.convention) == (32, 16, ["R", "G", "B"], "envkit")
    assert not b.data.any()
    b.data[...] = arr  # envkit's own storage, written in place
    assert np.array_equal(b.power(), m.power())
    assert np.array_equal(b.convert("cube", size=8).data, m.convert("cube", size=8).data)
    c = envkit.EnvMap.blank(8, "cube", channels=4, convention="gl")
    assert (c.width, c.height, c.layout, c.alpha_channel) == (8, 48, "vstrip", 3)
    v = envkit.EnvMap.blank(20, "fisheye", view=dict(lens="equisolid", fov=190))
    assert v.view["lens"] == "equisolid" and v.view["fov"] == 190 and (v.width, v.height) == (20, 20)
    with pytest.raises(envkit.Error, match="camera view"):
        envkit.EnvMap.blank(8, "latlong", view=dict(fov=60))
