"""Property-based test of the module's argument handling (hypothesis): whatever is passed as an integer, size,
count or real argument, or as an array, the only exceptions are TypeError, ValueError or OSError naming that
argument: never RuntimeError (envkit.Error), MemoryError, another exception, or a crash of the interpreter."""
import math
import os
import tempfile

import numpy as np
import pytest

import envkit

hypothesis = pytest.importorskip("hypothesis")
# Hypothesis keeps caches under .hypothesis/ of the working directory (the source tree under CTest): not there.
import hypothesis.configuration  # noqa: E402
hypothesis.configuration.set_hypothesis_home_dir(tempfile.mkdtemp(prefix="envkit-hypothesis-"))
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402
import hypothesis.extra.numpy as hnp  # noqa: E402

# Derandomized: the suite runs the same examples every time (no flaky CTest); ENVKIT_HYPOTHESIS_RANDOM=1 explores
# new ones (then raise max_examples with ENVKIT_HYPOTHESIS_EXAMPLES).
RANDOM = os.environ.get("ENVKIT_HYPOTHESIS_RANDOM") == "1"
EXAMPLES = int(os.environ.get("ENVKIT_HYPOTHESIS_EXAMPLES", "60"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=not RANDOM,
                    suppress_health_check=list(HealthCheck))


@pytest.fixture(scope="module")
def sky():
    return envkit.probes.default().rasterize("latlong", 16)


@pytest.fixture(scope="module")
def tables(sky):
    return envkit.bake(sky, tables=["cdf", "alias", "hierarchical"])


def integers():
    """Values for an integer argument: small valid ones (cheap to compute), sizes that are valid integers but far
    too large to make, out-of-range and negative integers, and values of every other type."""
    return st.one_of(
        st.integers(min_value=0, max_value=6),
        st.sampled_from([65536, 131072, 1 << 20, 1 << 31, 1 << 40, 1 << 63, 1 << 64]),
        st.integers(min_value=1 << 21, max_value=1 << 90),
        st.integers(max_value=-1, min_value=-(1 << 90)),
        st.floats(allow_nan=True, allow_infinity=True),
        st.just(math.nan),
        st.text(max_size=4),
        st.none(),
        st.booleans(),
        st.complex_numbers(max_magnitude=10),
        st.lists(st.integers(0, 4), max_size=3),
        st.sampled_from([np.int64(3), np.uint8(2), np.float32(2.0), np.complex64(1)]),
    )


def reals():
    return st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(1 << 70), 1 << 70), st.text(max_size=3),
                     st.none(), st.complex_numbers(max_magnitude=10))


DTYPES = [np.float32, np.float64, np.float16, np.int32, np.uint8, np.int64, np.bool_, np.complex64, np.complex128,
          ">f4", "U2", object]


@st.composite
def arrays(draw, shapes):
    """Arrays of every kind of dtype, shapes around the expected ones, contiguous or strided."""
    dtype = np.dtype(draw(st.sampled_from(DTYPES)))
    shape = draw(shapes)
    if dtype.kind == "O":
        a = np.empty(shape, dtype=object)
        a.fill(draw(st.sampled_from([None, "x", 1.5])))
    else:
        elements = None
        if dtype.kind == "U":
            elements = st.text(alphabet="ab-", max_size=2)
        a = draw(hnp.arrays(dtype, shape, elements=elements))
    if draw(st.booleans()) and a.ndim >= 1 and a.shape[0] > 1:
        a = a[::2]  # a strided view
    return a


def image_shapes():
    return hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=9)


def vector_shapes(k):
    return st.one_of(hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=5),
                     st.tuples(st.integers(0, 7), st.just(k)))


def check(name, f, *args, **kwargs):
    """Calls f; an exception must be TypeError, ValueError or OSError (not an envkit.Error, which is a RuntimeError)
    whose message names `name`."""
    try:
        f(*args, **kwargs)
    except (TypeError, ValueError, OSError) as e:
        assert not isinstance(e, RuntimeError), "%s: %s" % (type(e).__name__, e)
        assert name in str(e), "%s does not name %s: %s" % (type(e).__name__, name, e)


@SETTINGS
@given(value=integers())
def test_size_arguments(sky, value):
    check("size", sky.convert, "cube", size=value)
    check("size", sky.convert, "latlong", size=value)
    check("size", sky.resize, value)
    check("size", envkit.EnvMap.blank, value)
    check("size", envkit.bake, sky, size=value)
    check("size", envkit.irradiance, sky, size=value)
    check("size", envkit.prefilter, sky, size=value)
    check("size", envkit.dfg_lut, value)
    check("size", envkit.merge, [sky], size=value)
    check("size", envkit.probes.constant([1, 1, 1]).rasterize, "octahedral", value)


@SETTINGS
@given(value=integers())
def test_count_arguments(sky, value):
    check("channels", envkit.EnvMap.blank, 4, channels=value)
    check("nside", sky.convert, "healpix", nside=value)
    check("levels", envkit.prefilter, sky, size=4, levels=value)
    check("order", envkit.sh, sky, order=value)
    check("n_theta", envkit.probes.checker, value, 4)
    check("seed", envkit.probes.outdoor, seed=value)
    check("resolution", envkit.bake, sky, resolution=(value, 8))
    check("resolution", envkit.bake, sky, resolution=value)


def render_integers():
    """integers() without the valid values that make a render slow (spp, sizes and depths in the thousands)."""
    return st.one_of(
        st.integers(min_value=0, max_value=2),
        st.integers(min_value=1 << 33, max_value=1 << 90),
        st.integers(max_value=-1, min_value=-(1 << 90)),
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=4),
        st.none(),
        st.booleans(),
        st.complex_numbers(max_magnitude=10),
        st.sampled_from([np.float32(2.0), np.complex64(1), [1, 2]]),
    )


@pytest.mark.skipif(not envkit.has_renderer, reason="built without the renderer")
@settings(max_examples=25, deadline=None, database=None, derandomize=not RANDOM,
          suppress_health_check=list(HealthCheck))
@given(value=render_integers(), which=st.sampled_from(["spp", "width", "height", "max_depth", "sun_samples",
                                                         "bsdf_samples", "seed"]))
def test_render_arguments(value, which):
    kwargs = {"spp": 1, "width": 4, "height": 2}
    kwargs[which] = value
    check(which, envkit.render, **kwargs)


@SETTINGS
@given(value=reals())
def test_real_arguments(sky, value):
    check("accuracy", envkit.irradiance, sky, size=4, accuracy=value)
    check("aspect", sky.convert, "perspective", size=4, aspect=value)


@SETTINGS
@given(array=arrays(image_shapes()))
def test_image_arrays(array):
    check("array", envkit.EnvMap, array)
    check("array", envkit.EnvMap, array, parameterization="octahedral")


@SETTINGS
@given(array=arrays(vector_shapes(3)))
def test_direction_arrays(sky, tables, array):
    check("directions", sky.lookup, array)
    check("directions", sky.texel_of, array)
    check("directions", tables.pdf, array)
    check("directions", tables.invert, array, method="cdf")
    check("directions", envkit.probes.default().radiance, array)
    check("colour_a", envkit.probes.checker, 2, 2, colour_a=array)


@SETTINGS
@given(array=arrays(vector_shapes(2)))
def test_sample_arrays(tables, array):
    for method in ("cdf", "alias", "hierarchical"):
        check("u", tables.sample, array, method=method)
