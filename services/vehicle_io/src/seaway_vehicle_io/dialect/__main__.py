"""Regenerate ``events.py`` from ``events.xml`` with pymavlink's own generator."""

from __future__ import annotations

from pathlib import Path

from pymavlink.generator import mavgen

HERE = Path(__file__).resolve().parent
XML = HERE / "events.xml"
OUT = HERE / "events.py"


def generate(out: Path = OUT) -> Path:
    """Write the Python module for ``events.xml`` to ``out`` (MAVLink 2)."""
    opts = mavgen.Opts(output=str(out), wire_protocol="2.0", language="Python3", validate=False)
    if not mavgen.mavgen(opts, [str(XML)]):
        raise SystemExit(f"mavgen failed on {XML}")
    return out


if __name__ == "__main__":
    print(f"wrote {generate()}")
