"""Contract, checked over the source (AST): production code stays off the lab, and spells no key.

* Production is every module under ``services/*/src``. None imports ``seaway_lab`` (the in-process
  closed loop, the scripted autopilot, the responder, the benchmarks) or a module named like one of
  the lab's harnesses, and no service package depends on the lab.
* Keys are spelled once, in ``seaway.contract.keys``: no string in production code outside that file
  spells a registered key suffix (``nav/state``), a key expression's root (``seaway/...``) or a
  service-token family (``health/``, ``run/``). Uses go through the ``KeySpec`` objects
  (``keys.NAV_STATE.suffix``, ``keys.SIM_TRUTH.wildcard()``). Documentation does not count: a
  bare string statement (a module, class or function docstring, or an attribute's docstring) is
  prose that is never executed.
"""

from __future__ import annotations

import ast
import re
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest
from seaway.contract import keys

REPO = Path(__file__).resolve().parents[2]
LAB = REPO / "lab" / "src" / "seaway_lab"
KEYS_FILE = REPO / "services" / "common" / "src" / "seaway" / "contract" / "keys.py"


def production_files(root: Path = REPO) -> list[Path]:
    return sorted((root / "services").glob("*/src/**/*.py"))


def _imported_modules(tree: ast.AST) -> Iterator[tuple[int, str]]:
    """(line, module) of every absolute import, and of every string passed to an import function."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, a.name) for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
            yield from ((node.lineno, f"{node.module}.{a.name}") for a in node.names)
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and getattr(node.func, "attr", getattr(node.func, "id", "")) in ("import_module",
                                                                                 "__import__")):
            yield node.lineno, node.args[0].value


def lab_module_names() -> set[str]:
    """The lab's harness and benchmark module names (``closed_loop``, ``fake_autopilot``, ``bench``)."""
    names = {p.stem for p in LAB.glob("*.py") if p.stem != "__init__"}
    names |= {p.parent.name for p in LAB.glob("*/__init__.py")}
    return names


def lab_imports(files: list[Path], root: Path = REPO) -> list[str]:
    harnesses = lab_module_names()
    found = []
    for py in files:
        for line, mod in _imported_modules(ast.parse(py.read_text(), str(py))):
            parts = mod.split(".")
            if parts[0] == LAB.name or harnesses & set(parts[1:]):
                found.append(f"{py.relative_to(root)}:{line} imports {mod}")
    return found


def test_the_lab_has_the_harnesses_this_guards_against():
    assert {"closed_loop", "fake_autopilot", "responder", "bench"} <= lab_module_names()


def test_no_production_module_imports_the_lab():
    assert lab_imports(production_files()) == []


def test_no_service_package_depends_on_the_lab():
    for pyproject in sorted((REPO / "services").glob("*/pyproject.toml")):
        project = tomllib.loads(pyproject.read_text())["project"]
        deps = [*project.get("dependencies", []),
                *(d for ds in project.get("optional-dependencies", {}).values() for d in ds)]
        assert not [d for d in deps if re.match(r"seaway[-_]lab\b", d)], pyproject


# -- keys -------------------------------------------------------------------------------------------


def key_patterns() -> list[re.Pattern[str]]:
    """What spelling a key looks like: a registered suffix as a whole token, the root of a key
    expression, or a service token (``health/<service>``, ``run/<service>``: the third and fourth
    chunks of ``health_key`` and friends) whose service is a known one, a wildcard or still to be
    filled in (the end of an f-string part). ``run/run.json``, an attachment's name, is no key."""
    pats = [re.compile(rf"(?<![\w]){re.escape(spec.suffix)}(?![\w])") for spec in keys.REGISTRY]
    pats.append(re.compile(rf"^{re.escape(keys.ROOT)}/"))
    families = {fn("v", keys.SERVICES[0]).split("/")[2]
                for fn in (keys.health_key, keys.run_description_key)}
    services = "|".join(re.escape(s) for s in keys.SERVICES)
    pats += [re.compile(rf"(?:^|/){re.escape(f)}/(?:$|\*|(?:{services})(?![\w]))")
             for f in sorted(families)]
    return pats


def _documentation(tree: ast.AST) -> set[int]:
    """ids of the string constants that are bare statements (docstrings, attribute docstrings)."""
    return {id(node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)}


def key_spellings(files: list[Path], root: Path = REPO) -> list[str]:
    pats = key_patterns()
    found = []
    for py in files:
        if py.resolve() == KEYS_FILE.resolve():
            continue
        tree = ast.parse(py.read_text(), str(py))
        docs = _documentation(tree)
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and id(node) not in docs and any(p.search(node.value) for p in pats)):
                found.append(f"{py.relative_to(root)}:{node.lineno}: {node.value[:80]!r}")
    return found


def test_keys_are_spelled_only_in_the_key_registry():
    assert key_spellings(production_files()) == []


@pytest.mark.parametrize(("source", "flagged"), [
    ('TOPICS = ("sim/truth", "nav/state")', 2),
    ('dec.get("nav/state")', 1),
    ('log.warning("nav/state older than %.2f s", age)', 1),
    ('expr = f"seaway/{vessel}/**"', 1),
    ('expr = f"{root}/{vessel}/ctrl/thrust"', 1),
    ('token = f"{root}/{vessel}/health/{service}"', 1),
    ('tokens = ("health/*", "run/estimator")', 2),
    ('attachment = "run/run.json"', 0),
    ('"""Reads nav/state and sim/truth (a docstring)."""', 0),
    ('X = 1\n"""X: from ctrl/solve (an attribute docstring)."""', 0),
    ('spec = keys.NAV_STATE.suffix', 0),
    ('a = "nav/statement"; b = "seaway.v1.SimTruth"; c = "zenoh/peer.json5"', 0),
])
def test_the_key_check_bites(tmp_path, source, flagged):
    """The check finds a key reintroduced by hand, in any of the shapes it takes, and only those."""
    py = tmp_path / "services" / "x" / "src" / "x" / "mod.py"
    py.parent.mkdir(parents=True)
    py.write_text(source + "\n")
    assert len(key_spellings(production_files(tmp_path), tmp_path)) == flagged


def test_the_lab_check_bites(tmp_path):
    py = tmp_path / "mod.py"
    py.write_text("import seaway_lab\nfrom seaway_lab.bench import io\nfrom x.closed_loop import run\n"
                  "import importlib\nimportlib.import_module('seaway_lab.responder')\n"
                  "from seaway.contract import keys\nfrom seaway_controller import mpc\n")
    found = {f.split(" imports ")[1] for f in lab_imports([py], tmp_path)}
    assert found == {"seaway_lab", "seaway_lab.bench", "seaway_lab.bench.io", "x.closed_loop",
                     "x.closed_loop.run", "seaway_lab.responder"}
