"""Writers of range-limited formats warn from Python with the command-line tools' text when they clamp a value."""
import warnings

import numpy as np
import pytest

import envkit


def sun_map(value=1e6):
    pixels = np.full((16, 32, 3), 0.5, dtype=np.float32)
    pixels[4, 10, :] = value
    return envkit.EnvMap(pixels, parameterization="latlong")


def test_half_write_warns_with_count_and_largest(tmp_path):
    out = tmp_path / "sun.exr"
    with pytest.warns(UserWarning, match=r"sun\.exr: 3 values above half's largest 65504 were clamped "
                                         r"\(largest 1e\+06\); use a float output to keep the sun"):
        sun_map().write(str(out), half=True)
    assert out.exists()


def test_float_write_and_values_in_range_do_not_warn(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sun_map().write(str(tmp_path / "float.exr"))
        sun_map(1000.0).write(str(tmp_path / "half.exr"), half=True)


@pytest.mark.parametrize("fmt,largest", [("rgba16f", "65504"), ("rg11b10f", "65024"), ("rgb9e5", "65408")])
def test_ibl_write_warns_for_each_format_that_cannot_hold_the_sun(tmp_path, fmt, largest):
    irr = sun_map(1e8).irradiance(size=4)
    with pytest.warns(UserWarning, match=r"irr\.ktx2: [0-9]+ values? above %s's largest %s" % (fmt, largest)):
        irr.write(str(tmp_path / "irr.ktx2"), format=fmt)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        irr.write(str(tmp_path / "irr32.ktx2"), format="rgba32f")


def test_warning_as_error_leaves_the_file_written(tmp_path):
    # The warning comes after the write: an error raised from it cannot leave a partial file.
    out = tmp_path / "sun.exr"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning):
            sun_map().write(str(out), half=True)
    assert out.exists()
