"""Shared fixtures of the envkit pytest suites: where the CLIs are, and small inputs made by envprobe."""
import os
import subprocess

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
BUILD = os.environ.get("ENVKIT_BUILD", os.path.join(HERE, "..", "..", "build"))
BIN = os.environ.get("ENVKIT_BIN", os.path.join(BUILD, "bin"))


def tool(name):
    return os.path.join(BIN, name)


def run_tool(name, *args, check=True):
    """Runs a CLI; returns the CompletedProcess (text)."""
    p = subprocess.run([tool(name), *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError("%s failed (%d): %s" % (name, p.returncode, p.stderr))
    return p


def exr_array(path):
    """An EXR as a float32 array, read by envkit (the same reader the CLIs use)."""
    import envkit

    return np.asarray(envkit.read_image(str(path)))


@pytest.fixture(scope="session")
def probe_dir(tmp_path_factory):
    """Inputs: the default outdoor probe (a sun and a textured sky) at 256x128 and a sun probe at 128x64."""
    d = tmp_path_factory.mktemp("inputs")
    run_tool("envprobe", "default", "-o", d / "sky.exr", "--size", "256x128")
    run_tool("envprobe", "sun", "-o", d / "sun.exr", "--size", "128x64", "--radiance", "1e4", "--sky", "0.2")
    return d
