#!/usr/bin/env bash
# Set up evedge on a fresh Debian machine: system libraries for offscreen
# rendering (EGL + Mesa llvmpipe), a virtual environment in .venv, the project
# and its dependencies. Idempotent; re-run after changing pyproject.toml.
set -euo pipefail
cd "$(dirname "$0")/.."

DEBS="libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libxrender1"
missing=""
if command -v dpkg-query >/dev/null 2>&1; then
  for pkg in $DEBS; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing="$missing $pkg"
  done
fi
if [ -n "$missing" ]; then
  cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends$missing"
  if [ "$(id -u)" = "0" ]; then
    echo "setup: installing Debian packages for offscreen rendering:$missing"
    sh -c "$cmd"
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    echo "setup: installing Debian packages for offscreen rendering (sudo):$missing"
    sudo sh -c "$cmd"
  else
    echo "setup: these Debian packages are missing and I am not root:$missing" >&2
    echo "setup: run as root:  $cmd" >&2
    echo "setup: continuing; 3-D rendering will fail until they are installed." >&2
  fi
fi

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  echo "setup: evedge needs Python 3.11 or newer; $PY is $("$PY" --version 2>&1)" >&2
  exit 1
fi
if [ ! -x .venv/bin/python ]; then
  if ! "$PY" -m venv .venv; then
    echo "setup: '$PY -m venv' failed; on Debian install it with: apt-get install -y python3-venv" >&2
    exit 1
  fi
fi
stamp=.venv/.evedge-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e '.[test]'
  touch "$stamp"
fi
echo "setup: ready (.venv)"
