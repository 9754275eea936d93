"""Python-side manners: every bound type prints what it is, and refusals raise the built-in kinds Python users
catch (ValueError for bad values, OSError for files, TypeError for wrong types), still as envkit.Error."""

import os

import numpy as np
import pytest

import envkit


@pytest.fixture(scope="module")
def sky():
    return envkit.probes.gradient([0.1] * 3, [1.0] * 3).rasterize("latlong", 16)


def test_every_bound_type_has_a_repr(sky):
    objects = {
        "EnvMap": sky,
        "Tables": envkit.bake(sky, tables=["cdf"]),
        "PrefilteredChain": sky.prefilter(size=8, levels=2),
        "Probe": envkit.probes.constant([1, 1, 1]),
        "_RenderJob": envkit._envkit._RenderJob(None, None, "", None, "hierarchical", "power", None, None, 1, 1, 0.0,
                                                8, 4, False),
    }
    irr = sky.irradiance(size=4)
    for name, obj in list(objects.items()) + [("PrefilteredChain", irr)]:
        text = repr(obj)
        assert text.startswith("<envkit.") and name in text, text
        assert " object at 0x" not in text
    assert "latlong 32x16" in repr(objects["Tables"]) and "cdf" in repr(objects["Tables"])
    assert "2 GGX levels" in repr(objects["PrefilteredChain"]) and "irradiance" in repr(irr)
    assert "8x4, auto" in repr(objects["_RenderJob"])
    # Every class the module binds is covered above.
    classes = {n for n in dir(envkit._envkit) if isinstance(getattr(envkit._envkit, n), type)
               and not issubclass(getattr(envkit._envkit, n), BaseException)}
    classes |= {n for n in dir(envkit.probes) if isinstance(getattr(envkit.probes, n), type)}
    assert classes <= set(objects), classes - set(objects)


def test_exception_hierarchy():
    assert issubclass(envkit.ArgumentError, ValueError) and issubclass(envkit.ArgumentError, envkit.Error)
    assert issubclass(envkit.FileError, OSError) and issubclass(envkit.FileError, envkit.Error)
    assert issubclass(envkit.ConversionError, envkit.ArgumentError)
    assert issubclass(envkit.Error, RuntimeError)


@pytest.mark.parametrize(
    "call",
    [
        lambda m: envkit.EnvMap.blank(4, "nope"),
        lambda m: m.convert("nope"),
        lambda m: m.convert("cube", convention="nope"),
        lambda m: m.convert("cube", layout="diagonal"),
        lambda m: m.convert("latlong", filter="sinc"),
        lambda m: m.convert("latlong", rotate="a,b,c"),
        lambda m: m.convert("fisheye", lens="pinhole"),
        lambda m: m.lookup(np.array([[0, 0, 1.0]]), filter="area"),
        lambda m: m.diff(m, metric="nope"),
        lambda m: envkit.bake(m, importance="nope"),
        lambda m: envkit.bake(m, tables=["nope"]),
        lambda m: m.prefilter(size=8, mapping="nope"),
        lambda m: m.sh(2, window="nope"),
        lambda m: envkit.EnvMap(np.zeros((4, 8, 3), np.float32), "latlong", view=dict(fov=10)),
        lambda m: envkit.probes.gradient([0.1] * 3, [1] * 3, form="cubic"),
    ],
)
def test_bad_values_are_value_errors(sky, call):
    with pytest.raises(ValueError) as info:
        call(sky)
    assert isinstance(info.value, envkit.Error)


def test_files_are_os_errors(tmp_path, sky):
    missing = str(tmp_path / "missing.exr")
    corrupt = tmp_path / "corrupt.exr"
    corrupt.write_bytes(b"v/1\x01 this is no OpenEXR file" * 4)
    for call in (
        lambda: envkit.EnvMap(missing),
        lambda: envkit.EnvMap(str(corrupt)),
        lambda: envkit.read_image(missing),
        lambda: envkit.read_image(str(corrupt)),
        lambda: envkit.load(str(tmp_path / "missing.envtbl")),
        lambda: envkit.load(str(corrupt)),
        lambda: sky.write(str(tmp_path / "no" / "such" / "dir" / "out.exr")),
        lambda: envkit.bake(sky, tables=["cdf"]).save(str(tmp_path / "no" / "dir" / "t.envtbl")),
        lambda: sky.prefilter(size=8, levels=1).write(str(tmp_path / "no" / "dir" / "c.ktx2")),
    ):
        with pytest.raises(OSError) as info:
            call()
        assert isinstance(info.value, envkit.Error)
        assert str(tmp_path) in str(info.value) or "corrupt" in str(info.value), str(info.value)
    if os.geteuid() != 0:
        unreadable = tmp_path / "unreadable.exr"
        sky.write(str(unreadable))
        unreadable.chmod(0)
        with pytest.raises(OSError):
            envkit.EnvMap(str(unreadable))


@pytest.mark.parametrize(
    "call",
    [
        lambda m: m.convert("cube", size=8.5),
        lambda m: m.convert("perspective", view="x" and 5),
        lambda m: m.lookup("north"),
        lambda m: envkit.merge([5]),
        lambda m: m.blur("sharp"),
        lambda m: m.hemisphere("up"),
        lambda m: envkit.EnvMap(np.zeros((4, 8, 3), complex)),
        lambda m: envkit.EnvMap.from_faces(np.zeros((6, 4, 4, 3))),
    ],
)
def test_wrong_types_are_type_errors(sky, call):
    with pytest.raises(TypeError):
        call(sky)
