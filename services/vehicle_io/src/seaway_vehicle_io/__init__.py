"""Seaway vehicle I/O: the only process that speaks MAVLink."""

# Each autopilot profile registers itself in ``profile``'s registry when imported; importing them
# here completes the registry before any other module of the package runs. A new autopilot is a
# new module added to this line.
from seaway_vehicle_io import ardupilot, px4  # noqa: F401
