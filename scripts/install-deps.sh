#!/usr/bin/env bash
# Installs every Debian 12 package spacewarp needs to build, test, benchmark and fuzz.
# A quick no-op when all of them are present already.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libglm-dev libtbb-dev
  libtinyobjloader-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libtet1.5-dev
  libopenvdb-dev libboost-iostreams-dev
  libnanoflann-dev libxsimd-dev
  # CHOLMOD (the deformation graph's sparse Cholesky) and an optimised BLAS for its
  # supernodal kernels: with the reference BLAS CHOLMOD runs ~3x slower.
  libsuitesparse-dev libstb-dev libopenblas0-pthread
  clang libclang-rt-14-dev clang-format
  # The Python package (python/): pybind11 and NumPy for Debian's python3, pytest for its
  # tests, SciPy for sparse weight matrices, setuptools for `pip install --no-build-isolation .`
  python3-dev pybind11-dev python3-numpy python3-pytest python3-scipy python3-setuptools
  # spacewarp.dask (work spread over a Dask cluster): Dask, its distributed scheduler, zarr arrays
  python3-dask python3-distributed python3-zarr
  # The viewer's local server (spacewarp view): cpp-httplib
  libcpp-httplib-dev
  # The viewer's browser tests (tests/web): headless Chromium, driven by playwright-core from npm
  chromium
)
# The viewer page (web/) is built with npm: Debian's Node.js and npm unless a node is on PATH
# already (a newer one installed outside Debian's packages is kept).
if ! command -v node >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "Installing: ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
