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

# A python3 first on PATH that is another interpreter (pyenv's, say) sees neither Debian's site
# folders nor its NumPy. When it is the same Python version (same extension ABI), a .pth file in
# its site folder appends Debian's folders to its path (its own packages keep precedence), so
# that `python3 -c "import spacewarp"` works there too; otherwise say what to do.
other=$(command -v python3 || true)
if [ -n "$other" ] && ! (cd / && python3 -c "import spacewarp" > /dev/null 2>&1); then
  version() { "$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])'; }
  pth=""
  if [ "$(version python3)" = "$(version "$python")" ] && [ -z "${SPACEWARP_NO_PTH:-}" ]; then
    other_site=$(python3 -c 'import site; print(site.getsitepackages()[0])')
    pth="$other_site/spacewarp-debian-site.pth"
    "$python" -c 'import site, sysconfig; print(sysconfig.get_path("platlib")); print("\n".join(p for p in site.getsitepackages() if p.startswith("/usr/lib")))' > "$pth" 2> /dev/null || pth=""
  fi
  if [ -n "$pth" ] && (cd / && python3 -c "import spacewarp" > /dev/null 2>&1); then
    echo "install-python: python3 on PATH ($(python3 -c 'import sys; print(sys.executable)')) sees Debian's site folders through $pth"
  else
    [ -n "$pth" ] && rm -f "$pth"
    echo "install-python: note: 'python3' on PATH ($other) cannot import spacewarp; use $python," \
         "or build for that interpreter: pip install --no-build-isolation ." >&2
  fi
fi
