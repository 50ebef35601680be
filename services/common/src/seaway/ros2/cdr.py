"""CDR, as ROS 2 puts messages on the wire and in rosbag2: encode and decode ``seaway.ros2.types``.

The format (OMG CDR version 1, "XCDR1", little endian), as rmw_zenoh and rosbag2 use it:

* a 4-byte encapsulation header ``00 01 00 00`` (CDR_LE, options 0);
* then the fields in order; a primitive of n bytes (n = 1, 2, 4, 8) starts at an offset (counted
  from after the header) that is a multiple of n; a nested message has no alignment of its own;
* ``bool``, ``byte``, ``char``, ``int8``, ``uint8``: one byte;
* ``string``: ``uint32`` length including the terminating NUL, the UTF-8 bytes, the NUL;
* a fixed array: its elements; an unbounded sequence: ``uint32`` count, then the elements.

A message value is a ``dict`` of field name to value (nested messages as dicts, arrays and
sequences as lists). Decoding refuses what is not a whole, valid message (``CdrError`` naming
the field), so a malformed payload can be dropped and counted by whoever received it.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from typing import Any

from seaway.ros2.types import Field, get

HEADER_LE = b"\x00\x01\x00\x00"
"""CDR_LE encapsulation, no options."""
_FORMATS: dict[str, str] = {
    "int8": "b", "uint8": "B", "byte": "B", "char": "B", "bool": "?", "int16": "h", "uint16": "H",
    "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d",
}
MAX_SEQUENCE = 1 << 20
"""The longest sequence or string a decoded message may claim (elements or bytes): a corrupt count
must not make the reader allocate gigabytes."""


class CdrError(ValueError):
    """A value that cannot be encoded, or bytes that are not a message of the type; names where."""


class _Writer:
    def __init__(self) -> None:
        self.buf = bytearray()

    def align(self, n: int) -> None:
        self.buf.extend(b"\x00" * (-len(self.buf) % n))

    def primitive(self, kind: str, value: Any, where: str) -> None:
        fmt = _FORMATS[kind]
        size = struct.calcsize(fmt)
        self.align(size)
        try:
            self.buf.extend(struct.pack("<" + fmt, value))
        except (struct.error, TypeError) as err:
            raise CdrError(f"{where}: {value!r} is not a {kind} ({err})") from None

    def string(self, value: Any, where: str) -> None:
        if not isinstance(value, str):
            raise CdrError(f"{where}: {value!r} is not a string")
        data = value.encode()
        self.primitive("uint32", len(data) + 1, where)
        self.buf.extend(data + b"\x00")


def encode(type_name: str, value: Mapping[str, Any]) -> bytes:
    """The CDR bytes (with the encapsulation header) of ``value``, a message of ``type_name``."""
    w = _Writer()
    _write_message(w, type_name, value, type_name.rsplit("/", 1)[-1])
    return HEADER_LE + bytes(w.buf)


def _write_message(w: _Writer, type_name: str, value: Mapping[str, Any], where: str) -> None:
    if not isinstance(value, Mapping):
        raise CdrError(f"{where}: expected a {type_name} (a mapping), got {type(value).__name__}")
    for f in get(type_name).fields:
        if f.name not in value:
            raise CdrError(f"{where}.{f.name}: missing")
        _write_field(w, f, value[f.name], f"{where}.{f.name}")


def _write_one(w: _Writer, f: Field, v: Any, where: str) -> None:
    if f.nested:
        _write_message(w, f.type, v, where)
    elif f.type == "string":
        w.string(v, where)
    else:
        w.primitive(f.type, v, where)


def _write_field(w: _Writer, f: Field, v: Any, where: str) -> None:
    if f.array is None and not f.sequence:
        _write_one(w, f, v, where)
        return
    items = list(v)
    if f.array is not None and len(items) != f.array:
        raise CdrError(f"{where}: {len(items)} elements, the type has exactly {f.array}")
    if f.sequence:
        w.primitive("uint32", len(items), where)
    for i, item in enumerate(items):
        _write_one(w, f, item, f"{where}[{i}]")


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 0

    def take(self, n: int, where: str) -> bytes:
        if self.pos + n > len(self.data):
            raise CdrError(f"{where}: the payload ends at byte {len(self.data)}, "
                           f"{n} more needed at {self.pos}")
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def primitive(self, kind: str, where: str) -> Any:
        fmt = _FORMATS[kind]
        size = struct.calcsize(fmt)
        self.pos += -self.pos % size
        value = struct.unpack("<" + fmt, self.take(size, where))[0]
        if kind == "bool" and value not in (True, False):
            raise CdrError(f"{where}: {value!r} is not a bool")
        return value

    def count(self, where: str) -> int:
        n = self.primitive("uint32", where)
        if n > MAX_SEQUENCE:
            raise CdrError(f"{where}: a length of {n} is beyond {MAX_SEQUENCE}")
        return int(n)

    def string(self, where: str) -> str:
        n = self.count(where)
        if n == 0:
            raise CdrError(f"{where}: a string's length includes its NUL, so it is at least 1")
        raw = self.take(n, where)
        if raw[-1:] != b"\x00":
            raise CdrError(f"{where}: the string does not end in NUL")
        try:
            return raw[:-1].decode()
        except UnicodeDecodeError as err:
            raise CdrError(f"{where}: not UTF-8 ({err})") from None


def decode(type_name: str, data: bytes | bytearray | memoryview) -> dict[str, Any]:
    """The message of ``type_name`` in ``data`` (CDR with its encapsulation header); CdrError if
    the header is not CDR_LE, the bytes end early, or bytes are left over beyond alignment."""
    raw = bytes(data)
    if raw[:2] != HEADER_LE[:2]:
        raise CdrError(f"{type_name}: encapsulation {raw[:4].hex() or 'missing'}, "
                       f"only CDR little endian ({HEADER_LE.hex()}) is read")
    r = _Reader(raw[4:])
    out = _read_message(r, type_name, type_name.rsplit("/", 1)[-1])
    if len(r.data) - r.pos > 3:  # a writer pads to 4 at most
        raise CdrError(f"{type_name}: {len(r.data) - r.pos} bytes left over after the message")
    return out


def _read_message(r: _Reader, type_name: str, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in get(type_name).fields:
        w = f"{where}.{f.name}"
        if f.array is None and not f.sequence:
            out[f.name] = _read_one(r, f, w)
        else:
            n = f.array if f.array is not None else r.count(w)
            out[f.name] = [_read_one(r, f, f"{w}[{i}]") for i in range(n)]
    return out


def _read_one(r: _Reader, f: Field, where: str) -> Any:
    if f.nested:
        return _read_message(r, f.type, where)
    if f.type == "string":
        return r.string(where)
    return r.primitive(f.type, where)
