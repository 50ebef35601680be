"""The reference pages under ``docs/reference/`` are what the code gives (``seaway docs reference``).

Regenerated in memory and compared with the committed pages; the check must bite when a key or a
command changes without them, and the pages must not depend on the terminal they were made in.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest
from seaway.tools import cli as seaway_cli
from seaway_lab.docs_reference import cli

REPO = Path(__file__).resolve().parents[2]
REFERENCE = REPO / "docs" / "reference"
HOW = (f"the generated reference is out of date: run `.venv/bin/{cli.REGENERATE}` and commit "
       "docs/reference/")


def test_committed_reference_is_current() -> None:
    problems = cli.stale(REFERENCE, cli.generate())
    assert not problems, HOW + "\n\n" + "\n\n".join(problems)


def test_a_new_key_makes_the_keys_page_stale(monkeypatch: pytest.MonkeyPatch) -> None:
    spec = keys.KeySpec("docs/probe", ArmRequest, "controller", "query", doc="a key the pages lack")
    monkeypatch.setattr(keys, "REGISTRY", (*keys.REGISTRY, spec))
    problems = cli.stale(REFERENCE, cli.generate())
    stale_pages = {p.split(":")[0]: p for p in problems}
    assert str(REFERENCE / "keys.md") in stale_pages  # and messages.md, which lists each type's keys
    assert "docs/probe" in stale_pages[str(REFERENCE / "keys.md")]


def test_a_new_command_makes_the_commands_page_stale(monkeypatch: pytest.MonkeyPatch) -> None:
    def probe(argv: list[str]) -> int:
        import argparse

        argparse.ArgumentParser(prog="seaway probe", description="a command the pages lack").parse_args(argv)
        return 0

    monkeypatch.setitem(seaway_cli.BUILTIN, "probe", probe)
    monkeypatch.setitem(seaway_cli.SUMMARIES, "probe", "a command the pages lack")
    problems = cli.stale(REFERENCE, cli.generate())
    assert [p.split(":")[0] for p in problems] == [str(REFERENCE / "commands.md")]
    assert "seaway probe" in problems[0]


def test_pages_do_not_depend_on_the_terminal(tmp_path: Path) -> None:
    """Another process, another terminal width, another working directory: the same pages."""
    env = {**os.environ, "COLUMNS": "47", "LINES": "7"}
    done = subprocess.run([sys.executable, "-m", "seaway_lab.docs_reference", "reference", "--check",
                           "--out", str(REFERENCE)], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
