#!/usr/bin/env bash
# Sets up everything cpp_mujoco needs on a fresh Debian/Ubuntu machine; safe to run again.
#   - system libraries for offscreen OpenGL (EGL and OSMesa), when run as root
#   - chromium (headless), when run as root: tests/test_report.py opens the results page in it
#   - a virtual environment in .venv with the package, its pinned dependencies, dev tools, Ray and
#     the documentation site's tools (mkdocs), installed by uv (pip where uv cannot be had)
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(libegl1 libgl1 libosmesa6 libglx-mesa0)
# optional: a failed install (Ubuntu's chromium is a snap stub) only skips the page test
OPTIONAL_APT_PACKAGES=(chromium)
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  missing=()
  for pkg in "${APT_PACKAGES[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
  optional=()
  for pkg in "${OPTIONAL_APT_PACKAGES[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || optional+=("$pkg")
  done
  if [ ${#optional[@]} -gt 0 ]; then
    echo "setup: installing ${optional[*]} (optional)"
    { [ ${#missing[@]} -gt 0 ] || apt-get update -qq; } &&
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        "${optional[@]}" >/dev/null ||
      echo "setup: could not install ${optional[*]}; tests/test_report.py will skip" >&2
  fi
else
  echo "setup: not root; make sure ${APT_PACKAGES[*]} are installed for offscreen rendering" >&2
  echo "setup: and chromium, for tests/test_report.py (it skips without it)" >&2
fi

PYTHON=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
# torch first, pinned: the CPU build; any other spec pulls gigabytes of CUDA packages
.venv/bin/python -m pip install -q --disable-pip-version-check torch==2.13.0
# ray: the optional distributed engine, installed here so its tests run; docs: the site CI builds;
# site: the site command's shapely, pyproj and pymavlink, installed so its tests run.
# uv resolves and installs the same releases as pip in a twentieth of the time (measured: 10 s
# against 160 s); it keeps the torch above, and pip does the work where uv cannot be had.
EXTRAS=".[dev,ray,docs,site]"
if .venv/bin/python -m pip install -q --disable-pip-version-check uv==0.13.9 &&
  .venv/bin/uv pip install -q --python .venv/bin/python -e "$EXTRAS"; then
  :
else
  echo "setup: uv unavailable; installing with pip" >&2
  .venv/bin/python -m pip install -q --disable-pip-version-check -e "$EXTRAS"
fi
echo "setup: ready (.venv)"
