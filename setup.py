"""Builds the extension envkit._envkit with the project's CMake build for `pip install .` (pyproject.toml).

CMake configures the whole project with tests and benchmarks off, builds only the extension and libenv's modules
(OpenColorIO, OpenImageIO, HEALPix: shared objects libenv opens on first need), and the wheel carries them next to
the extension, where envkit/__init__.py points libenv at them. The interpreter running pip is the one the module
is built for. Environment: CMAKE_ARGS (extra -D options, e.g. -DCMAKE_CXX_COMPILER_LAUNCHER=ccache), ENVKIT_JOBS
(parallel compile jobs, default all cores).
"""

import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent
# libenv's modules (libenv/CMakeLists.txt), built into <build>/lib.
MODULES = ("envkit_ocio", "envkit_oiio", "envkit_healpix")


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = Path(self.build_temp).resolve() / "cmake"
        build.mkdir(parents=True, exist_ok=True)
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build), "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
            "-DENVKIT_BUILD_TESTS=OFF", "-DENVKIT_BUILD_BENCHMARKS=OFF", "-DENVKIT_BUILD_PYTHON=ON",
            "-DPython_EXECUTABLE=" + sys.executable,
        ] + shlex.split(os.environ.get("CMAKE_ARGS", ""))
        subprocess.run(configure, check=True)
        jobs = os.environ.get("ENVKIT_JOBS", str(os.cpu_count() or 1))
        subprocess.run(["cmake", "--build", str(build), "-j", jobs, "--target", "_envkit", *MODULES], check=True)
        target = Path(self.get_ext_fullpath(ext.name)).resolve()
        target.parent.mkdir(parents=True, exist_ok=True)
        built = list((build / "python" / "envkit").glob("_envkit*.so"))
        if len(built) != 1:
            raise RuntimeError("setup.py: expected one _envkit*.so in %s, found %s" % (build, built))
        shutil.copy2(built[0], target)
        for module in MODULES:
            shutil.copy2(build / "lib" / ("lib%s.so" % module), target.parent / ("lib%s.so" % module))


setup(
    ext_modules=[CMakeExtension("envkit._envkit")],
    cmdclass={"build_ext": CMakeBuild},
    # Keep setuptools' own build tree out of the CMake build folders (build/, build-*/) the scripts use.
    options={"build": {"build_base": "build/pip"}},
)
