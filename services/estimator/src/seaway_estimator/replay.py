"""Input traces: what the estimator was fed, as JSON lines, and replaying them exactly.

One line per core call, in the order the calls were made::

    {"kind": "gnss", "msg": {...GnssFix fields...}}
    {"kind": "attitude", "msg": {...}}
    {"kind": "thrust", "msg": {...}}
    {"kind": "status", "msg": {...VehicleStatus fields...}}   # real time only
    {"kind": "tick", "t_ns": 1234}          # predict_to(t_ns): one output line
    {"kind": "reset", "keep_origin": true}

Replaying a trace into a fresh core gives one output per ``tick``: the ``StateEstimate`` wire bytes,
or ``null`` when there was no estimate (not initialised). The core reads no clock and draws no random
number, so the outputs are the same bytes every time (``python -m seaway_estimator.replay TRACE``).
The service writes such a trace with ``--record-inputs FILE``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any

from seaway.contract.messages import Message

from seaway_estimator.config import EstimatorConfig, load_estimator_config
from seaway_estimator.core import INPUT_KEYS, STATUS_KEY, EstimatorCore

Entry = tuple[str, Any]
_TYPES: dict[str, type[Message]] = {kind: spec.message
                                    for kind, spec in [*INPUT_KEYS.items(), ("status", STATUS_KEY)]
                                    if spec.message is not None}


def encode_entry(kind: str, value: Any) -> str:
    """One JSON line for a core call (``value``: a message, a time in ns, or keep_origin)."""
    if kind in _TYPES:
        return json.dumps({"kind": kind, "msg": json.loads(value.encode())}, sort_keys=True)
    if kind == "tick":
        return json.dumps({"kind": "tick", "t_ns": int(value)})
    if kind == "reset":
        return json.dumps({"kind": "reset", "keep_origin": bool(value)})
    raise ValueError(f"unknown trace entry kind {kind!r}")


def decode_entry(line: str) -> Entry:
    d = json.loads(line)
    kind = d.get("kind")
    if kind in _TYPES:
        return kind, _TYPES[kind].model_validate(d["msg"])
    if kind == "tick":
        return kind, int(d["t_ns"])
    if kind == "reset":
        return kind, bool(d.get("keep_origin", True))
    raise ValueError(f"unknown trace entry kind {kind!r}")


def write_trace(path: str | Path, entries: Iterable[Entry]) -> int:
    n = 0
    with open(path, "w", encoding="utf-8") as f:
        for kind, value in entries:
            f.write(encode_entry(kind, value) + "\n")
            n += 1
    return n


def read_trace(path: str | Path) -> Iterator[Entry]:
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.strip():
                yield decode_entry(line)


def apply(core: EstimatorCore, kind: str, value: Any) -> bytes | None:
    """Make one core call; a tick returns the estimate's wire bytes (or None), others None."""
    if kind == "gnss":
        core.on_gnss(value)
    elif kind == "attitude":
        core.on_attitude(value)
    elif kind == "thrust":
        core.on_thrust(value)
    elif kind == "status":
        core.on_vehicle_status(value)
    elif kind == "reset":
        core.reset(keep_origin=value)
    elif kind == "tick":
        est = core.predict_to(value)
        return b"null" if est is None else est.encode()
    else:
        raise ValueError(f"unknown trace entry kind {kind!r}")
    return None


def replay(entries: Iterable[Entry], config: EstimatorConfig | None = None,
           core: EstimatorCore | None = None) -> list[bytes]:
    """Feed ``entries`` to a fresh core (or ``core``); the outputs of every tick, in order."""
    core = core or EstimatorCore(config)
    out = []
    for kind, value in entries:
        r = apply(core, kind, value)
        if kind == "tick":
            assert r is not None
            out.append(r)
    return out


class TraceWriter:
    """Appends core calls to a JSON-lines file as they are made (the service's --record-inputs)."""

    def __init__(self, path: str | Path) -> None:
        # Line-buffered: a process that is killed leaves every complete line it fed.
        self._f: IO[str] = open(path, "w", encoding="utf-8", buffering=1)  # noqa: SIM115

    def write(self, kind: str, value: Any) -> None:
        self._f.write(encode_entry(kind, value) + "\n")

    def close(self) -> None:
        self._f.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m seaway_estimator.replay",
                                 description="replay an input trace; print one output per tick")
    ap.add_argument("trace", type=Path)
    ap.add_argument("--config", default=None, help="estimator config file (default: defaults)")
    args = ap.parse_args(argv)
    for b in replay(read_trace(args.trace), load_estimator_config(args.config)):
        sys.stdout.write(b.decode() + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
