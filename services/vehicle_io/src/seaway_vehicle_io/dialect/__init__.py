"""MAVLink messages vehicle_io needs that pymavlink's dialects lack (``events.xml``).

``events.py`` is generated, not written: after changing ``events.xml`` run::

    python -m seaway_vehicle_io.dialect

``seaway_vehicle_io.mav`` adds these messages to the dialect it decodes with.
"""
