"""Contract: keys are valid Zenoh key expressions, unique, one producer each; services stay apart."""

from __future__ import annotations

import ast
import re
import tomllib
from pathlib import Path

import pytest
import zenoh
from seaway.contract import keys

REPO = Path(__file__).resolve().parents[2]


def test_keys_are_valid_unique_concrete_key_expressions() -> None:
    seen = set()
    for spec in keys.REGISTRY:
        k = spec.key("vessel1")
        assert str(zenoh.KeyExpr(k)) == k
        assert "*" not in k and "$" not in k
        assert k not in seen, f"{k} registered twice"
        seen.add(k)
        assert zenoh.KeyExpr(spec.wildcard()).intersects(zenoh.KeyExpr(k))


def test_each_key_has_one_known_producer_and_a_type() -> None:
    for spec in keys.REGISTRY:
        assert spec.producer in keys.SERVICES, spec
        assert spec.message is not None, spec


def test_health_keys_live_under_the_vessel() -> None:
    assert keys.health_key("boat-7", "estimator") == "seaway/boat-7/health/estimator"
    with pytest.raises(keys.KeyNameError, match="unknown service"):
        keys.health_key("boat-7", "estimatr")


@pytest.mark.parametrize("bad", ["", "a/b", "*", "**", "a*", "$x", "a b", "-lead", "x" * 65])
def test_bad_vessel_names_refused(bad: str) -> None:
    with pytest.raises(keys.KeyNameError, match="vessel name"):
        keys.THRUST.key(bad)


def test_spec_for_key() -> None:
    assert keys.spec_for_key("seaway/v/ctrl/thrust") is keys.THRUST
    assert keys.spec_for_key("seaway/v/nope") is None
    assert keys.spec_for_key("other/v/ctrl/thrust") is None


def _service_packages() -> dict[str, Path]:
    out = {}
    for pyproject in (REPO / "services").glob("*/pyproject.toml"):
        for pkg in (pyproject.parent / "src").glob("*/__init__.py"):
            out[pkg.parent.name] = pkg.parent
    return out


def test_no_service_imports_another() -> None:
    pkgs = _service_packages()
    assert "seaway" in pkgs
    services = {name for name in pkgs if name != "seaway"}
    for name, path in pkgs.items():
        for py in path.rglob("*.py"):
            tree = ast.parse(py.read_text(), str(py))
            for node in ast.walk(tree):
                mods = []
                if isinstance(node, ast.Import):
                    mods = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                    mods = [node.module]
                if isinstance(node, ast.ImportFrom) and node.module in pkgs and node.level == 0:
                    mods = [f"{node.module}.{a.name}" for a in node.names]  # from pkg import module
                for mod in mods:
                    top = mod.split(".")[0]
                    assert not (top in services and top != name), f"{py} imports {mod}"


def test_no_service_depends_on_another() -> None:
    """Nor does its package ask for another service's: what services share is in ``seaway``."""
    projects = {tomllib.loads(p.read_text())["project"]["name"]: p
                for p in (REPO / "services").glob("*/pyproject.toml")}
    services = set(projects) - {"seaway"}
    for name, pyproject in projects.items():
        project = tomllib.loads(pyproject.read_text())["project"]
        deps = [*project.get("dependencies", []),
                *(d for ds in project.get("optional-dependencies", {}).values() for d in ds)]
        wanted = {re.match(r"[A-Za-z0-9_.-]+", d).group(0).lower().replace("_", "-") for d in deps}
        assert not (wanted & services) - {name}, f"{pyproject} depends on {wanted & services}"
