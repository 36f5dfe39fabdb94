"""The pip route to the Python package: `pip install --no-build-isolation .` configures and builds
the extension module with the project's own CMake (the same build as `make`), then installs the
package folder python/spacewarp with it. The README's set-up command is the other route."""

import os
import re
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


class CMakeExtension(Extension):
    def __init__(self, name: str) -> None:
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    """Builds spacewarp._spacewarp with CMake for the interpreter running pip."""

    def build_extension(self, ext: Extension) -> None:
        build = Path(self.build_temp).resolve() / "cmake"
        target = Path(self.get_ext_fullpath(ext.name)).resolve()
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), "-G", "Ninja",
                        "-DCMAKE_BUILD_TYPE=Release", f"-DPython3_EXECUTABLE={sys.executable}",
                        "-DSPACEWARP_WITH_PYTHON=ON", "-DSPACEWARP_BUILD_TESTS=OFF",
                        "-DSPACEWARP_BUILD_APPS=OFF", "-DSPACEWARP_BUILD_BENCHMARKS=OFF"], check=True)
        subprocess.run(["cmake", "--build", str(build), "--target", "_spacewarp", "-j", jobs], check=True)
        built = next((build / "python" / "spacewarp").glob("_spacewarp*.so"))
        target.parent.mkdir(parents=True, exist_ok=True)
        self.copy_file(str(built), str(target))


version = re.search(r"project\(spacewarp VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)

setup(
    name="spacewarp",
    version=version,
    description="Space deformations and cage coordinates: warps, mean-value, Green and harmonic coordinates, FFD, RBF",
    packages=["spacewarp"],
    package_dir={"": "python"},
    package_data={"spacewarp": ["py.typed", "*.pyi"]},
    ext_modules=[CMakeExtension("spacewarp._spacewarp")],
    cmdclass={"build_ext": CMakeBuild},
    python_requires=">=3.9",
    install_requires=["numpy"],
    zip_safe=False,
)
