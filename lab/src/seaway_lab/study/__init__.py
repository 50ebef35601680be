"""``seaway study NAME``: a list of independent runs through the real processes in lockstep.

* ``definitions``: the studies, as data (which scenario, controller and options each run has, and
  where it goes in the table);
* ``execute``: one run (``seaway launch sim-batch ...`` on its own Zenoh rendezvous port, then the
  report of its recording) and the two ways of running many: a local pool of subprocess launches
  (``--workers``) or a Dask cluster (``--dask``), or shared stacks that fly one run after another;
  built from ``isolation`` (a rendezvous port and CPUs per stack), ``launcher`` (the launcher's
  command, options and output), ``monitor`` (CPU per process), ``outcome`` (what a run gave, its
  report) and ``shared`` (``SharedStack``);
* ``results``: the table beside the paper's Table I with the differences in percent, and the
  Markdown, CSV and JSON files;
* ``figures``: trajectories (paper Fig. 5), thrusts (Fig. 4) and the T^w sweep, from the recordings;
* ``cli``: the command.
"""
