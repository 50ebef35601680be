"""The documentation: the site builds in strict mode, and the README is short, its commands run
(``--help`` at least) and its links resolve."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
VENV_BIN = REPO / ".venv" / "bin"
README_MAX_LINES = 150
COMMAND_PREFIXES = ("./run", "./test", ".venv/bin/seaway", "seaway")
"""How a line of a README code block starts when it is a command to check."""


def _env() -> dict[str, str]:
    return {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PATH": f"{VENV_BIN}{os.pathsep}{os.environ['PATH']}"}


def test_site_builds_strict(tmp_path: Path) -> None:
    """``mkdocs build --strict``: a broken link or anchor, or a page left out of the nav, fails."""
    start = time.monotonic()
    site = tmp_path / "site"
    done = subprocess.run([str(VENV_BIN / "mkdocs"), "build", "--strict", "--site-dir", str(site)],
                          cwd=REPO, env=_env(), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"mkdocs build --strict failed:\n{done.stdout}{done.stderr}"
    assert (site / "index.html").is_file()
    print(f"mkdocs build --strict: {time.monotonic() - start:.1f} s")


def readme_commands(text: str) -> list[str]:
    """Each command line of the README's code blocks that starts with one of COMMAND_PREFIXES,
    without its comment."""
    found = []
    for block in re.findall(r"^```[a-z]*\n(.*?)^```", text, flags=re.S | re.M):
        for line in block.splitlines():
            line = line.split(" #", 1)[0].strip()
            if line.split(" ", 1)[0] in COMMAND_PREFIXES:
                found.append(line)
    return found


def readme_links(text: str) -> list[str]:
    """Every link and image target of the README that is not a web address."""
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    return [t for t in targets if not re.match(r"^[a-z]+:", t)]


def test_readme_is_short() -> None:
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, (f"README.md has {lines} lines, at most {README_MAX_LINES}: "
                                       "move the detail into docs/")


def test_readme_links_resolve() -> None:
    links = readme_links(README.read_text(encoding="utf-8"))
    assert links, "the README links nowhere"
    missing = [t for t in links if not (README.parent / t.split("#", 1)[0]).exists()]
    assert not missing, f"README.md links to paths that do not exist: {missing}"


COMMANDS = readme_commands(README.read_text(encoding="utf-8"))


def test_readme_has_the_two_commands() -> None:
    assert {c.split()[0] for c in COMMANDS} >= {"./run", "./test"}


@pytest.mark.parametrize("command", COMMANDS)
def test_readme_command_runs(command: str) -> None:
    """Each command of the README, with ``--help``: it exists, and it takes the options shown."""
    argv = shlex.split(command)
    if argv[0] == "seaway":
        argv[0] = str(VENV_BIN / "seaway")
    if "--help" not in argv:
        argv.append("--help")
    done = subprocess.run(argv, cwd=REPO, env=_env(), capture_output=True, text=True, timeout=300,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 0, f"{shlex.join(argv)} exited {done.returncode}:\n{done.stdout}{done.stderr}"
    shown = done.stdout + done.stderr
    assert "usage" in shown.lower(), f"{shlex.join(argv)} printed no usage"
    # argparse stops at --help before it refuses an unknown option: the help must name each one.
    unknown = [a.split("=", 1)[0] for a in shlex.split(command)
               if a.startswith("-") and a.split("=", 1)[0] not in shown]
    assert not unknown, f"{command}: options its --help does not list: {unknown}"
