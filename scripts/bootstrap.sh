#!/usr/bin/env bash
# Set up the project venv (.venv): ROS 2 Jazzy from PyPI wheels, the libraries, and this package.
# Idempotent: a re-run with unchanged requirements only checks a stamp and returns in well under a second.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${PLANTER_VENV:-.venv}
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

stamp="$VENV/.planter-stamp"
want=$(cat requirements.txt setup.py setup.cfg package.xml scripts/bootstrap.sh | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "bootstrap: installing requirements into $VENV (first run takes about a minute)" >&2
  # (this workplace's pip config warns about every missing local index folder: filter that noise)
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r requirements.txt \
    2> >(grep -v 'is ignored: it is neither a file nor a directory' >&2)
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps --use-pep517 -e . \
    2> >(grep -v 'is ignored: it is neither a file nor a directory' >&2)
  echo "$want" > "$stamp"
fi
# the README's commands run these console scripts from the venv
for exe in planter design_node sync_node monitor_node; do
  if [ ! -x "$VENV/bin/$exe" ]; then
    echo "bootstrap: $VENV/bin/$exe is missing after the install (delete $VENV and re-run)" >&2
    exit 1
  fi
done
