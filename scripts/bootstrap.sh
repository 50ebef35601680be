# Sourced by ./run and ./test: make .venv hold exactly the locked dependencies of every package.
# Needs only python3 (>= 3.11) with venv; fetches uv (pinned) from PyPI into .tools/ if not on PATH.
# Never downloads a Python build: uses the python3 it finds.
set -euo pipefail
UV_VERSION="0.13.8"
export UV_PYTHON_DOWNLOADS=never
PY="${SEAWAY_PYTHON:-python3}"
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
    echo "Seaway needs Python >= 3.11 as '$PY' (set SEAWAY_PYTHON to another interpreter)." >&2
    exit 1
fi
if command -v uv >/dev/null 2>&1; then
    UV=uv
else
    UV=.tools/bin/uv
    if [ ! -x "$UV" ] || ! "$UV" --version 2>/dev/null | grep -q "$UV_VERSION"; then
        echo "bootstrap: installing uv $UV_VERSION into .tools/" >&2
        if ! "$PY" -m venv .tools >/dev/null 2>&1; then
            echo "bootstrap: '$PY -m venv' failed; on Debian/Ubuntu: sudo apt install python3-venv" >&2
            exit 1
        fi
        .tools/bin/pip install -q "uv==$UV_VERSION"
    fi
fi
# --locked: fail rather than silently re-resolve, so every machine gets the same versions.
"$UV" sync --locked --all-packages --python "$PY" -q
