"""Seaway's laboratory: what tests and benchmarks need and a vessel never runs.

* ``closed_loop``: the one in-process closed loop, built from the services' own cores (the
  simulator's ``SimCore``, optionally the estimator's, steered by the controller's core or by the
  shared line-of-sight guidance): the paper's setting and the estimator's benchmark;
* ``fake_autopilot``: a scripted MAVLink autopilot (PX4 or ArduPilot flavoured) for vehicle_io's tests;
* ``responder``: an instant lockstep participant for the simulator's benchmark;
* ``bench``: every ``seaway bench NAME``.

No production module imports this package (``tests/contract/test_keys.py`` checks it).
"""
