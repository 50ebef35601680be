"""axe-core (Deque's accessibility engine, from npm) run inside the ground station's page.

``axe/`` holds the npm lockfile; ``install`` puts axe-core in a cache folder with ``npm ci`` on first
use (about 3 MB), as the Foxglove Studio test does. ``violations(page)`` injects ``axe.min.js`` into a
Playwright page and runs the WCAG 2.x A and AA rules (colour contrast among them); the test decides
which impacts fail it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

AXE_DIR = Path(__file__).parent / "axe"
ENV_CACHE = "SEAWAY_AXE_CACHE"
WCAG_AA_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]


class AxeUnavailableError(RuntimeError):
    """axe-core cannot be installed here (no npm, or npm failed)."""


def install(cache: Path | None = None) -> Path:
    """``axe.min.js`` of the locked axe-core, installed with ``npm ci`` on first use."""
    lock = (AXE_DIR / "package-lock.json").read_bytes()
    root = cache or Path(os.environ.get(ENV_CACHE) or Path.home() / ".cache" / "seaway" / "axe-core")
    where = root / hashlib.sha256(lock).hexdigest()[:12]
    script = where / "node_modules" / "axe-core" / "axe.min.js"
    if script.is_file():
        return script
    npm = shutil.which("npm")
    if npm is None:
        raise AxeUnavailableError("npm is not installed (apt-get install npm; .ci/run does)")
    where.mkdir(parents=True, exist_ok=True)
    for name in ("package.json", "package-lock.json"):
        shutil.copyfile(AXE_DIR / name, where / name)
    done = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"], cwd=where,
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0 or not script.is_file():
        raise AxeUnavailableError(f"npm ci failed in {where}: {done.stderr[-2000:]}")
    return script


def violations(page: Any, script: Path) -> list[dict[str, Any]]:
    """axe-core's WCAG A/AA violations of the page as it is now: each ``{id, impact, help,
    nodes: [{target, summary}]}``."""
    page.add_script_tag(path=str(script))
    return page.evaluate("""async (tags) => {
        const r = await axe.run(document, { runOnly: { type: "tag", values: tags } });
        return r.violations.map((v) => ({ id: v.id, impact: v.impact, help: v.help,
            nodes: v.nodes.map((n) => ({ target: n.target, summary: n.failureSummary })) }));
    }""", WCAG_AA_TAGS)


def serious(found: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The violations a crew would be hurt by: impact serious or critical."""
    return [v for v in found if v["impact"] in ("serious", "critical")]
