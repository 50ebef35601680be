"""Fixtures of the launch tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.system.launch.identify_runs import IdentifyRuns, makers


@pytest.fixture(scope="session")
def identify_runs(request: pytest.FixtureRequest,
                  tmp_path_factory: pytest.TempPathFactory) -> Iterator[IdentifyRuns]:
    """The identification flights on firmware, flown at the same time (``identify_runs``)."""
    runs = IdentifyRuns(tmp_path_factory.mktemp("identify"),
                        {item.name for item in request.session.items}, makers())
    yield runs
    runs.stop_all()
