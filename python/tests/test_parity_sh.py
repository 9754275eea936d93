"""Spherical harmonics of any order (EnvMap.sh) and their reconstruction into a map (envkit.sh_reconstruct),
against scipy's complex spherical harmonics turned into envkit's real basis (sh_basis.h: orthonormal, no
Condon-Shortley phase, polar axis z, azimuth from +x towards +y, index l (l + 1) + m, m < 0 the sine terms)."""

import numpy as np
import pytest

import envkit

scipy_special = pytest.importorskip("scipy.special")


def real_basis(lmax, d):
    """(..., (lmax + 1)^2) real SH at unit directions d (..., 3), from scipy.special.sph_harm."""
    polar = np.arccos(np.clip(d[..., 2], -1.0, 1.0))
    azimuth = np.arctan2(d[..., 1], d[..., 0])
    out = np.empty(d.shape[:-1] + ((lmax + 1) ** 2,))
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            y = scipy_special.sph_harm(abs(m), l, azimuth, polar)  # includes (-1)^m: removed below
            phase = (-1.0) ** abs(m)
            if m == 0:
                v = y.real
            elif m > 0:
                v = np.sqrt(2.0) * phase * y.real
            else:
                v = np.sqrt(2.0) * phase * y.imag
            out[..., l * (l + 1) + m] = v
    return out


@pytest.mark.parametrize("lmax", [1, 4, 8])
def test_reconstruction_is_the_scipy_basis_at_texel_centres(lmax):
    n = (lmax + 1) ** 2
    rng = np.random.default_rng(lmax)
    coeffs = rng.normal(size=(n, 3))
    m = envkit.sh_reconstruct(coeffs, 24, "latlong")
    assert m.data.shape == (24, 48, 3) and m.parameterization == "latlong"
    ref = real_basis(lmax, m.directions()) @ coeffs
    np.testing.assert_allclose(m.data, ref, rtol=1e-5, atol=1e-5)
    # Any kind: a cube of the same coefficients, and the truncation to fewer bands.
    cube = envkit.sh_reconstruct(coeffs[:, 0], 8, "cube", order=1)
    np.testing.assert_allclose(cube.data[..., 0], real_basis(1, cube.directions()) @ coeffs[:4, 0], atol=1e-5)


def test_projection_up_to_degree_8_against_scipy():
    # A band-limited map made from the scipy basis projects back onto its coefficients.
    lmax = 8
    rng = np.random.default_rng(7)
    coeffs = rng.normal(size=((lmax + 1) ** 2, 3))
    m = envkit.EnvMap.blank(256, "latlong", channels=3)
    m.data[...] = real_basis(lmax, m.directions()) @ coeffs
    got = m.sh(lmax)
    assert got.shape == ((lmax + 1) ** 2, 3)
    np.testing.assert_allclose(got, coeffs, atol=2e-3 * np.abs(coeffs).max())
    # Beyond the map's bands the coefficients vanish.
    higher = m.sh(10)
    np.testing.assert_allclose(higher[: (lmax + 1) ** 2], got, atol=1e-9)
    assert np.abs(higher[(lmax + 1) ** 2 :]).max() < 2e-3 * np.abs(coeffs).max()


def test_sh_round_trip_and_irradiance_reconstruction():
    sky = envkit.probes.gradient([0.1, 0.2, 0.3], [1.0, 0.8, 0.6]).rasterize("latlong", 64)
    c = sky.sh(6)
    back = envkit.sh_reconstruct(c, 64)
    np.testing.assert_allclose(back.sh(6), c, atol=1e-3)  # the projection's quadrature on 128 x 64 texels
    # Irradiance coefficients reconstruct E / pi, which a white Lambertian surface reflects: for a constant sky of
    # radiance 1 it is 1 everywhere.
    one = envkit.probes.constant([1.0, 1.0, 1.0]).rasterize("latlong", 32)
    e = envkit.sh_reconstruct(one.sh(4, kind="irradiance", lambertian=True), 8)
    np.testing.assert_allclose(e.data, 1.0, atol=1e-3)  # the higher bands hold the quadrature's error


def test_sh_refusals():
    m = envkit.EnvMap.blank(8)
    with pytest.raises(ValueError, match="order"):
        m.sh(17)
    with pytest.raises(ValueError, match="coeffs"):
        envkit.sh_reconstruct(np.zeros((5, 3)), 8)
    with pytest.raises(ValueError, match="coeffs"):
        envkit.sh_reconstruct(np.zeros((4, 2)), 8)
    with pytest.raises(ValueError, match="parameterization"):
        envkit.sh_reconstruct(np.zeros((4, 3)), 8, "perspective")
    with pytest.raises(TypeError):
        envkit.sh_reconstruct(np.zeros((4, 3)), 8.5)
