"""The files a recording carries, made into attachments for the writer (``<role>/<file name>``).

The names, roles and their reading back are the shared library's (``seaway.recording.runinfo``);
making them from files on disk is the recorder's: ``seaway record --scenario/--profile/--attach``.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from seaway.contract.config import ConfigError
from seaway.recording.runinfo import ROLES, scenario_path, vessel_path
from seaway.simkit.scenario import Scenario, load_scenario

from seaway_recorder.core import AttachmentSpec, media_type_for


def attachment(role: str, path: Path, name: str | None = None) -> AttachmentSpec:
    """The file ``path`` as the attachment ``<role>/<name or its file name>``; ConfigError if it
    does not read, ValueError for a role not in ``ROLES``."""
    if role not in ROLES:
        raise ValueError(f"attachment role {role!r}: use one of {', '.join(ROLES)}")
    p = Path(path)
    try:
        data = p.read_bytes()
        created = int(p.stat().st_mtime * 1e9)
    except OSError as err:
        raise ConfigError(f"cannot attach {p}: {err.strerror or err}") from None
    return AttachmentSpec(f"{role}/{name or p.name}", media_type_for(p), data, created)


def parse_attach_arg(text: str) -> AttachmentSpec:
    """``ROLE=FILE`` or ``FILE`` (role ``config``)."""
    role, sep, path = text.partition("=")
    if sep and role in ROLES:
        return attachment(role, Path(path))
    return attachment("config", Path(text))


def scenario_attachments(name_or_path: str, with_vessel: bool = True
                         ) -> tuple[list[AttachmentSpec], Scenario]:
    """The scenario file (validated), the data files it refers to and, optionally, its vessel file."""
    path = scenario_path(name_or_path)
    scenario = load_scenario(path)
    out = [attachment("scenario", path)]
    doc = tomllib.loads(path.read_text()) if path.suffix == ".toml" else json.loads(path.read_text())
    for d in doc.get("disturbances", []) or []:
        if isinstance(d, dict) and "file" in d:
            out.append(attachment("scenario-data", path.parent / d["file"], name=str(d["file"])))
    if with_vessel:
        out.append(attachment("vessel", vessel_path(scenario.vessel, path.parent)))
    return out, scenario
