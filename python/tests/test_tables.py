"""Tables: baking equals envbake, sample/pdf/invert bit-identical to the C++ (envsample's CSV), any shape."""
import csv
import math

import numpy as np
import pytest

import envkit
from conftest import run_tool


@pytest.fixture(scope="module")
def baked(probe_dir, tmp_path_factory):
    d = tmp_path_factory.mktemp("tables")
    path = d / "sky.envtbl"
    run_tool("envbake", probe_dir / "sky.exr", "-o", path, "--tables", "cdf,alias,hierarchical,compensated", "-q")
    return path


def read_csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    u = np.array([[float(r["u0"]), float(r["u1"])] for r in rows])
    d = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])
    pdf = np.array([float(r["pdf"]) for r in rows])
    tex = np.array([[int(r["texel_x"]), int(r["texel_y"])] for r in rows])
    return u, d, pdf, tex


@pytest.mark.parametrize("method", ["cdf", "alias", "hierarchical"])
@pytest.mark.parametrize("compensated", [False, True])
def test_sample_equals_envsample(baked, tmp_path, method, compensated):
    out = tmp_path / "s.csv"
    args = ["-n", "3000", "--method", method, "--sequence", "random", "--seed", "3", "-o", out, "-q"]
    run_tool("envsample", baked, *args + (["--compensated"] if compensated else []))
    u, d_cli, pdf_cli, tex_cli = read_csv(out)  # 17 significant digits: the doubles round-trip exactly
    t = envkit.load(str(baked))
    d, pdf, tex = t.sample(u, method=method, compensated=compensated)
    assert np.array_equal(d, d_cli)
    assert np.array_equal(pdf, pdf_cli)
    assert np.array_equal(tex, tex_cli)
    # pdf(direction) is the sampled density (the C++ contract), bit for bit.
    assert np.array_equal(t.pdf(d, method=method, compensated=compensated), pdf)
    if method != "alias":
        uu = t.invert(d, method=method, compensated=compensated)
        d2, _, _ = t.sample(uu, method=method, compensated=compensated)
        assert np.allclose(d2, d, atol=1e-9)
    else:
        with pytest.raises(envkit.Error, match="cannot be inverted"):
            t.invert(d, method="alias")


@pytest.mark.parametrize("grid,size", [("latlong", 64), ("latlong", 1024), ("octahedral", 64), ("healpix", 16)])
def test_batched_sample_equals_scalar(probe_dir, grid, size):
    # Tables.sample runs the batched C++ sample(); batched=False calls the one-sample sample() per element. Bit for
    # bit equal for every method, at lengths around the batch's group size, at u on the edges of [0, 1) and above
    # the parallel threshold (oneTBB chunks).
    t = envkit.bake(envkit.EnvMap(str(probe_dir / "sky.exr")), grid=grid, size=size,
                    tables=["cdf", "alias", "hierarchical", "compensated"])
    edges = [0.0, 0.5, 1.0 - 2.0**-24, np.nextafter(1.0, 0.0), 1.0, -0.5, 2.0]
    u = np.concatenate([np.array([[a, b] for a in edges for b in edges]),
                        np.random.default_rng(4).random((20000, 2))])
    for method in ("cdf", "alias", "hierarchical"):
        for compensated in (False, True):
            for n in (0, 1, 31, 32, 33, 1000, len(u)):
                a = t.sample(u[:n], method=method, compensated=compensated)
                b = t.sample(u[:n], method=method, compensated=compensated, batched=False)
                for x, y in zip(a, b):
                    assert x.shape == y.shape and np.array_equal(x, y), (method, compensated, n)
            # One call per sample (the C++ scalar call per element) equals the batched array too.
            d, pdf, tex = t.sample(u[:200], method=method, compensated=compensated)
            for k in range(0, 200, 7):
                d1, pdf1, tex1 = t.sample(u[k], method=method, compensated=compensated, batched=False)
                assert np.array_equal(d1, d[k]) and pdf1 == pdf[k] and np.array_equal(tex1, tex[k])


def test_bake_equals_envbake(probe_dir, baked, tmp_path):
    m = envkit.EnvMap(str(probe_dir / "sky.exr"))
    t = envkit.bake(m, tables=["cdf", "alias", "hierarchical", "compensated"])
    cli = envkit.load(str(baked))
    assert t.source_hash == cli.source_hash == envkit.file_content_hash(str(probe_dir / "sky.exr"))
    assert np.array_equal(t.importance, cli.importance)
    assert t.total_importance == cli.total_importance
    u = np.random.default_rng(1).random((5000, 2))
    for method in ("cdf", "alias", "hierarchical"):
        a, b = t.sample(u, method=method), cli.sample(u, method=method)
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
    t.save(str(tmp_path / "py.envtbl"))
    again = envkit.load(str(tmp_path / "py.envtbl"), expected_source_hash=t.source_hash)
    assert np.array_equal(again.sample(u)[0], t.sample(u)[0])
    with pytest.raises(envkit.Error, match="py.envtbl"):
        envkit.load(str(tmp_path / "py.envtbl"), expected_source_hash="0" * 32)


def test_healpix_bake_equals_envbake(probe_dir, tmp_path):
    # size is N_side for HEALPix, as envbake --size: 4N x 3N texels.
    cli_path = tmp_path / "hp.envtbl"
    run_tool("envbake", probe_dir / "sky.exr", "-o", cli_path, "--param", "healpix", "--size", "8", "-q")
    t = envkit.bake(envkit.EnvMap(str(probe_dir / "sky.exr")), grid="healpix", size=8)
    cli = envkit.load(str(cli_path))
    assert (t.grid, t.width, t.height) == ("healpix", 32, 24) == (cli.grid, cli.width, cli.height)
    assert np.array_equal(t.importance, cli.importance)
    u = np.random.default_rng(2).random((2000, 2))
    d, pdf, tex = t.sample(u, method="hierarchical")
    assert np.all(pdf > 0)
    assert np.array_equal(d, cli.sample(u, method="hierarchical")[0])
    with pytest.raises(ValueError, match="^resolution: .*4 N_side x 3 N_side"):
        envkit.bake(envkit.EnvMap(str(probe_dir / "sky.exr")), grid="healpix", resolution=(16, 16))


def test_shapes_and_large_arrays(baked):
    t = envkit.load(str(baked))
    u = np.random.default_rng(2).random((70000, 2))  # parallel path
    d, pdf, tex = t.sample(u)
    # The same computation one by one (the serial path) gives the same bits.
    for k in (0, 12345, 69999):
        dk, pk, tk = t.sample(u[k])
        assert dk.shape == (3,) and pk.shape == () and np.array_equal(dk, d[k]) and pk == pdf[k]
    grid = u.reshape(7, 10000, 2)
    d3, p3, t3 = t.sample(grid)
    assert d3.shape == (7, 10000, 3) and p3.shape == (7, 10000) and t3.shape == (7, 10000, 2)
    assert np.array_equal(d3.reshape(-1, 3), d)
    assert t.sample(np.zeros((0, 2)))[0].shape == (0, 3)
    out = (np.empty((70000, 3)), np.empty(70000), np.empty((70000, 2), np.int32))
    filled = t.sample(u, out=out)
    assert all(f is o for f, o in zip(filled, out))
    assert np.array_equal(out[0], d) and np.array_equal(out[1], pdf) and np.array_equal(out[2], tex)
    with pytest.raises(envkit.Error, match="out pdf"):
        t.sample(u, out=(out[0], np.empty(5), out[2]))
    with pytest.raises(envkit.Error, match="wrong dtype"):
        t.sample(u, out=(out[0], out[1], np.empty((70000, 2))))
    with pytest.raises(ValueError, match=r"^u: .*\(\.\.\., 2\)"):
        t.sample(np.zeros((4, 3)))
    # The density integrates to 1: it is constant per texel of the bake grid, so sum(pdf(centre) x Omega) = 1.
    grid_map = envkit.EnvMap(np.zeros((t.height, t.width, 1), np.float32), parameterization="latlong")
    total = np.sum(t.pdf(grid_map.directions()) * grid_map.solid_angles())
    assert total == pytest.approx(1.0, rel=1e-9)
    assert t.pdf(np.zeros(3)) == 0.0


def test_importance_view(baked):
    t = envkit.load(str(baked))
    imp = t.importance
    assert imp.shape == (t.height, t.width) and imp.dtype == np.float32
    assert not imp.flags.writeable
    assert "cdf" in t.methods() and "hierarchical-compensated" in t.methods()
