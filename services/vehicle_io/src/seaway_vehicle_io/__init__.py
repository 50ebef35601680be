"""Seaway vehicle I/O: the only process that speaks MAVLink."""
