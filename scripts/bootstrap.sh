# Sourced by ./run and ./test: make .venv hold exactly the locked dependencies of every package.
# Needs only python3 (>= 3.11) with venv; fetches uv (pinned) from PyPI into .tools/ if not on PATH.
# Never downloads a Python build: uses one it finds.
set -euo pipefail
UV_VERSION="0.13.8"
export UV_PYTHON_DOWNLOADS=never
new_enough() { "$1" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; }
# The interpreter: $SEAWAY_PYTHON if set; else the distribution's /usr/bin/python3 if it is 3.11 or
# newer; else python3 on PATH. The distribution's first because Debian and Ubuntu build theirs with
# profile-guided and link-time optimisation, which a version manager's default build (pyenv's) has
# not, and a lockstep mission is mostly pure Python: docs/results.md ("Timing") has the figures.
# Always the same choice on one machine, so .venv is not made again from another interpreter.
if [ -n "${SEAWAY_PYTHON:-}" ]; then
    PY="$SEAWAY_PYTHON"
elif new_enough /usr/bin/python3; then
    PY=/usr/bin/python3
else
    PY=python3
fi
if ! new_enough "$PY"; then
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
