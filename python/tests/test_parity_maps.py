"""skylibs' EnvironmentMap calls on envkit.EnvMap (docs/PYTHON.md, "Parity"): each checked against a computation
that does not go through the method under test (numpy on directions() / solid_angles(), or a closed form)."""

import numpy as np
import pytest

import envkit


def smooth_map(n=16, kind="latlong", channels=3):
    """A map of `kind` whose texels hold smooth functions of their direction (one per channel)."""
    m = envkit.EnvMap.blank(n, kind, channels=channels)
    d = m.directions()
    fields = [1.0 + d[..., 0], 1.5 + d[..., 1] * d[..., 2], 2.0 + d[..., 1], 0.5 + 0.25 * d[..., 2]]
    for c in range(channels):
        m.data[..., c] = fields[c]
    return m


def test_image_coordinates_are_texel_centres_in_unit_square():
    m = envkit.EnvMap.blank(4, "latlong")
    u, v = m.image_coordinates()
    assert u.shape == v.shape == (4, 8)
    np.testing.assert_allclose(u[0], (np.arange(8) + 0.5) / 8)
    np.testing.assert_allclose(v[:, 0], (np.arange(4) + 0.5) / 4)
    # The same positions texel_of gives for the texels' own directions, divided by the image size.
    pos = m.texel_of(m.directions())
    np.testing.assert_allclose(pos[..., 0] / 8, u, atol=1e-12)
    np.testing.assert_allclose(pos[..., 1] / 4, v, atol=1e-12)


def test_set_background_fills_texels_without_data_only():
    ball = envkit.EnvMap.blank(16, "mirrorball")
    ball.data[...] = 0.25
    out = ball.set_background([1.0, 2.0, 3.0])
    assert out is ball
    outside = ball.solid_angles() == 0
    dirs_zero = np.all(ball.directions() == 0, axis=-1)
    assert outside.any() and (~outside).any()
    np.testing.assert_array_equal(ball.data[dirs_zero], np.tile([1.0, 2.0, 3.0], (dirs_zero.sum(), 1)))
    np.testing.assert_array_equal(ball.data[~dirs_zero], 0.25)


def test_set_background_fills_uncovered_alpha_and_keeps_alpha():
    view = envkit.EnvMap.from_array(np.ones((8, 8, 3), np.float32), "perspective", view=dict(fov=60))
    ll = view.convert("latlong", size=16)
    alpha = ll.data[..., 3].copy()
    ll.set_background(0.5)
    uncovered = alpha == 0
    assert uncovered.any()
    np.testing.assert_array_equal(ll.data[uncovered][:, :3], 0.5)
    np.testing.assert_array_equal(ll.data[..., 3], alpha)


def test_set_background_refuses_wrong_value_count():
    with pytest.raises(ValueError, match="color"):
        envkit.EnvMap.blank(4, "mirrorball").set_background([1, 2])


@pytest.mark.parametrize(
    "mode,weights",
    [("bt709", (0.2126, 0.7152, 0.0722)), ("bt601", (0.299, 0.587, 0.114)), ("mean", (1 / 3, 1 / 3, 1 / 3)),
     ("ITU BT.601", (0.299, 0.587, 0.114))],
)
def test_intensity_modes(mode, weights):
    m = smooth_map()
    y = m.intensity(mode)
    assert y.data.shape == m.data.shape[:2] + (1,)
    assert y.channels == ["Y"] and y.parameterization == "latlong"
    np.testing.assert_allclose(y.data[..., 0], m.data @ np.array(weights), rtol=2e-4)


def test_intensity_keeps_alpha_and_refuses_unknown_mode():
    m = smooth_map(channels=4)
    y = m.intensity("mean")
    assert y.channels == ["Y", "A"]
    np.testing.assert_array_equal(y.data[..., 1], m.data[..., 3])
    np.testing.assert_allclose(y.data[..., 0], m.data[..., :3].mean(-1), rtol=1e-6)
    with pytest.raises(ValueError, match="mode"):
        m.intensity("bt2020x")


@pytest.mark.parametrize("kind", ["latlong", "cube", "mirrorball"])
def test_hemisphere_mask_and_value(kind):
    m = smooth_map(8, kind)
    n = np.array([0.3, 0.8, -0.2])
    mask = m.hemisphere(n)
    d = m.directions()
    expected = (d @ (n / np.linalg.norm(n)) > 0) & np.any(d != 0, axis=-1)
    np.testing.assert_array_equal(mask, expected)
    before = m.data.copy()
    assert m.set_hemisphere(n, [7, 8, 9]) is m
    np.testing.assert_array_equal(m.data[mask], np.tile([7, 8, 9], (mask.sum(), 1)))
    np.testing.assert_array_equal(m.data[~mask], before[~mask])
    with pytest.raises(ValueError, match="normal"):
        m.hemisphere([0, 0, 0])


def test_mean_light_vectors_against_numpy_and_closed_form():
    m = smooth_map(32)
    normals = np.array([[0, 1, 0], [1, 0, 0], [0.2, -0.5, 0.7]], float)
    got = m.mean_light_vectors(normals)
    assert got.shape == (3, 3)
    d, omega = m.directions(), m.solid_angles()
    y = m.data.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    for k, n in enumerate(normals):
        vis = d @ n > 0
        ref = (d * (y * omega * vis)[..., None]).sum((0, 1)) / omega.sum()
        np.testing.assert_allclose(got[k], ref, rtol=1e-3, atol=1e-9)
    # Constant radiance 1: (1 / 4 pi) times the integral of d over the hemisphere (pi n) is n / 4.
    one = envkit.EnvMap.blank(64, "latlong")
    one.data[...] = 1.0
    np.testing.assert_allclose(one.mean_light_vectors([0.0, 1.0, 0.0]), [0, 0.25, 0], atol=2e-4)
    with pytest.raises(ValueError, match="normals"):
        one.mean_light_vectors([[0.0, 0.0, 0.0]])


def vmf_direct(m, kappa):
    """The normalised von Mises-Fisher convolution of a map, texel by texel with numpy."""
    d = m.directions().reshape(-1, 3)
    omega = m.solid_angles().reshape(-1)
    data = m.data.reshape(-1, m.data.shape[-1]).astype(np.float64)
    w = np.exp(kappa * (d @ d.T - 1.0)) * omega[None, :]
    return (w @ data / w.sum(1, keepdims=True)).reshape(m.data.shape)


@pytest.mark.parametrize("kind,kappa", [("latlong", 4.0), ("latlong", 40.0), ("cube", 10.0), ("octahedral", 0.0)])
def test_blur_matches_direct_convolution(kind, kappa):
    m = smooth_map(8, kind)
    rng = np.random.default_rng(1)
    m.data[...] += rng.random(m.data.shape).astype(np.float32)
    np.testing.assert_allclose(m.blur(kappa).data, vmf_direct(m, kappa), rtol=2e-5, atol=1e-6)


def test_blur_of_a_band_one_function_scales_by_the_vmf_coefficient():
    # Funk-Hecke: the vMF convolution of a degree-1 harmonic is coth(k) - 1/k times it.
    m = envkit.EnvMap.blank(64, "latlong", channels=1)
    d = m.directions()
    m.data[..., 0] = d[..., 2]
    kappa = 5.0
    a1 = 1.0 / np.tanh(kappa) - 1.0 / kappa
    np.testing.assert_allclose(m.blur(kappa).data[..., 0], a1 * d[..., 2], atol=3e-3)
    with pytest.raises(ValueError, match="kappa"):
        m.blur(-1.0)


def test_c2e_any_aspect_ratio():
    cube = smooth_map(16, "cube")
    ll = cube.convert("latlong", size=(48, 16))
    assert ll.data.shape == (16, 48, 3) and ll.parameterization == "latlong"
    np.testing.assert_allclose(ll.solid_angles().sum(), 4 * np.pi, rtol=1e-9)
    # Smooth content: a wide map sees what the cube shows in each texel's direction.
    ref = cube.lookup(ll.directions(), filter="bilinear")
    np.testing.assert_allclose(ll.data, ref, atol=0.06)
    assert abs(ll.power()[0] / cube.power()[0] - 1) < 1e-3
