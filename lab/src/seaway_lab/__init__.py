"""Seaway's laboratory: what tests and benchmarks need and a vessel never runs.

* ``closed_loop``: the in-process closed loop (plant, sensors, estimator, controller), the paper's
  setting and the estimator's benchmark, built from the same parts as the services;
* ``fake_autopilot``: a scripted MAVLink autopilot (PX4 or ArduPilot flavoured) for vehicle_io's tests;
* ``responder``: an instant lockstep participant for the simulator's benchmark;
* ``bench``: every ``seaway bench NAME``.

No production module imports this package (``tests/contract/test_keys.py`` checks it).
"""
