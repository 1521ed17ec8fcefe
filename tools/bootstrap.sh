#!/usr/bin/env bash
# Create or repair .venv with Python 3.13 and the pinned dependencies of requirements.txt,
# then install SSS Lab itself in editable mode. Safe to run again: it does nothing when the
# environment is complete and requirements.txt has not changed.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv
WANT=3.13
STAMP="$VENV/.sss_lab-installed"

fail() { echo "bootstrap: error: $*" >&2; exit 1; }

is_py313() {
  # A pyenv shim is on PATH even when its version is not active: run the candidate to be sure.
  [ -n "$1" ] && [ -x "$1" ] && "$1" -c "import sys; sys.exit(sys.version_info[:2] != (3, 13))" >/dev/null 2>&1
}

find_python() {
  local cand
  for cand in "${PYTHON313:-}" "$(command -v python$WANT || true)"; do
    is_py313 "$cand" && { echo "$cand"; return 0; }
  done
  if command -v pyenv >/dev/null 2>&1; then
    for cand in "$(pyenv root)"/versions/$WANT*/bin/python$WANT; do
      is_py313 "$cand" && { echo "$cand"; return 0; }
    done
  fi
  for cand in "$HOME"/.pyenv/versions/$WANT*/bin/python$WANT; do
    is_py313 "$cand" && { echo "$cand"; return 0; }
  done
  return 1
}

venv_ok() {
  is_py313 "$VENV/bin/python"
}

if [ -d "$VENV" ] && ! venv_ok; then
  echo "bootstrap: $VENV is broken or not Python $WANT; recreating it"
  rm -rf "$VENV"
fi

if [ ! -d "$VENV" ]; then
  PY=$(find_python) || fail "Python $WANT not found. bpy 5.2.3 needs exactly Python $WANT: install it
  (e.g. 'pyenv install $WANT' or your system's python$WANT package) so that 'python$WANT' is on PATH,
  or set PYTHON313=/path/to/python$WANT"
  echo "bootstrap: creating $VENV with $PY"
  "$PY" -m venv "$VENV" || fail "'$PY -m venv $VENV' failed (on Debian/Ubuntu: install python$WANT-venv)"
fi

want_hash=$(cat requirements.txt pyproject.toml | sha256sum | cut -d' ' -f1)
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$want_hash" ] && "$VENV/bin/python" -c "import bpy, OpenEXR, numpy, pytest, sss_lab" 2>/dev/null; then
  exit 0
fi

echo "bootstrap: installing pinned dependencies into $VENV (bpy is about 900 MB on first install)"
if ! "$VENV/bin/python" -m pip install --disable-pip-version-check -q -r requirements.txt; then
  fail "installing requirements.txt failed. Is the Python package index reachable from this machine
  (check your network or proxy, or set PIP_INDEX_URL to a mirror)? pip's message is above."
fi
"$VENV/bin/python" -m pip install --disable-pip-version-check -q --no-deps -e . >/dev/null 2>&1 \
  || fail "installing SSS Lab itself ('pip install -e .') failed; run it by hand to see why"
"$VENV/bin/python" -c "import bpy, OpenEXR, numpy, sss_lab" \
  || fail "the environment installed but does not import; delete $VENV and run again"
echo "$want_hash" > "$STAMP"
echo "bootstrap: $VENV ready"
