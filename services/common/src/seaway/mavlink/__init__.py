"""MAVLink as the simulator and vehicle_io both speak it, on raw frame bytes (no pymavlink here):
``wire`` (the frame layout: magic bytes, header, CRC and signature block, the ids a frame claims)
and ``signing`` (MAVLink 2 signing: key files, timestamps, the check of an incoming signature).
"""
