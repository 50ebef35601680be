"""rmw_zenoh's wire conventions: key expressions, liveliness tokens, the attachment, the QoS chunk.

Followed: rmw_zenoh_cpp as released for ROS 2 Jazzy from 0.2.4 and for Kilted (0.6), the format
after ros2/rmw_zenoh#601 (positional attachment); read from its sources
(``liveliness_utils.cpp``, ``attachment_helpers.cpp``, ``rmw_publisher_data.cpp``,
``type_support_common.hpp``). docs/ros2.md says the same for users.

* A topic's data travels on ``<domain>/<topic without leading or trailing slash>/<type>/<hash>``,
  the type as ``pkg::msg::dds_::Name_`` and the hash ``RIHS01_<hex>`` (``seaway.ros2.types``).
* The graph is liveliness tokens under ``@ros2_lv/<domain>/``: a node's
  ``@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave>/<namespace>/<node>`` and a publisher's
  ``@ros2_lv/<domain>/<zid>/<nid>/<id>/MP/<enclave>/<namespace>/<node>/<topic>/<type>/<hash>/<qos>``;
  every ``/`` inside a name becomes ``%`` (so the root namespace ``/`` is ``%``).
* Each sample's attachment, in zenoh-ext's serialisation: the sequence number (int64, little
  endian), the source timestamp (int64 ns since the Unix epoch, little endian), then the
  publisher's GID as a sequence of 16 bytes (its length as a LEB128 varint, 0x10, then the bytes).
* The QoS chunk names only what differs from ROS's default profile (reliable, volatile, keep last
  10, no deadline, lifespan or liveliness lease): ``::,:,:,:,,`` for the default itself.

The GID, as rmw_zenoh makes it (``Entity::Entity`` in ``liveliness_utils.cpp``): XXH3-128, seed 0,
of the entity's whole liveliness token (``@ros2_lv/...``), its 128-bit value stored as the low 64
bits then the high 64 bits, each in the machine's byte order (little endian on every platform ROS 2
ships for), so the 16 bytes are the value little endian. A ROS 2 tool that compares a sample's GID
with the one it derives from the publisher's token (``ros2 topic info --verbose``) sees the same.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

import xxhash

from seaway.ros2.types import dds_type_name, type_hash

ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
DEFAULT_QOS = "::,:,:,:,,"
"""The QoS chunk of ROS's default profile (rmw_qos_profile_default): reliable, volatile, keep last 10."""
GID_BYTES = 16
ROS_DOMAIN_MAX = 232
"""The largest ROS_DOMAIN_ID (ROS 2's documented range is 0-232 on Linux)."""
DEFAULT_ROUTER = "tcp/127.0.0.1:7447"
"""Where ``ros2 run rmw_zenoh_cpp rmw_zenohd`` listens by default."""
_NAME_RE = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")


class RosNameError(ValueError):
    """A namespace, node or topic name ROS 2 would refuse."""


def check_name(name: str, what: str) -> str:
    """``name`` if ROS 2 accepts it as a ``what`` (letters, digits, underscores; tokens that do not
    start with a digit, separated by ``/``), else RosNameError saying so."""
    if name != "/" and not _NAME_RE.match(name):
        raise RosNameError(f"{what} {name!r} is not a valid ROS 2 name: use letters, digits and "
                           "'_', tokens separated by '/', none starting with a digit")
    return name


def ros_name(text: str) -> str:
    """A Seaway name (a vessel: letters, digits, ``_.-``) as one ROS 2 name token."""
    token = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return token if token[:1].isalpha() or token[:1] == "_" else f"v{token}"


def mangle(name: str) -> str:
    """A name as one key chunk: ``/`` becomes ``%``."""
    return name.replace("/", "%")


def qualify(namespace: str, topic: str) -> str:
    """The fully qualified topic name: ``topic`` if absolute, else under ``namespace``."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def topic_key(domain: int, fq_topic: str, type_name: str) -> str:
    """The key expression a topic's samples travel on."""
    return f"{domain}/{fq_topic.strip('/')}/{dds_type_name(type_name)}/{type_hash(type_name)}"


@dataclass(frozen=True)
class Node:
    """One ROS 2 node on one Zenoh session (``zid``: the session's id as Zenoh prints it)."""

    domain: int
    zid: str
    node_id: int
    namespace: str
    name: str
    enclave: str = "/"

    def __post_init__(self) -> None:
        if not 0 <= self.domain <= ROS_DOMAIN_MAX:
            raise RosNameError(f"ROS domain {self.domain} is outside 0..{ROS_DOMAIN_MAX}")
        check_name(self.namespace, "namespace")
        check_name(self.name, "node name")

    def _prefix(self, entity_id: int, kind: str) -> str:
        return (f"{ADMIN_SPACE}/{self.domain}/{self.zid}/{self.node_id}/{entity_id}/{kind}/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{mangle(self.name)}")

    def token(self) -> str:
        """The node's liveliness token."""
        return self._prefix(self.node_id, NODE)

    def publisher_token(self, entity_id: int, fq_topic: str, type_name: str,
                        qos: str = DEFAULT_QOS) -> str:
        """A publisher's liveliness token: the node's, then topic, type, hash and QoS."""
        return (f"{self._prefix(entity_id, PUBLISHER)}/{mangle(fq_topic)}/"
                f"{dds_type_name(type_name)}/{type_hash(type_name)}/{qos}")

    def subscription_token(self, entity_id: int, fq_topic: str, type_name: str,
                           qos: str = DEFAULT_QOS) -> str:
        return (f"{self._prefix(entity_id, SUBSCRIPTION)}/{mangle(fq_topic)}/"
                f"{dds_type_name(type_name)}/{type_hash(type_name)}/{qos}")


def gid(token: str) -> bytes:
    """The 16-byte GID of the entity whose liveliness token is ``token`` (module docstring)."""
    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_BYTES, "little")


def attachment(sequence: int, source_stamp_ns: int, source_gid: bytes) -> bytes:
    """A sample's attachment: int64 sequence, int64 timestamp [ns], the GID as a sequence."""
    if len(source_gid) != GID_BYTES:
        raise ValueError(f"a GID is {GID_BYTES} bytes, not {len(source_gid)}")
    return struct.pack("<qqB", sequence, source_stamp_ns, GID_BYTES) + source_gid


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence, timestamp [ns], GID) of an attachment; ValueError if it is not one."""
    if len(data) != 17 + GID_BYTES or data[16] != GID_BYTES:
        raise ValueError(f"an rmw_zenoh attachment is {17 + GID_BYTES} bytes with a GID of "
                         f"{GID_BYTES}; got {len(data)} bytes")
    seq, ts = struct.unpack_from("<qq", data)
    return seq, ts, bytes(data[17:])
