"""What vehicle_io's core hears the time as and says back: ``Now`` and the outputs the loop performs.

``Now`` carries both clocks [ns]: ``wall_ns`` (Unix epoch) stamps messages, ``mono_ns``
(monotonic) measures every timeout. The outputs are performed in order by the node (``node.py``):
``Send*`` go to the autopilot as MAVLink (ids as MAVLink numbers them, parameters in the command's
own units), ``Publish`` goes to the bus, ``LockPeer`` tells the link which peer to hear. The
outputs of the parts the core drives (the fence sync, the events channel, the component metadata
fetch) are defined beside those parts and gathered into ``Output`` here.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.contract.messages import Message

from seaway_vehicle_io.authority import Address
from seaway_vehicle_io.component_metadata import SendFileTransfer, SendRequestMessage
from seaway_vehicle_io.events_channel import SendRequestEvent
from seaway_vehicle_io.fence_sync import FenceOutput
from seaway_vehicle_io.profile import ManualControlAxes


@dataclass(frozen=True)
class Now:
    """The two clocks the loop passes in [ns]."""

    wall_ns: int
    mono_ns: int


# -- outputs ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SendHeartbeat:
    """Our 1 Hz HEARTBEAT (as a GCS-type component)."""


@dataclass(frozen=True)
class SendManualControl:
    target_system: int
    axes: ManualControlAxes
    neutral: bool


@dataclass(frozen=True)
class SendCommandLong:
    target_system: int
    target_component: int
    command: int
    confirmation: int
    params: tuple[float, float, float, float, float, float, float]


@dataclass(frozen=True)
class SendParamRequestRead:
    target_system: int
    target_component: int
    param_id: str


@dataclass(frozen=True)
class SendRequestDataStream:
    """REQUEST_DATA_STREAM (start): the stream-rate fallback of the rate request (``rates.py``)."""

    target_system: int
    target_component: int
    stream_id: int
    rate_hz: int


@dataclass(frozen=True)
class Publish:
    message: Message


@dataclass(frozen=True)
class LockPeer:
    """Tell the link which peer address the autopilot is at (None: the lock is released), so it can
    refuse other datagrams before parsing them (cheap enough to outrun a flood) and, listening
    (udpin), answer the autopilot only."""

    address: Address


Output = (SendHeartbeat | SendManualControl | SendCommandLong | SendParamRequestRead
          | SendRequestDataStream | SendRequestMessage | SendFileTransfer | SendRequestEvent
          | Publish | LockPeer | FenceOutput)


# -- state pieces ---------------------------------------------------------------------------------
