"""A lockstep answer on the wire: the ``PeriodDone`` and the messages it lists, in one sample.

In lockstep (``seaway.runtime.lockstep``) each member publishes exactly one sample per period, on
``seaway/<vessel>/lockstep/<service>``: its *bundle*. The bundle is JSON Lines (UTF-8, ``\\n``
between lines, no newline inside a line: compact JSON escapes it):

* the first line is the member's ``PeriodDone`` (its answer), exactly as it would be sent alone;
* then one line per message the answer lists (``PeriodDone.published``), in the order the member
  published them, each ``["<key suffix>",<the message's JSON>]``, the message's bytes unchanged:
  a recorder writes them on their own key's channel as if they had been sent alone.

Why one sample: each sample a process hears costs it a hand-over from Zenoh's thread to Python,
and that per-sample cost, not the bytes, is most of what hearing a period's messages costs. So a
lockstep period is one sample per member, and
the messages reach everybody who hears the answer together with it: nothing listed can be missing.

Real time publishes every message on its own key, as does any process that is not a lockstep member.
``Bus.subscribe`` of a key also takes it out of its producer's bundles (``bundled_by``), so a
subscriber never needs to know which way it came.

Authority: Zenoh's access control lets only a member publish its own bundle key; a bundle may carry
only keys that member produces (``bundled_by(spec) == service``): ``unpack`` and ``check_line``
refuse any other line, and ``Bus.subscribe`` takes from a member's bundles only that member's keys,
so a member cannot publish another's key by wrapping it.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple

from seaway.contract import keys
from seaway.contract.messages import (
    JSON_ENCODING,
    LOCKSTEP_SERVICES,
    Message,
    MessageError,
    PeriodDone,
)

ENCODING = f"application/jsonl;{PeriodDone.SCHEMA}"
"""The Zenoh encoding of a bundle: JSON Lines whose first line is a ``PeriodDone``."""

BUNDLERS = ("sim", "estimator", "controller")
"""The members whose bundles carry messages (the recorder's answer lists nothing)."""
assert set(BUNDLERS) < set(LOCKSTEP_SERVICES)

_STAND_INS = {"replay": "sim"}
"""A replay stands in for the sim in lockstep (``seaway replay --lockstep`` publishes its bundles)."""


def _bundler(spec: keys.KeySpec) -> str | None:
    if spec.kind != "topic" or spec.message is PeriodDone:
        return None
    for producer in spec.producers:
        member = _STAND_INS.get(producer, producer)
        if member in BUNDLERS:
            return member
    return None


_BUNDLED_BY: dict[str, str] = {s.suffix: b for s in keys.REGISTRY if (b := _bundler(s)) is not None}


def bundled_by(spec: keys.KeySpec) -> str | None:
    """The lockstep member whose bundle carries ``spec`` in lockstep (``sensors/gnss``: the sim),
    or None for a key no bundle carries (requests, the recorder's log lines, lockstep answers)."""
    return _BUNDLED_BY.get(spec.suffix)


def suffixes_of(service: str) -> frozenset[str]:
    """The key suffixes ``service``'s bundle may carry."""
    return frozenset(s for s, b in _BUNDLED_BY.items() if b == service)


def encode(answer: bytes, lines: Iterable[tuple[str, bytes]]) -> bytes:
    """A bundle from an answer's bytes and its messages' (key suffix, bytes), in publishing order."""
    return b"\n".join([answer, *(_framed(suffix, data) for suffix, data in lines)])


def _framed(suffix: str, data: bytes) -> bytes:
    """One message line, ``["<key suffix>",<the message's JSON>]``."""
    return b'["' + suffix.encode() + b'",' + data + b"]"


class Carried(NamedTuple):
    """What a bundle was encoded from, handed along with its bytes on an in-process bus
    (``seaway.runtime.bus_raw.RawSample.carried``): its answer and its messages, in line order, and
    the bytes ``encode`` joined (the answer's, and each line's key suffix and message), so that
    nobody in the process splits the bundle's bytes again."""

    answer: PeriodDone
    messages: tuple[Message, ...]
    answer_bytes: bytes
    lines: tuple[tuple[str, bytes], ...]

    @classmethod
    def of(cls, answer: PeriodDone, answer_bytes: bytes, lines: Sequence[tuple[str, bytes]],
           messages: Sequence[Message]) -> tuple[bytes, Carried]:
        """(the bundle's bytes, what it carries) of an answer and its messages' lines."""
        lines = tuple(lines)
        return encode(answer_bytes, lines), cls(answer, tuple(messages), answer_bytes, lines)


def carried_answer(carried: Any) -> PeriodDone | None:
    """The answer ``carried`` holds if it is a bundle's (``Carried``), else None (decode the bytes)."""
    return carried.answer if type(carried) is Carried else None


def parts(payload: bytes, carried: Any = None) -> tuple[bytes, Sequence[tuple[str, bytes]]]:
    """``split`` of ``payload``, or the parts ``carried`` holds if it is what the bundle was
    encoded from (``Carried``): the same bytes, framed by ``encode`` itself."""
    if type(carried) is Carried:
        return carried.answer_bytes, carried.lines
    return split(payload)


def carried_lines(payload: bytes, carried: Any, suffixes: Iterable[str] | None = None
                  ) -> list[tuple[str, bytes, Message]] | None:
    """(key suffix, bytes, message) of ``payload``'s lines (on ``suffixes``, default all), each
    with the message it was encoded from, if ``carried`` is what the bundle was encoded from
    (``Carried``); else None: decode the lines' bytes. Which keys a member may carry is the
    caller's to ask."""
    if type(carried) is not Carried:
        return None
    wanted = None if suffixes is None else frozenset(suffixes)
    return [(suffix, data, msg) for (suffix, data), msg in zip(carried.lines, carried.messages,
                                                                strict=True)
            if wanted is None or suffix in wanted]


def answer_of(payload: bytes) -> bytes:
    """The answer's bytes of a bundle (its first line), unchecked: for a reader that wants only the
    answer (``PeriodDone.decode`` reads the same line)."""
    return payload.split(b"\n", 1)[0]


_RESENT_TAIL = (b',"resent":false}', b',"resent":true}')
"""How ``PeriodDone.encode`` ends an answer: ``resent`` is its last field, written compactly."""


def is_resent(payload: bytes, carried: Any = None) -> bool:
    """Whether a bundle is a copy of an earlier one sent again for a restarted recorder
    (``PeriodDone.resent``): news to a recorder that may have missed it, to nobody else.

    Asked of every bundle a recorder or display hears, so decoding the answer for it would cost:
    it agrees with the decoded field, read cheaply where it can be. An answer ending as
    ``PeriodDone.encode`` ends one (``_RESENT_TAIL``) has it as its last top-level key, which is
    the one a decoder keeps; one with no ``resent`` and no escape that could spell it has the
    default (False). Anything else (another encoder's spacing, the word inside another field, a
    repeated key) is decoded, as members decode it; an answer that does not decode is no copy.
    In process, the answer ``carried`` holds is read."""
    if type(carried) is Carried:
        return carried.answer.resent
    line = answer_of(payload)
    if line.endswith(_RESENT_TAIL[0]):
        return False
    if line.endswith(_RESENT_TAIL[1]):
        return True
    if b"resent" not in line and b"\\" not in line:
        return False
    try:
        return PeriodDone.decode(line).resent
    except MessageError:
        return False


def _line(line: bytes) -> tuple[str, bytes] | None:
    """(key suffix, message bytes) of one message line ``["<suffix>",{...}]``, or None if it is not
    framed so. The one place that knows a line's framing."""
    end = line.find(b'",', 2)
    if not (line.startswith(b'["') and end > 2 and line.endswith(b"}]")):
        return None
    return line[2:end].decode("ascii", "replace"), line[end + 2:-1]


def split(payload: bytes) -> tuple[bytes, list[tuple[str, bytes]]]:
    """(the answer's bytes, [(key suffix, message bytes)]) of a bundle; a lone ``PeriodDone`` is a
    bundle of one line. Checks the framing only (each line ``["suffix",{...}]``); MessageError
    naming the line otherwise. The messages themselves are decoded by whoever needs them."""
    answer, *rest = payload.split(b"\n")
    lines = []
    for i, raw in enumerate(rest, start=2):
        line = _line(raw)
        if line is None:
            raise MessageError(f"lockstep bundle line {i}: not [\"<key suffix>\",{{...}}]: "
                               f"{raw[:80]!r}")
        lines.append(line)
    return answer, lines


def check_line(service: str, suffix: str) -> keys.KeySpec:
    """The spec of a line of ``service``'s bundle; MessageError if ``service`` may not bundle it."""
    spec = keys.spec_for_suffix(suffix)
    if spec is None or _BUNDLED_BY.get(suffix) != service:
        allowed = ", ".join(sorted(suffixes_of(service))) or "none"
        raise MessageError(f"lockstep bundle of {service} carries {suffix!r}, which it does not "
                           f"produce (its keys: {allowed})")
    return spec


@functools.lru_cache(maxsize=1024)
def service_of(key: str) -> str | None:
    """The member whose bundle key ``key`` is (``seaway/<vessel>/lockstep/<service>``), else None."""
    parts = key.split("/")
    if len(parts) == 4 and parts[0] == keys.ROOT and parts[2] == "lockstep" \
            and parts[3] in LOCKSTEP_SERVICES:
        return parts[3]
    return None


def unpack(key: str, payload: bytes, carried: Any = None,
           foreign: list[tuple[str, bytes, str]] | None = None) -> list[tuple[str, bytes, str]]:
    """A bundle heard on ``key`` as the samples it stands for, (key, bytes, encoding): its messages
    in order, each on its own key, then the answer alone (it was sent after what it lists). What a
    recorder writes. MessageError if a line is badly framed, or (without ``foreign``) on a key of
    another member (``check_line``). ``foreign``: where such a line goes instead, as (key suffix,
    the line's bytes, why), the rest unpacked as if it were not there: what a member does with it
    (it drops the line and takes the rest), so a recorder writes what the members took.
    ``carried``: as ``parts`` takes it."""
    service = service_of(key)
    if service is None:
        raise MessageError(f"{key} is not a lockstep answer key")
    answer, lines = parts(payload, carried)
    vessel_prefix = key[: -len(f"lockstep/{service}")]
    out = []
    for suffix, data in lines:
        encoding = _LINE_ENCODINGS.get((service, suffix))
        if encoding is None:
            try:
                spec = check_line(service, suffix)
            except MessageError as err:
                if foreign is None:
                    raise
                foreign.append((suffix, _framed(suffix, data), str(err)))
                continue
            encoding = _LINE_ENCODINGS[(service, suffix)] = \
                f"{JSON_ENCODING};{spec.message.SCHEMA}"  # type: ignore[union-attr]
        out.append((vessel_prefix + suffix, data, encoding))
    out.append((key, answer, _ANSWER_ENCODING))
    return out


_LINE_ENCODINGS: dict[tuple[str, str], str] = {}
"""(member, key suffix) -> the Zenoh encoding of its line's message, once ``check_line`` let it:
``unpack`` runs for every bundle a recorder hears."""
_ANSWER_ENCODING = f"{JSON_ENCODING};{PeriodDone.SCHEMA}"


def lines_of(payload: bytes, suffixes: Sequence[str] | frozenset[str]) -> list[tuple[str, bytes]]:
    """The (suffix, bytes) of ``payload``'s lines on ``suffixes``, skipping any that is not framed
    (a display looking for a few keys in hundreds of bundles a second: its decode of what it takes
    validates that). Which keys a member may carry is the caller's to ask (``check_line``)."""
    out = []
    for raw in payload.split(b"\n")[1:]:
        line = _line(raw)
        if line is not None and line[0] in suffixes:
            out.append(line)
    return out
