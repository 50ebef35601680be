"""``seaway study NAME``: a list of independent runs through the real stack in lockstep, composed
in one process per stack (the default) or as its processes (``--processes``).

* ``definitions``: the studies, as data (which scenario, controller and options each run has, and
  where it goes in the table);
* ``execute``: one run (``seaway launch sim-batch [--composed] ...``, then the report of its
  recording) and the ways of running many: shared stacks that fly one run after another
  (``--workers``), a local pool of subprocess launches (``--fresh-stacks``) or a Dask cluster
  (``--dask``); built from ``isolation`` (a rendezvous port and CPUs per stack), ``launcher`` (the
  launcher's command, options and output), ``monitor`` (CPU per process), ``outcome`` (what a run
  gave, its report), ``shared`` (``SharedStack``), ``composed`` (``ComposedStack``, its services as
  nodes of this process) and ``worker`` (a study worker process per composed stack);
* ``results``: the table beside the paper's Table I with the differences in percent, and the
  Markdown, CSV and JSON files;
* ``figures``: trajectories (paper Fig. 5), thrusts (Fig. 4) and the T^w sweep, from the recordings;
* ``cli``: the command.
"""
