"""The recorder's configuration: defaults, a file (TOML or JSON), flags.

Made by ``seaway.runtime.config``: the defaults below, then ``--config FILE`` (unknown fields are
errors), then a flag per field (``--out``, ``--flush-interval``, ``--no-validate``, ...). The run
(``--run`` or the run flags) only describes the recording: the recorder records whatever runs.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator
from seaway.contract.config import ConfigModel
from seaway.recording import runinfo
from seaway.runtime.config import Flag

from seaway_recorder.syncer import DEFAULT_SYNC_INTERVAL_S

DEFAULT_FLUSH_S = 0.05
MAX_FLUSH_INTERVAL_S = 0.1
"""The longest time between two flushes [s]: a SIGKILL loses less than twice this."""
_UNITS = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30}


def parse_size(text: str) -> int:
    """A size in bytes: a number with an optional k, M or G (binary; ``512M``, ``4MiB``, ``65536``)."""
    t = text.strip().lower().removesuffix("b").removesuffix("i")
    mult = _UNITS.get(t[-1:], 1)
    try:
        value = int(float(t[:-1] if t[-1:] in _UNITS else t) * mult)
    except (ValueError, OverflowError):
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a size of at least 1 byte (a whole "
                                         "number with an optional k, M or G, e.g. 512M)")
    return value


def parse_meta(items: Sequence[str]) -> dict[str, str]:
    """``KEY=VALUE`` items -> a dict; ValueError naming the item that is not one."""
    out = {}
    for item in items:
        k, sep, v = item.partition("=")
        if not sep or not k:
            raise ValueError(f"wants KEY=VALUE, got {item!r}")
        out[k] = v
    return out


class RecorderConfig(ConfigModel):
    """What the recorder records, where, and how it writes."""

    out: Annotated[str | None, Flag()] = Field(
        default=None,
        description="output folder or .mcap file (default runs/<UTC time>/recording.mcap)")
    vessels: Annotated[str, Flag()] = Field(
        default="",
        description="comma-separated vessels to record (default: every vessel, seaway/**)")
    key_expr: Annotated[list[str], Flag()] = Field(
        default_factory=list, description="record this key expression instead")
    profile: Annotated[str | None, Flag()] = Field(
        default=None, description="launcher profile (name or file) to attach")
    mission: Annotated[str | None, Flag()] = Field(
        default=None, description="mission file to attach (MissionRequest JSON or TOML)")
    attach: Annotated[list[str], Flag(metavar="[ROLE=]FILE")] = Field(
        default_factory=list,
        description=f"attach a file; roles: {', '.join(runinfo.ROLES)} (default config)")
    meta: Annotated[list[str], Flag(metavar="KEY=VALUE")] = Field(
        default_factory=list, description="add to the seaway.run metadata record")
    flush_interval_s: Annotated[float, Flag("--flush-interval")] = Field(
        default=DEFAULT_FLUSH_S, gt=0, le=MAX_FLUSH_INTERVAL_S,
        description=f"seconds between flushes, at most {MAX_FLUSH_INTERVAL_S:g}")
    sync_interval_s: Annotated[float, Flag("--sync-interval")] = Field(
        default=DEFAULT_SYNC_INTERVAL_S, ge=0,
        description="seconds between syncs of the recording to the disk (fdatasync, on a thread of "
                    "its own): about what a power loss loses; 0: never (the OS may hold 30 s)")
    max_bytes: Annotated[int | None, Flag(parse=parse_size)] = Field(
        default=None, gt=0, description="rotate after this size (e.g. 512M)")
    max_seconds: Annotated[float | None, Flag()] = Field(
        default=None, gt=0, description="rotate after this many seconds")
    compression: Annotated[Literal["zstd", "lz4", "none"], Flag()] = Field(
        default="zstd",
        description="chunk compression (default zstd; none writes fastest, files are larger)")
    chunk_size_bytes: Annotated[int, Flag("--chunk-size", parse=parse_size)] = Field(
        default=4 << 20, gt=0, description="end a chunk early past this many bytes (default 4M)")
    queue: Annotated[int, Flag()] = Field(
        default=200_000, ge=1,
        description="samples buffered between Zenoh and the writer before drops")
    validate_samples: Annotated[bool, Flag("--no-validate")] = Field(
        default=True,
        description="check samples against their types (without: faster; nothing counts as "
                    "malformed)")
    foxglove: Annotated[bool, Flag()] = Field(
        default=True,
        description="add the derived Foxglove channels (map positions, mission, frames, 3D scene); "
                    "log lines (--logs) are recorded either way")
    status_interval_s: Annotated[float, Flag("--status-interval")] = Field(
        default=5.0, gt=0, description="seconds between status lines")
    events: Annotated[Path | None, Flag(metavar="FILE")] = Field(
        default=None,
        description="a launcher's events log (events.jsonl) to copy into the recording as it "
                    "grows, on launcher/events")
    logs: Annotated[list[str], Flag(metavar="GLOB|DIR")] = Field(
        default_factory=list,
        description="log files to copy into the recording as they grow, each line a foxglove.Log "
                    "on foxglove/log (a folder means its *.log; the launcher's profiles pass "
                    "'<run>/logs/*.log')")
    sim_epoch: Annotated[str | None, Flag(metavar="TIME")] = Field(
        default=None,
        description="lockstep: the wall-clock time simulated time 0 is logged at, ISO 8601 "
                    "(2026-05-01T09:00:00Z) or Unix seconds (default: when the run started, i.e. "
                    "the --run file was written, else now; whole seconds)")

    @field_validator("meta")
    @classmethod
    def _check_meta(cls, items: list[str]) -> list[str]:
        parse_meta(items)
        return items
