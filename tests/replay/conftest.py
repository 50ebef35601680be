"""``--regen``: re-record the replay goldens before the replay tests run (deliberately only)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session", autouse=True)
def _regen(request: pytest.FixtureRequest) -> None:
    if request.config.getoption("--regen"):
        from tests.replay.regen import regen_all

        for path in regen_all():
            print(f"regenerated {path}")
