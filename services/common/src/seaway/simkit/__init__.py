"""The simulation kit: scenarios and their disturbances, the simulated plant and its sensors.

Used by the simulator service and by the in-process closed loop (``seaway_lab``); a boat never runs it.
"""
