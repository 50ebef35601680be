"""Where vehicle_io's udpout socket listens: no more interfaces than the autopilot needs."""

from __future__ import annotations

import pytest
from pydantic import ValidationError
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.link import MavlinkLink, udpout_bind_host


@pytest.mark.parametrize(
    ("autopilot", "host"),
    [
        (("127.0.0.1", 14580), "127.0.0.1"),
        (("127.0.0.5", 14580), "127.0.0.1"),  # all of 127/8 is this machine
        (("192.0.2.7", 14550), "0.0.0.0"),  # a radio modem or companion on the network
        (None, "0.0.0.0"),  # a wildcard or broadcast destination: the answer's source is unknown
    ],
)
def test_default_bind_host(autopilot, host):
    assert udpout_bind_host(autopilot) == host


@pytest.mark.parametrize(
    ("url", "bind_host", "bound"),
    [
        ("udpout:127.0.0.1:14999", None, "127.0.0.1"),
        ("udpout:localhost:14999", None, "127.0.0.1"),
        ("udpout:127.0.0.1:14999", "0.0.0.0", "0.0.0.0"),  # the config can say otherwise
        ("udpout:192.0.2.7:14550", None, "0.0.0.0"),
    ],
)
def test_the_udpout_socket_is_bound_where_the_autopilot_needs(url, bind_host, bound):
    link = MavlinkLink(url, 255, 191, bind_host=bind_host)
    try:
        host, port = link.local_address().rsplit(":", 1)
        assert host == bound and int(port) > 0
    finally:
        link.close()


def test_bind_host_must_be_an_address():
    assert VehicleIoConfig(bind_host="0.0.0.0").bind_host == "0.0.0.0"
    with pytest.raises(ValidationError, match="bind_host"):
        VehicleIoConfig(bind_host="everywhere")
