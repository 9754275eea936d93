"""Argument checks of the Python module: every integer, size and count argument is converted by one checked
conversion (TypeError for a wrong type, ValueError for a value out of range, both naming the argument), arrays must
hold real numbers (complex ones are refused, strided views are accepted), and oversized requests are refused up
front with the size and the memory they need (libenv's request check), never with MemoryError."""
import json
import os

import numpy as np
import pytest

import envkit
from conftest import HERE


@pytest.fixture(scope="module")
def sky():
    return envkit.probes.default().rasterize("latlong", 32)


def raises(kind, name, call, *args, **kwargs):
    """Asserts call(*args, **kwargs) raises exactly `kind` (not a subclass such as envkit.Error) naming `name`."""
    with pytest.raises(Exception) as e:
        call(*args, **kwargs)
    assert type(e.value) is kind, "%s: %r" % (type(e.value).__name__, e.value)
    message = str(e.value)
    assert message.startswith(name + ":"), message
    assert "\n" not in message
    return message


@pytest.mark.parametrize("value", [8.5, 8.0, "8", None, 8j, [8], True])
def test_size_of_wrong_type_is_a_type_error(sky, value):
    raises(TypeError, "size", sky.convert, "cube", size=value)
    raises(TypeError, "size", sky.resize, value)
    raises(TypeError, "size", envkit.EnvMap.blank, value)
    raises(TypeError, "size", envkit.bake, sky, size=value)
    raises(TypeError, "size", envkit.irradiance, sky, size=value)
    raises(TypeError, "size", envkit.prefilter, sky, size=value)
    raises(TypeError, "size", envkit.dfg_lut, value)
    raises(TypeError, "size", envkit.merge, [sky], size=value)


@pytest.mark.parametrize("value", [-1, 1 << 40, -(1 << 70), 1 << 70])
def test_size_out_of_range_is_a_value_error(sky, value):
    raises(ValueError, "size", sky.convert, "cube", size=value)
    raises(ValueError, "size", sky.resize, value)
    raises(ValueError, "size", envkit.EnvMap.blank, value)
    raises(ValueError, "size", envkit.bake, sky, size=value)
    raises(ValueError, "size", envkit.irradiance, sky, size=value)
    raises(ValueError, "size", envkit.dfg_lut, value)
    raises(ValueError, "size", envkit.probes.default().rasterize, "latlong", value)


def test_numpy_integers_are_integers(sky):
    assert sky.convert("cube", size=np.int64(8)).width == 8
    assert envkit.EnvMap.blank(np.uint8(4), channels=np.int32(1)).data.shape == (4, 8, 1)


def test_counts_and_other_integers(sky):
    raises(ValueError, "channels", envkit.EnvMap.blank, 4, channels=5)
    raises(TypeError, "channels", envkit.EnvMap.blank, 4, channels=2.5)
    raises(ValueError, "levels", envkit.prefilter, sky, size=8, levels=99)
    raises(ValueError, "order", envkit.sh, sky, order=17)
    raises(TypeError, "nside", sky.convert, "healpix", nside=2.0)
    raises(ValueError, "resolution", envkit.bake, sky, resolution=(0, 8))
    raises(TypeError, "resolution", envkit.bake, sky, resolution=8)
    raises(ValueError, "n_theta", envkit.probes.checker, 0, 4)
    raises(ValueError, "seed", envkit.probes.outdoor, seed=-1)
    raises(TypeError, "accuracy", envkit.irradiance, sky, size=8, accuracy="high")
    raises(ValueError, "accuracy", envkit.irradiance, sky, size=8, accuracy=float("nan"))
    raises(ValueError, "aspect", sky.convert, "perspective", size=8, aspect=float("inf"))


def test_complex_arrays_are_refused(sky):
    a = np.ones((8, 16, 3), np.complex64)
    raises(TypeError, "array", envkit.EnvMap, a)
    raises(TypeError, "directions", sky.lookup, np.ones((4, 3), np.complex128))
    raises(TypeError, "u", envkit.bake(sky).sample, np.full((4, 2), 0.5 + 0.5j))
    raises(TypeError, "radiance", envkit.probes.constant, np.array([1, 2, 3], np.complex64))
    raises(TypeError, "array", envkit.EnvMap, np.array([["a", "b"]]))
    raises(TypeError, "array", envkit.EnvMap, None)


def test_array_shape_and_values_are_value_errors(sky):
    raises(ValueError, "array", envkit.EnvMap, np.zeros((8, 16, 5), np.float32))
    raises(ValueError, "array", envkit.EnvMap, np.zeros(8, np.float32))
    bad = np.ones((8, 16, 3), np.float32)
    bad[1, 2, 0] = np.nan
    assert "1 non-finite" in raises(ValueError, "array", envkit.EnvMap, bad)
    raises(ValueError, "directions", sky.lookup, np.zeros((4, 2)))
    raises(ValueError, "directions", sky.lookup, np.zeros((4, 3)))  # zero directions


def test_strided_views_are_accepted():
    base = np.random.default_rng(1).random((64, 256, 4), dtype=np.float32)
    view = base[::2, ::4, :3]  # non-contiguous float32
    assert not view.flags["C_CONTIGUOUS"]
    m = envkit.EnvMap(view)
    assert np.array_equal(m.data, view)
    # Fortran order, byte-swapped and integer arrays are real numbers too.
    assert np.array_equal(envkit.EnvMap(np.asfortranarray(view)).data, view)
    assert np.array_equal(envkit.EnvMap(view.astype(">f4")).data, view)
    assert np.array_equal(envkit.EnvMap(np.ones((8, 16, 3), np.uint16)).data, np.ones((8, 16, 3), np.float32))
    dirs = np.tile(np.array([0.0, 1.0, 0.0]), (10, 2))[:, ::2][:, :3]
    assert m.lookup(np.ascontiguousarray(dirs)).shape == (10, 3)


def test_a_huge_broadcast_view_is_refused_by_size_not_dtype():
    view = np.broadcast_to(np.float32(1.0), (1 << 16, 1 << 17, 3))
    message = raises(ValueError, "array", envkit.EnvMap, view)
    assert "texels" in message or "GiB" in message


# Oversized requests: refused at once with the size and what it needs, never MemoryError('std::bad_alloc').
def test_oversized_convert(sky):
    message = raises(ValueError, "size", sky.convert, "latlong", size=131072)
    assert "262144 x 131072" in message


def test_oversized_blank_and_resize(sky):
    assert "2097152 x 1048576" in raises(ValueError, "size", envkit.EnvMap.blank, 1 << 20)
    raises(ValueError, "size", sky.resize, 1 << 20)


def test_oversized_bake(sky):
    assert "131072 x 65536" in raises(ValueError, "size", envkit.bake, sky, size=65536)


def test_oversized_ibl(sky):
    message = raises(ValueError, "size", envkit.irradiance, sky, size=4096)
    assert "more than 512" in message and "irradiance" in message
    assert "more than 1024" in raises(ValueError, "size", envkit.dfg_lut, 4096)
    assert "more than 4096" in raises(ValueError, "size", envkit.prefilter, sky, size=8192)


def available_gib():
    with open("/proc/meminfo") as f:
        info = dict(line.split(":", 1) for line in f)
    return (int(info["MemAvailable"].split()[0]) + int(info.get("SwapFree", "0 kB").split()[0])) / (1 << 20)


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
@pytest.mark.skipif(available_gib() > 25, reason="a 16384^2 render (about 28 GiB) would fit in memory here")
def test_oversized_render(tmp_path):
    assert "16384 x 16384" in raises(ValueError, "width, height", envkit.render, width=16384, height=16384)
    with open(os.path.join(HERE, "..", "..", "renderer", "scenes", "default.json")) as f:
        scene = json.load(f)
    scene["camera"]["resolution"] = [16384, 16384]
    message = raises(ValueError, "scene", envkit.render, scene)
    assert "camera.resolution" in message and "16384 x 16384" in message and "GiB" in message
