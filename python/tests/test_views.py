"""Camera views, HEALPix and merging from Python against envconvert and envmerge, bit for bit."""
import json

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool


def cli_convert(src, out, *args):
    run_tool("envconvert", src, "-o", out, "-q", *args)
    return exr_array(out)


def test_perspective_crop_equals_envconvert(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    sky = envkit.EnvMap(str(src))
    expected = cli_convert(src, tmp_path / "v.exr", "--to", "perspective", "--view-dir", "30,10", "--fov", "60",
                           "--roll", "5", "--aspect", "1.5", "--size", "96")
    py = sky.convert("perspective", size=96, view_dir=(30, 10), fov=60, roll=5, aspect=1.5)
    assert py.data.shape == expected.shape == (64, 96, 3)
    assert np.array_equal(py.data, expected)
    # size=(w, h) is --size w --aspect w/h; the view is what the written file records.
    assert np.array_equal(sky.convert("perspective", size=(96, 64), view_dir=(30, 10), fov=60, roll=5).data, expected)
    assert envkit.EnvMap(str(tmp_path / "v.exr")).view == py.view
    # A vertical field of view and a direction as x, y, z; a point filter.
    expected = cli_convert(src, tmp_path / "w.exr", "--to", "perspective", "--view-dir", "0.3,-0.2,-1", "--fov",
                           "40", "--fov-axis", "v", "--size", "48", "--filter", "bilinear")
    py = sky.convert("perspective", size=48, view_dir=[0.3, -0.2, -1], fov=40, fov_axis="v", filter="bilinear")
    assert np.array_equal(py.data, expected)


@pytest.mark.parametrize("lens,fov", [("equisolid", 180), ("stereographic", 120), ("equidistant", 360)])
def test_fisheye_crop_equals_envconvert(probe_dir, tmp_path, lens, fov):
    src = probe_dir / "sky.exr"
    expected = cli_convert(src, tmp_path / "f.exr", "--to", "fisheye", "--lens", lens, "--fov", fov, "--view-dir",
                           "0,90", "--size", "64")
    py = envkit.EnvMap(str(src)).convert("fisheye", lens=lens, fov=fov, view_dir=(0, 90), size=64)
    assert np.array_equal(py.data, expected)
    assert py.view["lens"] == lens and py.view["fov"] == fov


def test_fisheye_default_fov_is_envconverts(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    expected = cli_convert(src, tmp_path / "f.exr", "--to", "fisheye", "--size", "32")
    py = envkit.EnvMap(str(src)).convert("fisheye", size=32)
    assert py.view["fov"] == 180 and np.array_equal(py.data, expected)


def test_healpix_equals_envconvert(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    expected = cli_convert(src, tmp_path / "h.exr", "--to", "healpix", "--size", "16")
    py = envkit.EnvMap(str(src)).convert("healpix", nside=16)
    assert py.data.shape == (48, 64, 3)
    assert np.array_equal(py.data, expected)
    omega = py.solid_angles()
    assert np.allclose(omega, 4 * np.pi / (12 * 16 * 16), rtol=1e-12)  # equal-area pixels
    back = cli_convert(tmp_path / "h.exr", tmp_path / "b.exr", "--to", "latlong", "--from", "healpix", "--size", "24")
    assert np.array_equal(py.convert("latlong", size=24).data, back)


def test_embedding_a_view_gives_coverage_alpha(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    crop = envkit.EnvMap(str(src)).convert("perspective", size=64, view_dir=(-40, 20), fov=70)
    crop.write(str(tmp_path / "crop.exr"))
    expected = cli_convert(tmp_path / "crop.exr", tmp_path / "ll.exr", "--to", "latlong", "--size", "48")
    embedded = envkit.EnvMap.from_array(crop.data, "perspective", view=crop.view).convert("latlong", size=48)
    assert embedded.channels == ["R", "G", "B", "A"]
    assert np.array_equal(embedded.data, expected)
    alpha = embedded.data[..., 3]
    assert alpha.max() == 1.0 and alpha.min() == 0.0  # seen, and not seen (no black light)
    # The view given as options, as envconvert --from perspective --view-dir ... --fov ...
    arr = crop.data.copy()
    explicit = cli_convert(tmp_path / "crop.exr", tmp_path / "ll2.exr", "--to", "latlong", "--size", "48", "--from",
                           "perspective", "--view-dir", "-40,20", "--fov", "70", "--roll", "0")
    m = envkit.EnvMap(arr, "perspective", view=dict(view_dir=(-40, 20), fov=70, roll=0))
    assert np.array_equal(m.convert("latlong", size=48).data, explicit)


def test_merge_equals_envmerge(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    f0, f1 = str(tmp_path / "f0.exr"), str(tmp_path / "f1.exr")
    run_tool("envconvert", src, "-o", f0, "-q", "--to", "fisheye", "--lens", "equisolid", "--fov", "190", "--size",
             "48")
    run_tool("envconvert", src, "-o", f1, "-q", "--to", "fisheye", "--lens", "equisolid", "--fov", "190", "--size",
             "48", "--view-dir", "180,0")
    out = tmp_path / "m.exr"
    cli = json.loads(run_tool("envmerge", f0, f1 + "@exposure=2", "-o", out, "--size", "24", "--json", "-q").stdout)
    merged, report = envkit.merge([envkit.EnvMap(f0), dict(map=envkit.EnvMap(f1), exposure=2)], size=24)
    assert np.array_equal(merged.data, exr_array(out))
    for k in ("uncovered_sr", "uncovered_percent", "captures"):
        assert report[k] == cli[k], k
    merged.write(str(tmp_path / "py.exr"))
    assert np.array_equal(exr_array(tmp_path / "py.exr"), exr_array(out))
    with pytest.raises(ValueError, match="^exposure: must be positive"):
        envkit.merge([dict(map=envkit.EnvMap(f0), exposure=0)])


def test_view_errors_carry_the_cli_message(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    p = run_tool("envconvert", src, "-o", tmp_path / "o.exr", "--to", "perspective", "--fov", "200", check=False)
    assert p.returncode == 2
    sky = envkit.EnvMap(str(src))
    with pytest.raises(envkit.Error) as e:
        sky.convert("perspective", fov=200)
    # A usage error names the option first: "--fov/--lens: <libenv's message>"; Python raises libenv's message.
    assert "--fov/--lens: " + str(e.value) in p.stderr.splitlines(), (p.stderr, str(e.value))
    with pytest.raises(envkit.Error, match="describe a camera view"):
        sky.convert("cube", fov=60)
    with pytest.raises(envkit.Error, match="describes a camera view"):
        envkit.EnvMap(sky.data, "latlong", view=dict(fov=60))
    with pytest.raises(envkit.Error, match="not x,y,z"):
        sky.convert("perspective", view_dir=(0, 0, 0))
    with pytest.raises(ValueError, match="^nside: "):
        sky.convert("latlong", nside=4)


@pytest.mark.parametrize("kind", ["perspective", "fisheye"])
def test_vanishing_fields_of_view_are_refused_not_black(probe_dir, kind):
    sky = envkit.EnvMap(str(probe_dir / "sky.exr"))
    for fov in (1e-20, 0.0, float("nan")):
        with pytest.raises((envkit.Error, ValueError), match="field of view|fov"):
            sky.convert(kind, size=8, fov=fov)
    narrowest = sky.convert(kind, size=8, fov=1e-6).data
    assert np.all(narrowest[3:5, 3:5, :3] > 0), "the narrowest accepted view sees the sky"


def test_view_size_from_the_texel_density_is_envconverts(probe_dir, tmp_path):
    src = probe_dir / "sky.exr"
    expected = cli_convert(src, tmp_path / "v.exr", "--to", "perspective", "--fov", "50", "--aspect", "2")
    py = envkit.EnvMap(str(src)).convert("perspective", fov=50, aspect=2)
    assert py.data.shape == expected.shape and np.array_equal(py.data, expected)


def test_mirror_ball_photograph_equals_envconvert(probe_dir, tmp_path):
    ball = envkit.EnvMap(str(probe_dir / "sky.exr")).convert("mirrorball", size=40)
    photo = np.zeros((52, 104, 3), np.float32)  # the ball off centre in a larger photograph
    photo[7:47, 33:73] = ball.data[..., :3]
    # Written as a 2:1 image (the writer refuses a ball map it could not read back without the ball's options);
    # --from mirrorball overrides its metadata.
    envkit.EnvMap(photo, "latlong").write(str(tmp_path / "photo.exr"))
    expected = cli_convert(tmp_path / "photo.exr", tmp_path / "ll.exr", "--to", "latlong", "--size", "20", "--from",
                           "mirrorball", "--ball-centre", "53,27", "--ball-radius", "20")
    py = envkit.EnvMap(photo, "mirrorball", ball_centre=(53, 27), ball_radius=20).convert("latlong", size=20)
    assert np.array_equal(py.data, expected)
    inscribed = envkit.EnvMap(photo[7:47, 33:73], "mirrorball").convert("latlong", size=20)
    # The same ball cut out (up to rounding of the shifted coordinates): the centre and radius were used.
    assert np.allclose(py.data, inscribed.data, rtol=1e-3, atol=1e-5)
    with pytest.raises(envkit.Error, match="mirror-ball photograph"):
        envkit.EnvMap(photo, "latlong", ball_radius=20)
