"""What the hardening tests share about a launched ``sim`` stack: a short lake mission, the
launcher's process events."""

from __future__ import annotations

import json
from pathlib import Path

from tests.conftest import REPO


def short_lake(tmp: Path, name: str) -> Path:
    """The lake scenario (real-time sim profile, about 1 m/s) with one 25 m leg: about 25 s."""
    text = (REPO / "deploy" / "scenarios" / "lake.toml").read_text()
    text = text.replace('name = "lake"', f'name = "{name}"')
    head = text[:text.index("[mission]")]
    path = tmp / f"{name}.toml"
    path.write_text(head + "[mission]\nwaypoints_m = [[0.0, 0.0], [25.0, 0.0]]\ncoa_radius_m = 2.0\n"
                    "task_power_w = 250.0\ncontroller = \"cc-empc\"\n")
    return path


def starts(run: Path, name: str) -> list[dict]:
    """The launcher's start events of process ``name`` (``events.jsonl``), oldest first."""
    path = run / "events.jsonl"
    if not path.exists():
        return []
    events = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [e for e in events if e.get("process") == name and e.get("event") == "start"]
