#!/usr/bin/env bash
# Create or repair the environment of one Blender version, then install SSS Lab itself in
# editable mode. Safe to run again: it does nothing when the environment is complete and the
# requirements have not changed.
#   tools/bootstrap.sh        Blender 5.2: .venv, Python 3.13, requirements.txt
#   tools/bootstrap.sh 4.5    Blender 4.5 LTS: .venv-4.5, Python 3.11, requirements.txt with the
#                             pins of requirements-4.5.txt in place of the same packages' pins
set -euo pipefail
cd "$(dirname "$0")/.."

BLENDER_VERSION=${1:-5.2}
case "$BLENDER_VERSION" in
  5.2) VENV=.venv; WANT=3.13; OVERRIDES= ;;
  4.5) VENV=.venv-4.5; WANT=3.11; OVERRIDES=requirements-4.5.txt ;;
  *) echo "bootstrap: error: unknown Blender version '$BLENDER_VERSION' (expected 5.2 or 4.5)" >&2; exit 1 ;;
esac
PYVAR=PYTHON${WANT/./}
STAMP="$VENV/.sss_lab-installed"

fail() { echo "bootstrap: error: $*" >&2; exit 1; }

is_wanted_python() {
  # A pyenv shim is on PATH even when its version is not active: run the candidate to be sure.
  [ -n "$1" ] && [ -x "$1" ] && "$1" -c "import sys; sys.exit('%d.%d' % sys.version_info[:2] != '$WANT')" >/dev/null 2>&1
}

find_python() {
  local cand
  for cand in "${!PYVAR:-}" "$(command -v python$WANT || true)"; do
    is_wanted_python "$cand" && { echo "$cand"; return 0; }
  done
  if command -v pyenv >/dev/null 2>&1; then
    for cand in "$(pyenv root)"/versions/$WANT*/bin/python$WANT; do
      is_wanted_python "$cand" && { echo "$cand"; return 0; }
    done
  fi
  for cand in "$HOME"/.pyenv/versions/$WANT*/bin/python$WANT; do
    is_wanted_python "$cand" && { echo "$cand"; return 0; }
  done
  return 1
}

venv_ok() {
  is_wanted_python "$VENV/bin/python"
}

if [ -d "$VENV" ] && ! venv_ok; then
  echo "bootstrap: $VENV is broken or not Python $WANT; recreating it"
  rm -rf "$VENV"
fi

if [ ! -d "$VENV" ]; then
  PY=$(find_python) || fail "Python $WANT not found. bpy for Blender $BLENDER_VERSION needs exactly Python $WANT:
  install it (e.g. 'pyenv install $WANT' or your system's python$WANT package) so that 'python$WANT' is
  on PATH, or set $PYVAR=/path/to/python$WANT"
  echo "bootstrap: creating $VENV with $PY"
  "$PY" -m venv "$VENV" || fail "'$PY -m venv $VENV' failed (on Debian/Ubuntu: install python$WANT-venv)"
fi

# The requirements of this version: requirements.txt, with each package that the overrides file
# pins taken from there instead (the same tools for both versions, Blender's own pins apart).
REQS=$(mktemp)
trap 'rm -f "$REQS"' EXIT
if [ -n "$OVERRIDES" ]; then
  overridden=$(sed -e 's/#.*//' -e 's/[<>=!~ ;\[].*//' "$OVERRIDES" | tr 'A-Z_' 'a-z-' | grep . || true)
  {
    while IFS= read -r line; do
      name=$(printf '%s' "$line" | sed -e 's/#.*//' -e 's/[<>=!~ ;\[].*//' | tr 'A-Z_' 'a-z-')
      if [ -z "$name" ] || ! printf '%s\n' "$overridden" | grep -qx -- "$name"; then printf '%s\n' "$line"; fi
    done < requirements.txt
    cat "$OVERRIDES"
  } > "$REQS"
else
  cp requirements.txt "$REQS"
fi

want_hash=$(cat "$REQS" pyproject.toml | sha256sum | cut -d' ' -f1)
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$want_hash" ] && "$VENV/bin/python" -c "import bpy, OpenEXR, numpy, pytest, sss_lab" 2>/dev/null; then
  exit 0
fi

echo "bootstrap: installing pinned dependencies into $VENV (bpy is about 900 MB on first install)"
if ! "$VENV/bin/python" -m pip install --disable-pip-version-check -q -r "$REQS"; then
  fail "installing the requirements of Blender $BLENDER_VERSION failed. Is the Python package index reachable from this machine
  (check your network or proxy, or set PIP_INDEX_URL to a mirror)? pip's message is above."
fi
"$VENV/bin/python" -m pip install --disable-pip-version-check -q --no-deps -e . >/dev/null 2>&1 \
  || fail "installing SSS Lab itself ('pip install -e .') failed; run it by hand to see why"
"$VENV/bin/python" -c "import bpy, OpenEXR, numpy, sss_lab" \
  || fail "the environment installed but does not import; delete $VENV and run again"
echo "$want_hash" > "$STAMP"
echo "bootstrap: $VENV ready (Blender $BLENDER_VERSION)"
