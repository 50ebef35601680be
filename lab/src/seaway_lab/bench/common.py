"""The benchmark convention: ``seaway bench NAME`` prints a table; ``--json`` prints one JSON object.

A benchmark is a function ``run(argv: list[str]) -> BenchResult`` registered under the entry-point
group ``seaway.benchmarks`` by the package that owns it. Figures carry their unit in their name, and
an optional target with whether it was met, so the table and the JSON say the same thing.

Authentication (issue 15): a benchmark that crosses Zenoh measures with the stack's mutual TLS and
access control on and off in the same run, alternating, and reports both with ``compare_auth``:
the ratios on / off are figures (target ``<= 1.1``), and the JSON also carries ``auth_on``,
``auth_off`` and ``auth_overhead_ratio`` (figure name -> value) beside ``figures``.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import socket
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from seaway.vessel.metrics import median

INTERPRETER = f"Python {platform.python_version()}, {sys.executable}"
"""The interpreter a bench ran on, in every result: how it was built moves the pure-Python figures
(scripts/bootstrap.sh chooses it; docs/results.md, "Timing")."""

AUTH_TARGET_RATIO = 1.1
"""Issue 15: with authentication on, within 10 % of the figures without it."""


@dataclass(frozen=True)
class Figure:
    name: str
    value: float | int | str
    target: str | None = None
    ok: bool | None = None
    note: str = ""


@dataclass
class BenchResult:
    name: str
    title: str
    figures: list[Figure] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)
    sections: dict[str, dict[str, float]] = field(default_factory=dict)
    """Named groups of figures, each a top-level JSON key beside ``figures`` (``compare_auth``)."""

    def add(self, name: str, value: float | int | str, target: str | None = None,
            ok: bool | None = None, note: str = "") -> None:
        self.figures.append(Figure(name, value, target, ok, note))

    @property
    def passed(self) -> bool:
        return all(f.ok is not False for f in self.figures)

    def to_json(self) -> dict[str, Any]:
        return {
            "bench": self.name,
            "figures": {f.name: f.value for f in self.figures},
            "targets": {f.name: {"target": f.target, "ok": f.ok} for f in self.figures if f.target},
            "passed": self.passed,
            "meta": {"python": INTERPRETER, **self.meta},
            **self.sections,
        }

    def table(self) -> str:
        def fmt(v: float | int | str) -> str:
            if isinstance(v, float):
                return f"{v:,.4g}" if abs(v) < 1e4 else f"{v:,.0f}"
            return f"{v:,}" if isinstance(v, int) else str(v)

        rows = [(f.name, fmt(f.value), f.target or "",
                 "" if f.ok is None else ("ok" if f.ok else "MISSED"), f.note) for f in self.figures]
        head = ("figure", "value", "target", "", "note")
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(5)]
        line = "  ".join("-" * w for w in widths)
        out = [self.title, "", "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)), line]
        out += ["  ".join(c.ljust(w) if i != 1 else c.rjust(w) for i, (c, w) in
                          enumerate(zip(r, widths, strict=True))) for r in rows]
        out += ["", *(f"{k}: {v}" for k, v in {"python": INTERPRETER, **self.meta}.items())]
        return "\n".join(s.rstrip() for s in out)

    def dumps(self) -> str:
        return json.dumps(self.to_json())


def compare_auth(result: BenchResult, on: dict[str, float], off: dict[str, float],
                 ratio_name: Callable[[str], str] = lambda k: f"auth on / off: {k}",
                 pairs: dict[str, list[float]] | None = None) -> dict[str, float]:
    """Report figures measured with authentication ``on`` and ``off`` (same names, same units): a
    ratio figure on / off for each (named ``ratio_name(name)``, with the issue-15 target) and the
    JSON sections ``auth_on``, ``auth_off`` and ``auth_overhead_ratio``. Returns the ratios.

    ``pairs`` (name -> the ratio on / off of each alternating pair of runs): the ratio reported is
    their median, not the ratio of ``on`` to ``off``. Why: a shared machine's speed drifts within
    minutes, and a run is closer in speed to its neighbour than to the median of its own setting;
    with few runs each, the ratio of medians can fall either side of the target from one bench to
    the next."""
    def ratio(k: str) -> float:
        if pairs:
            return median(pairs[k])
        return on[k] / off[k] if off[k] else float("nan")

    ratios = {k: ratio(k) for k in on}
    result.sections.update(auth_on=dict(on), auth_off=dict(off), auth_overhead_ratio=ratios)
    for k, r in ratios.items():
        note = f"on {on[k]:.4g}, off {off[k]:.4g}"
        if pairs:
            note += (f"; median of {len(pairs[k])} alternating pairs' ratios "
                     f"({min(pairs[k]):.3f}-{max(pairs[k]):.3f})")
        result.add(ratio_name(k), r, f"<= {AUTH_TARGET_RATIO:g}", r <= AUTH_TARGET_RATIO, note=note)
    return ratios


def pin_to_one_core() -> int | None:
    """Pin this process to one CPU so 'per core' figures mean that; returns the CPU or None."""
    try:
        cpu = sorted(os.sched_getaffinity(0))[-1]
        os.sched_setaffinity(0, {cpu})
        return cpu
    except (AttributeError, OSError):
        return None


def bench_credentials() -> dict[str, str]:
    """Environment entries that make this process and its children one stack with credentials of
    their own (a fresh authority in a temporary folder, removed at exit; this process and any
    non-service child are the harness identity, which may do everything)."""
    import atexit
    import shutil
    import tempfile
    from pathlib import Path

    from seaway.runtime import credentials

    tmp = Path(tempfile.mkdtemp(prefix="seaway-bench-"))
    atexit.register(shutil.rmtree, tmp, True)
    folder = credentials.create(tmp / "credentials", harness=True).folder
    return {credentials.ENV_CREDENTIALS: str(folder), credentials.ENV_IDENTITY: "harness"}


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port on 127.0.0.1 that nobody holds now (TCP unless ``kind`` says UDP): a private Zenoh
    rendezvous, or a socket of the bench's own."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def free_rendezvous() -> str:
    """A Zenoh rendezvous endpoint on a free loopback port, for ``$SEAWAY_ZENOH_RENDEZVOUS``: the
    bench's stack apart from any other on this machine."""
    return f"tcp/127.0.0.1:{free_port()}"


@contextlib.contextmanager
def restored_environ(*names: str) -> Iterator[None]:
    """``os.environ``'s ``names`` as they were (or unset) again on leaving: a bench sets them for
    itself and the processes it starts, and its caller (a test) goes on."""
    saved = {k: os.environ.get(k) for k in names}
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
