"""The controllers, one module each, registered by name.

Each public module here defines one controller (its stage cost, its terminal terms if it is an
economic MPC, its cold guess) and ``register``s it. Every module is imported below, so adding a
shipped controller is adding its module (and its name to ``seaway.contract.messages.
BuiltinControllerName``); the import fails if the shipped names and the contract's differ.

A controller of one's own lives in one file anywhere, registered the same way, and is loaded by
``load_module`` (``seaway-controller --controller-module FILE``, ``seaway launch ...
--controller-module FILE``); ``docs/researcher/new-controller.md`` walks through an example.
"""

from __future__ import annotations

import importlib
import importlib.util
import pkgutil
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import ModuleType

from seaway.contract.messages import CONTROLLER_NAMES, BuiltinControllerName

from seaway_controller.controllers._registry import Controller, register, registered

__all__ = ["CONTROLLERS", "NAMES", "Controller", "ControllerModuleError", "check_names", "get",
           "load_module", "names", "register",
           "source_file"]


def check_names(registered_names: Iterable[str], contract_names: Iterable[str]) -> None:
    """Raise if the shipped controllers are not exactly the contract's names."""
    have, want = set(registered_names), set(contract_names)
    if have != want:
        raise RuntimeError(
            "controllers registered and seaway.contract.messages.BuiltinControllerName differ: "
            f"not registered {sorted(want - have)}, not in the contract {sorted(have - want)}")


for _info in pkgutil.iter_modules(__path__):
    if not _info.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_info.name}")

check_names(registered(), CONTROLLER_NAMES)

NAMES: tuple[BuiltinControllerName, ...] = CONTROLLER_NAMES
"""The shipped controllers, in the contract's order (the paper's CC-EMPC first)."""
CONTROLLERS: Mapping[str, Controller] = {name: registered()[name] for name in NAMES}
"""The shipped controllers by name (``names()`` adds those loaded by ``load_module``)."""


def names() -> tuple[str, ...]:
    """Every registered controller: the shipped ones, then those ``load_module`` added."""
    return tuple(registered())


def get(name: str) -> Controller:
    """The controller registered as ``name``; ValueError naming the known ones otherwise."""
    try:
        return registered()[name]
    except KeyError:
        raise ValueError(f"unknown controller {name!r}; known: {', '.join(names())}") from None


class ControllerModuleError(ValueError):
    """A ``--controller-module`` that cannot be loaded, or registers no valid controller."""


_LOADED: dict[str, tuple[str, ...]] = {}
"""What each module loaded so far registered, by its resolved file or module name."""
_FILES: dict[str, Path] = {}
"""The file each loaded controller was registered from (part of its solver's cache key)."""


def load_module(spec: str) -> tuple[str, ...]:
    """Import a controller module of one's own and return the names it registered.

    ``spec`` is a Python file (``path/to/my_controller.py``, relative to the working directory) or
    an importable module (``my_package.my_controller``). Importing it must ``register`` at least one
    ``Controller`` whose name is spelled as ``CONTROLLER_NAME_PATTERN`` allows and is not taken.
    Loading the same module again registers nothing new and returns the same names.
    ControllerModuleError says what is wrong.
    """
    is_file = spec.endswith(".py") or "/" in spec or "\\" in spec
    key = str(Path(spec).expanduser().resolve()) if is_file else spec
    if key in _LOADED:
        return _LOADED[key]
    before = set(registered())
    try:
        module = _import_file(spec, Path(key)) if is_file else importlib.import_module(spec)
    except ControllerModuleError:
        raise
    except Exception as err:  # whatever the module raised while it was imported
        raise ControllerModuleError(f"controller module {spec}: {type(err).__name__}: {err}") from err
    added = tuple(n for n in registered() if n not in before)
    if not added:
        raise ControllerModuleError(f"controller module {spec} registered no controller: it must "
                                    "call seaway_controller.controllers.register(Controller(...))")
    _LOADED[key] = added
    for name in added:
        _FILES[name] = Path(module.__file__ or key)
    return added


def _import_file(spec: str, path: Path) -> ModuleType:
    if not path.is_file():
        raise ControllerModuleError(f"controller module {spec}: no such file (a .py file, or an "
                                    "importable module name such as my_package.my_controller)")
    name = "seaway_controller_module_" + re.sub(r"\W", "_", str(path))
    module_spec = importlib.util.spec_from_file_location(name, path)
    if module_spec is None or module_spec.loader is None:
        raise ControllerModuleError(f"controller module {spec}: not a Python file")
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module  # dataclasses and pickling look their module up here
    try:
        module_spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def source_file(name: str) -> Path | None:
    """The file the controller ``name`` was loaded from by ``load_module``; None for a shipped one."""
    return _FILES.get(name)
