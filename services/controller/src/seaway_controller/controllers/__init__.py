"""The controllers, one module each, registered by name.

Each public module here defines one controller (its stage cost, its terminal terms if it is an
economic MPC, its cold guess) and ``register``s it. Every module is imported below, so adding a
controller is adding its module (and its name to ``seaway.contract.messages.ControllerName``, the
wire's closed set); the import fails if the registered names and the contract's differ.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterable, Mapping

from seaway.contract.messages import CONTROLLER_NAMES, ControllerName

from seaway_controller.controllers._registry import Controller, register, registered

__all__ = ["CONTROLLERS", "NAMES", "Controller", "check_names", "get", "register"]


def check_names(registered_names: Iterable[str], contract_names: Iterable[str]) -> None:
    """Raise if the registered controllers are not exactly the contract's names."""
    have, want = set(registered_names), set(contract_names)
    if have != want:
        raise RuntimeError(
            "controllers registered and seaway.contract.messages.ControllerName differ: "
            f"not registered {sorted(want - have)}, not in the contract {sorted(have - want)}")


for _info in pkgutil.iter_modules(__path__):
    if not _info.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_info.name}")

check_names(registered(), CONTROLLER_NAMES)

NAMES: tuple[ControllerName, ...] = CONTROLLER_NAMES
"""The registered names, in the contract's order (the paper's CC-EMPC first)."""
CONTROLLERS: Mapping[str, Controller] = {name: registered()[name] for name in NAMES}


def get(name: str) -> Controller:
    """The controller registered as ``name``; ValueError naming the known ones otherwise."""
    try:
        return CONTROLLERS[name]
    except KeyError:
        raise ValueError(f"unknown controller {name!r}; known: {', '.join(NAMES)}") from None
