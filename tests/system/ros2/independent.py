"""The test's own ROS 2 side, written from rmw_zenoh's documented format (docs/design.md of
ros2/rmw_zenoh) with the zenoh Python API and ``rosbags``' type store, never with ``seaway.ros2``:
the independent client both ROS 2 system tests use."""

from __future__ import annotations

import zenoh


def dds_name(ros_type: str) -> str:
    """rmw_zenoh's type name in keys and tokens: ``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_``."""
    pkg, sub, name = ros_type.split("/")
    return f"{pkg}::{sub}::dds_::{name}_"


def ros_peer(port: int) -> zenoh.Session:
    """A Zenoh peer listening on ``port`` of loopback, as rmw_zenohd's router would be for the
    bridge to connect to (multicast scouting off, as rmw_zenoh's default session config has it)."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{port}"]')
    return zenoh.open(conf)
