#!/usr/bin/env bash
# Set up the project venv (.venv): ROS 2 Jazzy from PyPI wheels, the libraries, and this package.
# Idempotent: a re-run with unchanged requirements only checks a stamp and returns in well under a second.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${PLANTER_VENV:-.venv}
UV_VERSION=0.13.9
PY=${PYTHON:-python3}

if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info[:2] >= (3, 11) else 1)' 2>/dev/null; then
  echo "bootstrap: need Python >= 3.11 as '$PY' (set PYTHON=/path/to/python3.11)" >&2
  exit 2
fi
if [ ! -x "$VENV/bin/python" ]; then
  if ! "$PY" -m venv "$VENV" 2>/dev/null; then
    echo "bootstrap: '$PY -m venv' failed; on Debian run: sudo apt-get install python3-venv" >&2
    exit 2
  fi
fi

pip_quiet() {
  # (this workplace's pip config warns about every missing local index folder: filter that noise)
  "$VENV/bin/python" -m pip --quiet --disable-pip-version-check "$@" \
    2> >(grep -v 'is ignored: it is neither a file nor a directory' >&2)
}

# uv installs the same pinned wheels in ~15 s where pip takes ~50 s (byte code compiled at
# install, as pip does: where PYTHONDONTWRITEBYTECODE is set no process would cache it), with
# pip's own configuration (scripts/uv-pip-install). Any failure falls back to pip.
install_with_uv() {
  pip_quiet install "uv==$UV_VERSION" 2>/dev/null || return 1       # (no uv: pip, below)
  UV="$VENV/bin/uv" scripts/uv-pip-install "$VENV/bin/python" --compile-bytecode -r requirements.txt &&
    UV="$VENV/bin/uv" scripts/uv-pip-install "$VENV/bin/python" --no-deps -e .
}

stamp="$VENV/.planter-stamp"
want=$(cat requirements.txt setup.py setup.cfg package.xml scripts/bootstrap.sh scripts/uv-pip-install | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "bootstrap: installing requirements into $VENV" >&2
  if ! install_with_uv; then
    echo "bootstrap: uv could not install them; installing with pip (about a minute)" >&2
    pip_quiet install -r requirements.txt
    pip_quiet install --no-deps --use-pep517 -e .
  fi
  echo "$want" > "$stamp"
fi
# this package's own byte code, kept fresh on every run (0.1 s when nothing changed): where
# PYTHONDONTWRITEBYTECODE is set (CI, this workplace) Python would otherwise compile every
# module of it again in every process it starts (~0.13 s of CPU each; the tests start hundreds)
PYTHONDONTWRITEBYTECODE= "$VENV/bin/python" -m compileall -q -j 0 planter_ros >/dev/null
# the README's commands run these console scripts from the venv
for exe in planter design_node sync_node monitor_node; do
  if [ ! -x "$VENV/bin/$exe" ]; then
    echo "bootstrap: $VENV/bin/$exe is missing after the install (delete $VENV and re-run)" >&2
    exit 1
  fi
done
