"""A service's configuration, one way for every back-end service: a model, a file, flags.

Each service declares its settings once, as one ``ConfigModel`` subclass in its ``config.py``
(typed, SI units in the names, a description per field, bounds as pydantic constraints). The value
a process runs with comes from, in order, each later one overriding single fields:

1. the model's defaults;
2. ``--config FILE`` (TOML or JSON; for the estimator and vehicle_io also the name of a file
   shipped in the service's ``config/`` folder); an unknown field is an error naming it;
3. the command-line flags the model marks with ``Flag`` (a list given as flags replaces the file's).

The flags are made from the fields (``service_parser``): ``state_file`` becomes ``--state-file``
(``Flag("--other")`` keeps an older name), the help is the field's description, a number is
checked against the field's bounds as argparse parses it (``seaway.runtime.argtypes``: a bad one
stops the process with one line naming the flag and what is allowed, exit status 2), a ``Literal``
gives the choices, a bool with default False is a ``--flag`` that sets it (default True:
``--no-flag`` clears it), a list is a repeatable flag. What the model checks across fields comes
after parsing; its errors name the flag (or the file and field) too (``parse_service_args``).

Not settings of a service, so outside its model: the flags every service takes from
``seaway.runtime.service.base_parser`` (``--vessel``, ``--zenoh-config``, ``--credentials``,
``--log-level``) and the run's (``--run``, ``--scenario``, ``--vessel-file``,
``--plant-vessel-file``, ``--control-period-s``, ``--origin``, ``--lockstep``, ``--dead-zone``:
``seaway.runtime.run``), which every process of a run must agree on.
"""

from __future__ import annotations

import argparse
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar

import annotated_types
from pydantic import ValidationError
from pydantic.fields import FieldInfo

from seaway.contract.config import ConfigError, ConfigModel, named_file, parse_config, read_document
from seaway.runtime.argtypes import finite_number, whole_number
from seaway.runtime.service import base_parser

C = TypeVar("C", bound=ConfigModel)

CONFIG_DEST = "config"
"""Where ``--config`` lands in the parsed arguments."""


@dataclass(frozen=True)
class Flag:
    """Marks a config field as a command-line flag too: ``Annotated[float, Flag()]``.

    ``name``: the flag (default ``--`` and the field's name with dashes); ``metavar``: how help
    shows its value; ``parse``: a converter of the flag's text, for a value the field's type
    cannot read from one word (e.g. a size with a unit), instead of the one made from its type."""

    name: str | None = None
    metavar: str | None = None
    parse: Callable[[str], Any] | None = None


@dataclass(frozen=True)
class FlagSpec:
    """One flag made from one field."""

    field: str
    option: str
    info: FieldInfo
    flag: Flag


def flag_of(info: FieldInfo) -> Flag | None:
    """The field's ``Flag`` (None: it is set in the file only)."""
    return next((m for m in info.metadata if isinstance(m, Flag)), None)


def flags_of(model: type[ConfigModel]) -> list[FlagSpec]:
    """The model's flagged fields, in declaration order."""
    out = []
    for name, info in model.model_fields.items():
        flag = flag_of(info)
        if flag is not None:
            off = _bare(info.annotation) is bool and info.default is True
            option = flag.name or ("--no-" if off else "--") + name.replace("_", "-")
            out.append(FlagSpec(name, option, info, flag))
    return out


def _bare(annotation: Any) -> Any:
    """``X`` of ``X | None``."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return annotation


def _bound(info: FieldInfo, kind: type) -> Any:
    return next((getattr(m, kind.__name__.lower()) for m in info.metadata if isinstance(m, kind)),
                None)


def _converter(spec: FlagSpec, kind: Any) -> Callable[[str], Any]:
    """The argparse ``type`` of one value of the field: its bounds checked as it is parsed."""
    info = spec.info
    gt, ge, lt, le = (_bound(info, k) for k in (annotated_types.Gt, annotated_types.Ge,
                                                annotated_types.Lt, annotated_types.Le))
    if kind is int:
        low = ge if ge is not None else (gt + 1 if gt is not None else None)
        high = le if le is not None else (lt - 1 if lt is not None else None)
        if low is None:
            raise TypeError(f"{spec.option}: an int flag needs a lower bound (ge or gt)")
        return whole_number(low, high)
    if kind is float:
        return finite_number(gt=gt, ge=ge, lt=lt, le=le)
    if kind in (str, Path):
        return kind
    raise TypeError(f"{spec.option}: no flag for a field of type {kind!r} (give Flag(parse=...))")


def _add(group: argparse._ArgumentGroup, spec: FlagSpec) -> None:
    info, flag = spec.info, spec.flag
    if not (info.description and info.description.strip()):
        raise TypeError(f"{spec.option}: the field {spec.field} has no description (its help)")
    default = info.get_default(call_default_factory=True)
    help_text = info.description
    kind = _bare(info.annotation)
    kw: dict[str, Any] = {"dest": spec.field, "default": argparse.SUPPRESS}
    if kind is bool:
        if default:
            help_text = f"turns off (on by default): {help_text}"
        group.add_argument(spec.option, action="store_false" if default else "store_true",
                           help=help_text, **kw)
        return
    kw["metavar"] = flag.metavar or spec.option.removeprefix("--").upper().replace("-", "_")
    if default not in (None, "", [], ()) and "default" not in help_text.lower():
        help_text += f" (default {default:g})" if isinstance(default, float) else f" (default {default})"
    if typing.get_origin(kind) is list:
        (item,) = typing.get_args(kind)
        group.add_argument(spec.option, action="append", type=flag.parse or _converter(spec, item),
                           help=help_text + " (repeatable)", **kw)
    elif typing.get_origin(kind) is Literal:
        del kw["metavar"]  # argparse shows the choices
        group.add_argument(spec.option, choices=typing.get_args(kind), type=flag.parse,
                           help=help_text, **kw)
    else:
        group.add_argument(spec.option, type=flag.parse or _converter(spec, kind), help=help_text,
                           **kw)


def add_config_options(p: argparse.ArgumentParser, model: type[ConfigModel],
                       shipped: Path | None = None) -> None:
    """``--config FILE`` and one flag per flagged field of ``model``; ``shipped``: the folder of
    the service's named config files (``--config NAME`` means ``shipped/NAME.toml``)."""
    g = p.add_argument_group("configuration (the defaults, then --config FILE, then these flags)")
    where = f" or the name of one in {_shown(shipped)} (e.g. {_example(shipped)})" if shipped else ""
    g.add_argument("--config", dest=CONFIG_DEST, default=None, metavar="FILE",
                   help=f"config file (.toml or .json){where}; its fields are those of "
                        f"{model.__name__}, unknown ones are errors")
    for spec in flags_of(model):
        _add(g, spec)


def _shown(folder: Path) -> str:
    parts = folder.parts
    return "/".join(parts[parts.index("services"):]) + "/" if "services" in parts else str(folder)


def _example(folder: Path) -> str:
    names = sorted(p.stem for p in folder.glob("*.toml"))
    return names[0] if names else "NAME"


def service_parser(name: str, description: str, model: type[ConfigModel], *,
                   shipped: Path | None = None, prog: str | None = None) -> argparse.ArgumentParser:
    """A back-end service's command line: ``base_parser``'s flags (vessel, bus, credentials, log
    level, the run's) and its configuration's (``add_config_options``)."""
    p = base_parser(name, description, prog)
    p.set_defaults(_config_model=model, _config_shipped=shipped, _config_what=f"{name} config")
    add_config_options(p, model, shipped)
    return p


def config_file(args: argparse.Namespace, shipped: Path | None = None) -> Path | None:
    """The ``--config`` file's path (None: none given); ConfigError for an unknown shipped name."""
    text = getattr(args, CONFIG_DEST, None)
    if not text:
        return None
    if shipped is None:
        return Path(text)
    what = getattr(args, "_config_what", "config")
    return named_file(shipped, text, what, _shown(shipped))


def config_of(args: argparse.Namespace, model: type[C], shipped: Path | None = None) -> C:
    """The configuration: ``model``'s defaults, then ``--config``'s file, then the flags given.

    ConfigError: a bad file names the file and its field, a bad flag the flag; a check across
    fields names the fields (and the flags that set them)."""
    shipped = getattr(args, "_config_shipped", shipped)
    path = config_file(args, shipped)
    doc: dict[str, Any] = {}
    cfg = None
    if path is not None:
        doc = read_document(path)
        cfg = parse_config(doc, model, str(path))
    specs = {s.field: s for s in flags_of(model)}
    given = {f: getattr(args, f) for f in specs if hasattr(args, f)}
    if not given:
        return cfg if cfg is not None else parse_config({}, model, "defaults")
    try:
        return model.model_validate({**doc, **given})
    except ValidationError as err:
        raise ConfigError(_flag_errors(err, specs, given, path)) from None


def _flag_errors(err: ValidationError, specs: dict[str, FlagSpec], given: dict[str, Any],
                 path: Path | None) -> str:
    lines = []
    for e in err.errors():
        loc = [str(p) for p in e["loc"]]
        msg = e["msg"].removeprefix("Value error, ")
        if loc and loc[0] in given:
            lines.append(f"argument {specs[loc[0]].option}: {msg}")
        elif loc:
            lines.append(f"{path or 'config'}: {'.'.join(loc)}: {msg}")
        else:
            flags = ", ".join(specs[f].option for f in given)
            lines.append(f"{msg} (with {flags}{f' and {path}' if path else ''})")
    return "; ".join(lines)


def parse_service_args(parser: argparse.ArgumentParser, argv: Sequence[str] | None,
                       model: type[C] | None = None) -> tuple[argparse.Namespace, C]:
    """Parse a ``service_parser``'s command line and make the configuration (``config_of``).

    A bad value ends the process as argparse does: one line ``<prog>: error: ...`` naming the flag
    (or the file and field) and what is allowed, exit status 2."""
    args = parser.parse_args(list(argv) if argv is not None else None)
    model = model or args._config_model
    try:
        return args, config_of(args, model)
    except ConfigError as err:
        parser.exit(2, f"{parser.prog}: error: {err}\n")
    raise AssertionError("unreachable")  # parser.exit raises SystemExit

