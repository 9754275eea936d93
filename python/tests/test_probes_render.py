"""Probes and rendering against envprobe and envrender (bit for bit) and closed forms."""
import math

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool


@pytest.mark.parametrize("param,convention", [("latlong", "envkit"), ("cube", "gl"), ("mirrorball", "envkit")])
def test_sun_equals_envprobe(tmp_path, param, convention):
    out = tmp_path / "sun.exr"
    run_tool("envprobe", "sun", "-o", out, "--param", param, "--size", "32", "--convention", convention,
             "--direction", "0.3,0.8,0.5", "--radius-deg", "2", "--radiance", "100,80,60", "--sky", "0.5")
    probe = envkit.probes.sun([0.3, 0.8, 0.5], 2.0, [100, 80, 60], [0.5] * 3)
    m = probe.rasterize(param, 32, convention=convention)
    assert np.array_equal(m.data, exr_array(out))


def test_closed_forms():
    c = envkit.probes.constant([1.0, 2.0, 3.0])
    assert c.total_power() == pytest.approx((4 * math.pi, 8 * math.pi, 12 * math.pi))
    assert c.upward_irradiance() == pytest.approx((math.pi, 2 * math.pi, 3 * math.pi))
    m = c.rasterize("octahedral", 16)
    assert np.allclose(m.power(), c.total_power(), rtol=1e-12)
    sun = envkit.probes.sun([0, 1, 0], 0.5, [1e5] * 3, [0.0] * 3)
    for kind in ("latlong", "cube", "paraboloid"):
        assert np.allclose(sun.rasterize(kind, 16).power()[:3], sun.total_power(), rtol=1e-7)  # float32 texels
    g = envkit.probes.gradient([0.1] * 3, [1.0] * 3, form="quadratic")
    assert np.allclose(g.radiance(np.array([[0, 1.0, 0], [1.0, 0, 0]])), [[1.1] * 3, [0.1] * 3])
    assert envkit.probes.default().power_is_closed_form is False
    with pytest.raises(envkit.Error, match="form"):
        envkit.probes.gradient([0.1] * 3, [1.0] * 3, form="cubic")


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
def test_render_equals_envrender(tmp_path):
    out = tmp_path / "r.exr"
    run_tool("envrender", "-o", out, "--resolution", "24x16", "--spp", "2", "--seed", "5", "-q")
    img = envkit.render(width=24, height=16, spp=2, seed=5)
    assert img.shape == (16, 24, 3) and img.dtype == np.float32
    assert np.array_equal(img, exr_array(out)[..., :3])


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
def test_render_sun_samples_equal_envrender(tmp_path):
    # The default scene's probe has a sun: sun_samples=0 samples it as one table, 2 apart from the rest; both are
    # envrender's images bit for bit, and differ from each other (the sampling differs, not the integral).
    imgs = []
    for n in ("0", "2"):
        out = tmp_path / ("r%s.exr" % n)
        run_tool("envrender", "-o", out, "--resolution", "24x16", "--spp", "2", "--seed", "5", "--sun-samples", n, "-q")
        img = envkit.render(width=24, height=16, spp=2, seed=5, sun_samples=int(n))
        assert np.array_equal(img, exr_array(out)[..., :3])
        imgs.append(img)
    assert not np.array_equal(imgs[0], imgs[1])


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
def test_render_regularize_equals_envrender(tmp_path):
    # Two bounces, the unbiased setting and the default (glossy spheres widened after the ground's bounce): each is
    # envrender's image bit for bit, and the two differ; a negative value is refused.
    common = ["--resolution", "24x16", "--spp", "2", "--seed", "5", "--max-depth", "3", "-q"]
    run_tool("envrender", "-o", tmp_path / "unbiased.exr", "--regularize", "0", *common)
    run_tool("envrender", "-o", tmp_path / "default.exr", *common)
    unbiased = envkit.render(width=24, height=16, spp=2, seed=5, max_depth=3, regularize=0.0)
    default = envkit.render(width=24, height=16, spp=2, seed=5, max_depth=3)
    assert np.array_equal(unbiased, exr_array(tmp_path / "unbiased.exr")[..., :3])
    assert np.array_equal(default, exr_array(tmp_path / "default.exr")[..., :3])
    assert not np.array_equal(default, unbiased)
    explicit = envkit.render(width=24, height=16, spp=2, seed=5, max_depth=3,
                             regularize=envkit._envkit.default_regularize)
    assert np.array_equal(default, explicit)
    with pytest.raises(ValueError, match="regularize"):
        envkit.render(width=8, height=4, spp=1, regularize=-1)


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
def test_render_scene_dict(tmp_path):
    import json
    import os

    here = os.path.dirname(os.path.abspath(__file__))
    scenes = os.path.join(here, "..", "..", "renderer", "scenes")
    path = os.path.join(scenes, "default.json")
    with open(path) as f:
        scene = json.load(f)
    a = envkit.render(path, width=12, height=8, spp=1)
    b = envkit.render(scene, width=12, height=8, spp=1, base_dir=scenes)
    assert np.array_equal(a, b)
    scene["shapes"] = "oops"
    with pytest.raises(envkit.Error, match="shapes"):
        envkit.render(scene, base_dir=scenes)
