"""envkit for Python: environment maps, sampling tables, probes and rendering (docs/PYTHON.md).

    import envkit
    sky = envkit.EnvMap("sky.exr")                  # float32 H x W x C in sky.data (no copy)
    cube = sky.convert("cube", size=512)            # envconvert sky.exr -o ... --to cube --size 512
    tables = envkit.bake(sky)                       # envbake
    dirs, pdf, texels = tables.sample(u)            # u: (N, 2) in [0, 1)
    view = sky.convert("perspective", size=(640, 480), view_dir=(30, 10), fov=60)   # envconvert --to perspective
    chain = sky.prefilter(size=256)                 # envprefilter: GGX mip chain, chain.write("sky.ktx2")

Use Debian's interpreter, /usr/bin/python3: numpy (python3-numpy) is installed there; or install the package into a
venv made from it with --system-site-packages (pip install --no-build-isolation .; docs/PYTHON.md).
"""

try:
    import numpy as _numpy  # noqa: F401  (the extension hands out numpy arrays)
except ImportError as _e:  # pragma: no cover - depends on the interpreter
    import sys as _sys

    raise ImportError(
        "envkit needs numpy, which this interpreter (%s) does not have; use Debian's /usr/bin/python3 "
        "(apt-get install python3-numpy) or a venv made from it (/usr/bin/python3 -m venv --system-site-packages), "
        "or pip install numpy into this one" % _sys.executable
    ) from _e

import json as _json
import os as _os

# An installed package (pip install .) carries libenv's modules next to the extension: point libenv at them, unless
# the environment already names others.
for _module, _variable in (("ocio", "ENVKIT_OCIO_MODULE"), ("oiio", "ENVKIT_OIIO_MODULE"),
                           ("healpix", "ENVKIT_HEALPIX_MODULE")):
    _path = _os.path.join(_os.path.dirname(__file__), "libenvkit_%s.so" % _module)
    if _os.path.exists(_path):
        _os.environ.setdefault(_variable, _path)

from . import _envkit
from ._envkit import (
    ArgumentError,
    ConversionError,
    EnvMap,
    Error,
    FileError,
    PrefilteredChain,
    Tables,
    conventions,
    dfg_lut,
    file_content_hash,
    irradiance,
    merge,
    prefilter,
    probes,
    read_image,
    sh,
    sh_reconstruct,
)

__all__ = [
    "ArgumentError",
    "ConversionError",
    "FileError",
    "EnvMap",
    "Error",
    "Tables",
    "bake",
    "PrefilteredChain",
    "conventions",
    "dfg_lut",
    "file_content_hash",
    "irradiance",
    "merge",
    "prefilter",
    "sh",
    "sh_reconstruct",
    "load",
    "probes",
    "read",
    "read_image",
    "render",
    "has_renderer",
]

has_renderer = _envkit.has_renderer

from . import _faces  # noqa: E402  (py360convert's 'list' / 'dict' cube formats, on EnvMap)

EnvMap.faces = _faces.faces
EnvMap.from_faces = staticmethod(_faces.from_faces)


def read(path, **kwargs):
    """Reads an environment map (EnvMap(path, ...))."""
    return EnvMap(path, **kwargs)


def bake(map, **kwargs):
    """Bakes sampling tables of an EnvMap in memory (Tables.bake; the options of envbake)."""
    return Tables.bake(map, **kwargs)


def load(path, expected_source_hash=""):
    """Loads a table file written by envbake or Tables.save (zero copy)."""
    return Tables.load(path, expected_source_hash)


def render(
    scene=None,
    *,
    spp=16,
    strategy=None,
    light_method="hierarchical",
    heuristic="power",
    bsdf_samples=None,
    light_samples=None,
    sun_samples=1,
    max_depth=1,
    seed=0,
    width=0,
    height=0,
    bake=False,
    crop=None,
    base_dir=None,
    regularize=None,
):
    """Renders a scene with envrender's integrator and returns the mean image (H x W x 3 float32).

    scene: None (the built-in default scene), a path to a JSON scene file (docs/SCENE_FORMAT.md), or a dict in
    that format (relative paths inside it are relative to base_dir, default the current directory). The other
    arguments are envrender's options (strategy None: envrender's default; bsdf_samples and light_samples None: by
    each material's lobe, as envrender without --bsdf-samples / --light-samples); crop = (x0, y0, x1, y1);
    regularize: envrender's --regularize (None: envrender's default; 0: unbiased; > 0 trades a bias for
    less noise when max_depth > 1).
    """
    if not has_renderer:
        raise Error("this envkit was built without the renderer (ENVKIT_BUILD_RENDERER=OFF)")
    path = text = None
    base = ""
    if isinstance(scene, dict):
        text = _json.dumps(scene)
        base = _os.path.join(base_dir or _os.getcwd(), "<scene dict>")
    elif scene is not None:
        path = _os.fspath(scene)
    return _envkit._render(
        path, text, base, spp, strategy, light_method, heuristic, bsdf_samples, light_samples, sun_samples,
        max_depth, seed, width, height, bake, crop, regularize,
    )
