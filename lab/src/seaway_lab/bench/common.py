"""The benchmark convention: ``seaway bench NAME`` prints a table; ``--json`` prints one JSON object.

A benchmark is a function ``run(argv: list[str]) -> BenchResult`` registered under the entry-point
group ``seaway.benchmarks`` by the package that owns it. Figures carry their unit in their name, and
an optional target with whether it was met, so the table and the JSON say the same thing.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any


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
            "meta": self.meta,
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
        if self.meta:
            out += ["", *(f"{k}: {v}" for k, v in self.meta.items())]
        return "\n".join(s.rstrip() for s in out)

    def dumps(self) -> str:
        return json.dumps(self.to_json())


def pin_to_one_core() -> int | None:
    """Pin this process to one CPU so 'per core' figures mean that; returns the CPU or None."""
    try:
        cpu = sorted(os.sched_getaffinity(0))[-1]
        os.sched_setaffinity(0, {cpu})
        return cpu
    except (AttributeError, OSError):
        return None
