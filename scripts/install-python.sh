#!/usr/bin/env bash
# Installs the Python package built in BUILD (cmake's "python" component) for PYTHON, then checks
# that PYTHON imports it. Usage: install-python.sh BUILD PYTHON
set -euo pipefail
build=${1:-build}
python=${2:-/usr/bin/python3}

if [ ! -d "$build/python/spacewarp" ]; then
  echo "install-python: $build has no Python package (configured without pybind11 or NumPy?)" >&2
  exit 1
fi
sudo=""
site=$(grep -E '^SPACEWARP_PYTHON_INSTALL_DIR:' "$build/CMakeCache.txt" | cut -d= -f2-)
if [ ! -w "$(dirname "$site")" ] && [ ! -w "$site" ] && [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
$sudo cmake --install "$build" --component python > /dev/null
(cd / && "$python" -c "import spacewarp; print('spacewarp', spacewarp.__version__, 'installed for $python in', spacewarp.__path__[0])")

# A python3 first on PATH that is another interpreter (pyenv, conda) does not see Debian's
# site folders, nor NumPy: say so once, rather than let `python3 -c "import spacewarp"` puzzle.
other=$(command -v python3 || true)
if [ -n "$other" ] && ! (cd / && python3 -c "import spacewarp" > /dev/null 2>&1); then
  echo "install-python: note: 'python3' on PATH ($other) is not $python and cannot import spacewarp;" \
       "use $python, or install with that interpreter: pip install --no-build-isolation ." >&2
fi
