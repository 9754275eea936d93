"""Prefiltering, irradiance, spherical harmonics and the DFG LUT from Python against envprefilter, bit for bit."""
import filecmp
import json

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool


@pytest.mark.parametrize(
    "cli,py",
    [
        ([], {}),
        (["--octahedral", "--mapping", "filament", "--levels", "3"], dict(octahedral=True, mapping="filament", levels=3)),
        (["--rotate", "90,0,0", "--accuracy", "0.5", "--mapping", "unreal"], dict(rotate="90,0,0", accuracy=0.5,
                                                                                  mapping="unreal")),
    ],
)
def test_prefilter_levels_equal_envprefilter_exr(probe_dir, tmp_path, cli, py):
    src = probe_dir / "sky.exr"
    run_tool("envprefilter", src, "-o", tmp_path / "cli%.exr", "--size", "16", "-q", *cli)
    chain = envkit.EnvMap(str(src)).prefilter(size=16, **py)
    assert len(chain) == py.get("levels", 5)
    for m, level in enumerate(chain):
        expected = exr_array(tmp_path / ("cli%d.exr" % m))
        assert level.shape == expected.shape
        assert np.array_equal(level, expected), m
    if "mapping" not in py:  # gltf: r_m = m / (M - 1)
        assert chain.roughness == pytest.approx([m / 4 for m in range(5)], abs=1e-15)
    assert chain.alpha[0] == 0 and np.allclose(chain.alpha[1:], np.square(chain.roughness[1:]))  # level 0: a mirror
    # The chain's own EXR files carry envprefilter's metadata too.
    chain.write(str(tmp_path / "py%.exr"))
    for m in range(len(chain)):
        a = envkit.EnvMap(str(tmp_path / ("py%d.exr" % m)))
        b = envkit.EnvMap(str(tmp_path / ("cli%d.exr" % m)))
        assert a.metadata == b.metadata
        assert np.array_equal(a.data, b.data)


@pytest.mark.parametrize("name,fmt", [("a.ktx2", "rgba16f"), ("b.ktx2", "rgb9e5"), ("c.dds", "rgba32f")])
def test_prefilter_gpu_files_equal_envprefilter(probe_dir, tmp_path, name, fmt):
    src = probe_dir / "sky.exr"
    run_tool("envprefilter", src, "-o", tmp_path / ("cli_" + name), "--size", "16", "--format", fmt, "-q")
    envkit.prefilter(envkit.EnvMap(str(src)), size=16).write(str(tmp_path / ("py_" + name)), format=fmt)
    assert filecmp.cmp(tmp_path / ("cli_" + name), tmp_path / ("py_" + name), shallow=False)


def test_chain_arrays_are_views(probe_dir):
    chain = envkit.EnvMap(str(probe_dir / "sun.exr")).prefilter(size=8)
    a, b = chain[0], chain.levels[0]
    assert np.shares_memory(a, b) and a.dtype == np.float32 and a.shape == (48, 8, 3)
    assert chain[-1].shape == (6, 1, 3)
    before = a.copy()
    del chain
    # The view keeps the chain alive: its memory is not handed to the next chains.
    others = [envkit.EnvMap(str(probe_dir / "sky.exr")).prefilter(size=8) for _ in range(3)]
    assert np.array_equal(a, before) and len(others) == 3
    with pytest.raises(IndexError):
        envkit.EnvMap(str(probe_dir / "sun.exr")).prefilter(size=4)[3]


def test_irradiance_equals_envprefilter(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    run_tool("envprefilter", src, "--irradiance", tmp_path / "irr.exr", "--irradiance-size", "8", "-q")
    irr = envkit.irradiance(envkit.EnvMap(str(src)), size=8)
    assert np.array_equal(irr[0], exr_array(tmp_path / "irr.exr"))
    run_tool("envprefilter", src, "--irradiance", tmp_path / "irr.ktx2", "--irradiance-size", "8", "-q")
    irr.write(str(tmp_path / "py.ktx2"))
    assert filecmp.cmp(tmp_path / "irr.ktx2", tmp_path / "py.ktx2", shallow=False)
    e = envkit.irradiance(envkit.EnvMap(str(src)), size=8, divide_by_pi=False)
    assert np.allclose(e[0], irr[0] * np.pi, rtol=1e-6)


@pytest.mark.parametrize("order,window", [(2, "none"), (3, "hanning"), (1, "lanczos")])
def test_sh_equals_envprefilter_json(probe_dir, tmp_path, order, window):
    src = probe_dir / "sky.exr"
    run_tool("envprefilter", src, "--sh", tmp_path / "sh.json", "--sh-order", order, "--sh-window", window, "-q")
    j = json.load(open(tmp_path / "sh.json"))
    sky = envkit.EnvMap(str(src))

    def columns(section):
        return np.array([j[section]["coefficients"][c] for c in j["channels"]]).T

    rad = sky.sh(order)
    assert rad.shape == ((order + 1) ** 2, 3)
    assert np.array_equal(rad, columns("radiance"))
    assert np.array_equal(sky.sh(order, kind="irradiance", window=window), columns("irradiance"))
    assert np.array_equal(envkit.sh(sky, order, "irradiance", lambertian=True, window=window),
                          columns("irradiance_over_pi"))
    with pytest.raises(envkit.Error, match="irradiance"):
        sky.sh(order, lambertian=True)


def test_sh_of_a_constant_map():
    m = envkit.EnvMap(np.full((32, 64, 3), 2.0, np.float32), "latlong")
    c = m.sh(2)
    # L_00 = 2 * integral of Y_00 = 2 sqrt(4 pi); the other bands vanish up to the texel-centre quadrature's error.
    assert np.allclose(c[0], 2 * np.sqrt(4 * np.pi), rtol=1e-6)
    assert np.abs(c[1:]).max() < 1e-3 * c[0, 0]
    with pytest.raises(ValueError, match="^order: "):
        m.sh(17)


@pytest.mark.parametrize("layout", ["scale-bias", "filament"])
def test_dfg_lut_equals_envprefilter(probe_dir, tmp_path, layout):
    run_tool("envprefilter", probe_dir / "sun.exr", "--lut", tmp_path / "lut.exr", "--lut-size", "24", "--lut-layout",
             layout, "-q")
    lut = envkit.dfg_lut(24, layout)
    assert lut.shape == (24, 24, 3) and lut.dtype == np.float32
    assert np.array_equal(lut, exr_array(tmp_path / "lut.exr"))


def test_prefilter_errors_carry_the_cli_message(probe_dir, tmp_path):
    src = probe_dir / "sun.exr"
    target = tmp_path / "missing" / "x.ktx2"
    p = run_tool("envprefilter", src, "-o", target, "--size", "8", check=False)
    assert p.returncode == 1
    line = p.stderr.strip().splitlines()[-1]
    chain = envkit.EnvMap(str(src)).prefilter(size=8)
    with pytest.raises(envkit.Error) as e:
        chain.write(str(target))
    assert line == "envprefilter: " + str(e.value)
    with pytest.raises(envkit.Error, match="expected a .ktx2, .dds or .exr"):
        chain.write(str(tmp_path / "x.png"))
    # One mip-mapped OpenEXR cube holds OpenEXR's faces: a chain prefiltered for GL faces is refused, not resampled.
    with pytest.raises(envkit.Error, match="prefiltered into GL faces"):
        chain.write(str(tmp_path / "x.exr"))
    assert not any(tmp_path.iterdir()), "a failed write leaves no file"


def test_mip_mapped_exr_cube_equals_envprefilter(probe_dir, tmp_path):
    src = probe_dir / "sun.exr"
    run_tool("envprefilter", src, "-o", tmp_path / "cli.exr", "--size", "8", "-q")
    target = tmp_path / "py.exr"
    envkit.EnvMap(str(src)).prefilter(size=8, for_path=str(target)).write(str(target))
    assert (tmp_path / "cli.exr").read_bytes() == target.read_bytes()
