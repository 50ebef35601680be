"""Every service, the ground station too, is configured one way (``seaway.runtime.config``): its
settings are one ``ConfigModel`` subclass in its ``config.py``, each field described, and its entry
module (``main.py``; the ground station's ``service.py``) builds its command line with
``service_parser`` and reads it with ``parse_service_args``, adding no flag by hand, so a new
service or a new option cannot slip back into flags declared beside the model."""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

import pytest
from seaway.contract.config import ConfigModel
from seaway.runtime.config import flags_of

from tests.contract.test_service_shape import ROOT, SERVICES

HELPERS = {"service_parser", "parse_service_args"}
CONFIGURED = {**{service: (package, "main") for service, package in SERVICES.items()},
              "groundstation": ("seaway_groundstation", "service")}
"""Each service: (its package, its entry module)."""


def config_models(path: Path) -> list[str]:
    """The classes ``path`` defines whose bases name ``ConfigModel``."""
    tree = ast.parse(path.read_text(), str(path))
    return [node.name for node in tree.body if isinstance(node, ast.ClassDef)
            and any((isinstance(b, ast.Name) and b.id == "ConfigModel")
                    or (isinstance(b, ast.Attribute) and b.attr == "ConfigModel") for b in node.bases)]


def hand_made_flags(path: Path) -> list[str]:
    """Options ``path`` adds itself (``add_argument("--x", ...)``); positionals are allowed (a
    subcommand's operands, e.g. the recorder's ``recover IN OUT``)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "add_argument"):
            out += [a.value for a in node.args if isinstance(a, ast.Constant)
                    and isinstance(a.value, str) and a.value.startswith("-")]
    return out


def called(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    return {n.func.id if isinstance(n.func, ast.Name) else n.func.attr for n in ast.walk(tree)
            if isinstance(n, ast.Call) and isinstance(n.func, (ast.Name, ast.Attribute))}


@pytest.mark.parametrize("service", sorted(CONFIGURED))
def test_a_service_has_one_config_model(service: str) -> None:
    package = ROOT / "services" / service / "src" / CONFIGURED[service][0]
    assert (package / "config.py").is_file(), f"{service} has no config.py"
    models = config_models(package / "config.py")
    assert len(models) == 1, f"{service}/config.py defines {models}: one ConfigModel, its settings"
    model = getattr(importlib.import_module(f"{CONFIGURED[service][0]}.config"), models[0])
    assert inspect.isclass(model) and issubclass(model, ConfigModel)
    undescribed = [n for n, f in model.model_fields.items() if not (f.description or "").strip()]
    assert not undescribed, f"{model.__name__}: fields without a description: {undescribed}"


@pytest.mark.parametrize("service", sorted(CONFIGURED))
def test_a_service_main_makes_its_flags_from_its_model(service: str) -> None:
    package, entry = CONFIGURED[service]
    main = ROOT / "services" / service / "src" / package / f"{entry}.py"
    assert called(main) >= HELPERS, f"{service}/main.py does not use {sorted(HELPERS - called(main))}"
    assert "base_parser" not in called(main), f"{service}/main.py builds a parser by hand"
    assert hand_made_flags(main) == [], f"{service}/main.py declares flags beside its model"


@pytest.mark.parametrize("service", sorted(CONFIGURED))
def test_the_parser_holds_the_model_flags(service: str) -> None:
    """What main.py builds is the model's: every flagged field is an option of the parser."""
    main = importlib.import_module(".".join(CONFIGURED[service]))
    build = getattr(main, "build_parser", None) or main.parser
    parser = build()
    model = parser.get_default("_config_model")
    options = {o for a in parser._actions for o in a.option_strings}
    assert model is not None and {s.option for s in flags_of(model)} | {"--config"} <= options


def test_the_checks_bite(tmp_path: Path) -> None:
    (tmp_path / "config.py").write_text(
        "class A(ConfigModel):\n    pass\nclass B(seaway.ConfigModel):\n    pass\nclass C:\n    pass\n")
    assert config_models(tmp_path / "config.py") == ["A", "B"]
    (tmp_path / "main.py").write_text(
        "p = base_parser('x', 'y')\np.add_argument('--speed-mps', type=float)\n"
        "r.add_argument('input')\n")
    assert hand_made_flags(tmp_path / "main.py") == ["--speed-mps"]
    assert "base_parser" in called(tmp_path / "main.py")
    assert not called(tmp_path / "main.py") >= HELPERS
