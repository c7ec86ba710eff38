"""Builds sdot's compiled module (sdot/_sdot*.so) with the project's CMake, for pip.

setuptools drives CMake here because Debian ships no scikit-build; everything comes from Debian's
packages (scripts/install-deps.sh). SDOT_CMAKE_ARGS adds arguments to the CMake configuration.
"""

import os
import shlex
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        target_dir = Path(self.get_ext_fullpath(ext.name)).resolve().parent
        build_dir = Path(self.build_temp).resolve() / "cmake"
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            "-DSDOT_BUILD_PYTHON=ON", "-DSDOT_BUILD_TESTS=OFF", "-DSDOT_BUILD_CLI=OFF", "-DSDOT_BUILD_EXAMPLES=OFF",
            f"-DPython_EXECUTABLE={sys.executable}",
            f"-DSDOT_PYTHON_PACKAGE_DIR={target_dir}",
            *shlex.split(os.environ.get("SDOT_CMAKE_ARGS", "")),
        ]
        subprocess.run(configure, check=True)
        jobs = str(os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "sdot_python", "-j", jobs], check=True)


setup(ext_modules=[CMakeExtension("sdot._sdot")], cmdclass={"build_ext": CMakeBuild})
