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
# --compile-bytecode, and compileall for our own sources: every process of a stack imports numpy,
# pydantic, casadi and zenoh, and compiling them from source at each start cost it about 0.8 s of
# CPU (1.5 s -> 0.7 s a service, measured on a 2-core VM). Python reads the .pyc files even where
# PYTHONDONTWRITEBYTECODE is set; compileall rewrites only those older than their source.
"$UV" sync --locked --all-packages --python "$PY" -q --compile-bytecode
.venv/bin/python -m compileall -q -j 0 services/*/src lab/src >/dev/null
