"""axe-core (Deque's accessibility engine, from npm) run inside the ground station's page.

``axe/`` holds the npm lockfile; ``install`` puts axe-core in a cache folder with ``npm ci`` on first
use (about 3 MB), as the Foxglove Studio test does. ``violations(page)`` injects ``axe.min.js`` into a
Playwright page and runs the WCAG 2.x A and AA rules (colour contrast among them); the test decides
which impacts fail it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.system import npm_cache

AXE_DIR = Path(__file__).parent / "axe"
ENV_CACHE = "SEAWAY_AXE_CACHE"
WCAG_AA_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]


class AxeUnavailableError(RuntimeError):
    """axe-core cannot be installed here (no npm, or npm failed)."""


def install(cache: Path | None = None) -> Path:
    """``axe.min.js`` of the locked axe-core, installed with ``npm ci`` on first use."""
    try:
        where = npm_cache.install(AXE_DIR, "node_modules/axe-core/axe.min.js", ENV_CACHE,
                                  "axe-core", cache, timeout_s=600)
    except npm_cache.NpmUnavailableError as err:
        raise AxeUnavailableError(str(err)) from None
    return where / "node_modules" / "axe-core" / "axe.min.js"


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
