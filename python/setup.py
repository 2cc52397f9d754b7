"""Builds the mlclust package from this repository: `pip install --no-build-isolation ./python`.

The pure-Python modules are python/mlclust/*.py. What is built is the CMake target
mlclust_python (python/CMakeLists.txt): the gRPC stubs (mlclust/v1), the Draco helper
library (libmlclust_draco_c.so), _version.py and the mlclust binary that Client() with no
address starts (bin/mlclust). They are built in MLCLUST_BUILD_DIR (default: the repository's
build/, configured here when it is not yet) and copied into the wheel; nothing is fetched.
MLCLUST_BUILD_JOBS sets the build's parallelism (default: every core); MLCLUST_SOURCE_DIR
names the repository when this folder is a copy.
"""

import os
import re
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = os.path.dirname(os.path.abspath(__file__))
# The repository: this folder's parent, or MLCLUST_SOURCE_DIR for a copy of python/ made
# elsewhere (the install test builds such a copy, so nothing is written into the checkout).
REPOSITORY = os.path.abspath(os.environ.get("MLCLUST_SOURCE_DIR") or os.path.dirname(HERE))


def project_version():
    """The VERSION of CMakeLists.txt's project(): the one source of the version number."""
    with open(os.path.join(REPOSITORY, "CMakeLists.txt")) as f:
        match = re.search(r"project\(\s*mlclust\s+VERSION\s+([0-9][0-9.]*)", f.read())
    if match is None:
        raise RuntimeError(f"no project(mlclust VERSION ...) in {REPOSITORY}/CMakeLists.txt")
    return match.group(1)


def cache_value(build_dir, name):
    with open(os.path.join(build_dir, "CMakeCache.txt")) as f:
        for line in f:
            if line.startswith(name + ":"):
                return line.split("=", 1)[1].strip()
    return None


def build_package(build_dir):
    """Configures (when needed) and builds mlclust_python; returns the built package folder."""
    if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
        generator = ["-G", "Ninja"] if shutil.which("ninja") else []
        subprocess.check_call(["cmake", "-S", REPOSITORY, "-B", build_dir, *generator,
                               "-DCMAKE_BUILD_TYPE=Release", "-DMLCLUST_WITH_SERVER=ON"])
    home = cache_value(build_dir, "CMAKE_HOME_DIRECTORY")
    if home is None or os.path.realpath(home) != os.path.realpath(REPOSITORY):
        raise RuntimeError(f"MLCLUST_BUILD_DIR {build_dir} is the build of {home}, not of "
                           f"{REPOSITORY}: give this checkout's build folder")
    if cache_value(build_dir, "MLCLUST_WITH_SERVER") not in ("ON", "1", "TRUE"):
        raise RuntimeError(f"{build_dir} was configured with MLCLUST_WITH_SERVER=OFF; the "
                           "package needs the server (reconfigure with -DMLCLUST_WITH_SERVER=ON)")
    jobs = os.environ.get("MLCLUST_BUILD_JOBS") or str(os.cpu_count() or 1)
    subprocess.check_call(["cmake", "--build", build_dir, "--target", "mlclust_python",
                           "-j", jobs])
    return os.path.join(build_dir, "python", "mlclust")


class BuildPyWithCMake(build_py):
    """build_py, then the built files of mlclust_python beside the modules."""

    def run(self):
        super().run()
        build_dir = os.path.abspath(os.environ.get("MLCLUST_BUILD_DIR")
                                    or os.path.join(REPOSITORY, "build"))
        built = build_package(build_dir)
        target = os.path.join(self.build_lib, "mlclust")
        for name in ("v1", "bin"):
            shutil.rmtree(os.path.join(target, name), ignore_errors=True)
            # Links followed: bin/mlclust is a link to the build's binary.
            shutil.copytree(os.path.join(built, name), os.path.join(target, name),
                            ignore=shutil.ignore_patterns("__pycache__"))
        for name in ("libmlclust_draco_c.so", "_version.py"):
            shutil.copy2(os.path.join(built, name), os.path.join(target, name))


class BinaryDistribution(Distribution):
    """A platform wheel: it holds a shared library and an executable."""

    def has_ext_modules(self):
        return True


setup(version=project_version(), packages=["mlclust"], distclass=BinaryDistribution,
      cmdclass={"build_py": BuildPyWithCMake}, zip_safe=False)
