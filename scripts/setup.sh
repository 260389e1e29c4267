#!/usr/bin/env bash
# Set up evedge on a fresh Debian machine: system libraries for offscreen
# rendering (EGL + Mesa llvmpipe), a virtual environment in .venv, the project
# and its dependencies. Idempotent; re-run after changing pyproject.toml.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() {  # run a command as root, or return 1 when we cannot
  if [ "$(id -u)" = "0" ]; then sh -c "$1"
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then sudo sh -c "$1"
  else return 1; fi
}

DEBS="libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libxrender1"
missing=""
if command -v dpkg-query >/dev/null 2>&1; then
  for pkg in $DEBS; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing="$missing $pkg"
  done
fi
if [ -n "$missing" ]; then
  cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends$missing"
  echo "setup: Debian packages for offscreen rendering are missing:$missing"
  if ! as_root "$cmd"; then
    echo "setup: cannot install them (not root, no sudo)" >&2
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
  if ! "$PY" -c 'import ensurepip, venv' 2>/dev/null; then
    venv_cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends python3-venv"
    echo "setup: Python's venv module is missing; installing python3-venv"
    as_root "$venv_cmd" || { echo "setup: not root; run as root:  $venv_cmd" >&2; exit 1; }
  fi
  "$PY" -m venv .venv || { rm -rf .venv; echo "setup: '$PY -m venv .venv' failed" >&2; exit 1; }
fi
stamp=.venv/.evedge-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e '.[test]'
  touch "$stamp"
fi
echo "setup: ready (.venv)"
