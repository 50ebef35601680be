"""Browser-side test tools from npm, installed once per lockfile into a cache folder.

A tool's folder in the repository holds its ``package.json`` and ``package-lock.json``; ``install``
copies them into ``<cache root>/<sha256 of the lockfile>`` and runs ``npm ci`` there (no scripts),
unless the file ``marker`` (relative to that folder) is already there. Used for Foxglove Studio
(``tests/system/foxglove``) and axe-core (``tests/system/groundstation``).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path


class NpmUnavailableError(RuntimeError):
    """The tool cannot be installed here (no npm, or npm failed)."""


def install(package_dir: Path, marker: str, env_cache: str, cache_name: str,
            cache: Path | None = None, timeout_s: float = 900.0) -> Path:
    """The cache folder holding ``package_dir``'s locked packages (``marker`` in it). The cache root
    is ``cache``, else ``$env_cache``, else ``~/.cache/seaway/<cache_name>``."""
    lock = (package_dir / "package-lock.json").read_bytes()
    root = cache or Path(os.environ.get(env_cache) or Path.home() / ".cache" / "seaway" / cache_name)
    where = root / hashlib.sha256(lock).hexdigest()[:12]
    if (where / marker).is_file():
        return where
    npm = shutil.which("npm")
    if npm is None:
        raise NpmUnavailableError("npm is not installed (apt-get install npm; .ci/run does)")
    where.mkdir(parents=True, exist_ok=True)
    for name in ("package.json", "package-lock.json"):
        shutil.copyfile(package_dir / name, where / name)
    done = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"], cwd=where,
                          capture_output=True, text=True, timeout=timeout_s)
    if done.returncode != 0 or not (where / marker).is_file():
        raise NpmUnavailableError(f"npm ci failed in {where}: {done.stderr[-2000:]}")
    return where
