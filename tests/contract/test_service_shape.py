"""Every back-end service has the runtime's shape (services/common/README.md, "The runtime and a
node's shape"): its pure ``core.py``, its ``config.py``, a ``node.py`` whose node the runtime
drives, a ``main.py`` its console script runs, and no import of the lockstep protocol, which is the
runtime's alone."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SERVICES = {"sim": "seaway_sim", "estimator": "seaway_estimator", "controller": "seaway_controller",
            "recorder": "seaway_recorder", "vehicle_io": "seaway_vehicle_io"}
PROTOCOL = "seaway.runtime.lockstep"


def imports(path: Path) -> set[str]:
    """The modules ``path`` imports (``from a.b import c``: ``a.b`` and ``a.b.c``)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def protocol_users(package: Path) -> list[str]:
    return sorted(str(p.relative_to(ROOT)) for p in package.rglob("*.py")
                  if PROTOCOL in imports(p))


@pytest.mark.parametrize("service", sorted(SERVICES))
def test_a_service_is_a_node_run_by_its_main(service: str) -> None:
    package = ROOT / "services" / service / "src" / SERVICES[service]
    for part in ("core.py", "config.py", "node.py", "main.py"):
        assert (package / part).is_file(), f"{service} has no {part}"
    assert not (package / "service.py").exists(), "the loop around a core is the runtime's now"
    node_imports = imports(package / "node.py")
    assert any(m.startswith("seaway.runtime.node") or m.startswith("seaway.runtime.lockstep_clock")
               for m in node_imports), f"{service}'s node is no node of seaway.runtime.node"
    scripts = tomllib.loads((package.parents[1] / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts, f"{service} has no console script"
    assert all(target == f"{SERVICES[service]}.main:main" for target in scripts.values()), scripts


@pytest.mark.parametrize("service", sorted(SERVICES))
def test_no_service_imports_the_lockstep_protocol(service: str) -> None:
    assert protocol_users(ROOT / "services" / service / "src") == []


def test_the_protocol_check_bites(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("from seaway.runtime.lockstep import Period\n")
    (tmp_path / "b.py").write_text("from seaway.runtime.node import Period\n")
    assert [Path(p).name for p in protocol_users_at(tmp_path)] == ["a.py"]


def protocol_users_at(folder: Path) -> list[str]:
    return sorted(str(p) for p in folder.rglob("*.py") if PROTOCOL in imports(p))
