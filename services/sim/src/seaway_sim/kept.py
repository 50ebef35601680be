"""The scenario a sim was told to load, kept for the sim that replaces it (``--state-file PATH``).

A scenario loaded over the bus (``sim/scenario``, action ``load``: an operator's, or a study's shared
stack loading one per run) replaces the run's. The launcher restarts a sim that died with the same
command line, which names the run's scenario: without this file a restarted sim came back in other
water (another current, another wind, another start) and the mission went on there, its numbers
neither run's. So the sim writes each document it loads to PATH (atomically:
``seaway.runtime.atomic``) before it replies, and a sim that starts while PATH exists loads that
document instead of the run's, unless it was kept before the run started: an earlier launch into the
same run folder (``seaway.runtime.run.from_earlier_launch``). Time starts again at 0 either way (a
restart: a new lockstep episode).

A file that cannot be used (unreadable, not this format, a scenario that no longer validates) stops
the sim with the reason rather than fly the run's scenario in its place.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.runtime import atomic

KeptError = atomic.StateFileError
"""The file exists but cannot be used; the text says why."""


class KeptScenario(ConfigModel):
    """A loaded scenario as kept: the document as the load request carried it."""

    name: str = Field(description="the scenario's name, for people reading the file or the log")
    document: dict[str, Any] = Field(description="the scenario document (grid ``file`` entries "
                                     "relative to deploy/scenarios, as in a load request)")
    saved_unix_ns: int = Field(ge=0, description="when it was loaded [ns since the Unix epoch]")


def save(path: Path, kept: KeptScenario) -> None:
    """Keep ``kept`` at ``path`` (fsynced: a load is rare, and a power loss should keep it too)."""
    atomic.write_text(path, kept.model_dump_json())


def load(path: Path) -> KeptScenario | None:
    """What ``path`` keeps; None if there is no file; KeptError if it cannot be used."""
    return atomic.read_model(path, KeptScenario)
