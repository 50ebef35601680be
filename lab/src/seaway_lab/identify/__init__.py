"""``seaway identify``: a vessel model (``seaway.vessel.model``'s parameters) from a recorded run.

* ``manoeuvre``: the scripted thrust sequence (surge steps, turns both ways, spins, coasting), a
  pure function of time;
* ``trace``: what a fit needs from a recording (sensors and thrust commands), and the checks that
  refuse a recording that cannot support a fit;
* ``fit``: the fit itself (numpy only): an equation-error least squares for the start, then an
  output-error refinement, with standard errors, residuals and the dead-zone profile;
* ``sim_run``: the manoeuvre flown on the simulator's core in process, recorded to MCAP;
* ``output``: the vessel file (TOML, with the fit in comments) and the held-out plot;
* ``cli``: the ``seaway identify`` command.

It lives in the lab, not in ``seaway.vessel``: flying the manoeuvre needs the simulator's core
(``seaway_sim``) and reading/writing recordings needs the recorder's package, and the shared library
imports no service. Identification happens on a laptop with a recording, never on the boat.
"""
