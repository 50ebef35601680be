"""The plant's RK4 substeps compiled: ``seaway.vessel.model.rk4_step`` generated as C, many at once.

The plant (``seaway.simkit.plant``) integrates the vessel at ``internal_dt_s`` (10 ms), ten RK4
steps a control period, each as Python floats. Where nothing in a step depends on the state but the
model itself (no thruster fault or grounding, no thruster lag, no disturbance field that varies with
position), the inputs of every substep are known before the first: the held thrust, the step and the
disturbance sampled at each substep's time. ``Substeps`` then integrates them in one call of
compiled C instead of one Python ``rk4_step`` per substep.

The expressions are ``model.rk4_step`` evaluated on CasADi symbols (``seaway.vessel.native``), so
the model is written once. The operations are those Python performs on floats, in the same order,
compiled without contraction into fused multiply-adds and with the same libm, so the states are
the same floats, bit for bit (the paper's table is reproduced to the digit; a test compares the two
paths). Without CasADi or a C compiler the plant keeps its Python steps (``Substeps.make`` is None).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from seaway.vessel import model
from seaway.vessel.model import NX, VesselParams

log = logging.getLogger(__name__)

MAX_SUBSTEPS = 10
"""Substeps one call integrates (a longer step is cut into calls of at most this many): a control
period of 100 ms at 10 ms. A call always computes all of them; the ones past a step's own count
cost a fraction of a microsecond each and are not read."""
NU = 10
"""Inputs of one substep: thrust port, starboard [N], h [s], tau_body (surge, sway [N], yaw [N m]),
world force (north, east [N]), current (north, east [m/s])."""


def substeps_function(p: VesselParams):  # -> casadi.Function (casadi is imported only here)
    """``steps(x0[6], U[NU x MAX_SUBSTEPS]) -> X[6 x MAX_SUBSTEPS]``: column k is the state after
    substep k, each one ``model.rk4_step`` with column k of ``U`` held."""
    import casadi as ca

    x, u = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    xl = [x[i] for i in range(NX)]
    nxt = model.rk4_step(xl, [u[0], u[1]], u[2], p, ca, [u[3], u[4], u[5]], [u[6], u[7]],
                         [u[8], u[9]])
    one = ca.Function("seaway_plant_substep", [x, u], [ca.vertcat(*nxt)])
    return one.mapaccum("seaway_plant_substeps", MAX_SUBSTEPS)


class Substeps:
    """``substeps_function`` of one vessel, compiled, with its buffers."""

    def __init__(self, fn: object) -> None:
        self._fn = fn
        self._x, self._u = fn.inputs  # type: ignore[attr-defined]
        (self._out,) = fn.outputs  # type: ignore[attr-defined]

    @classmethod
    def make(cls, p: VesselParams) -> Substeps | None:
        """The compiled substeps of vessel ``p``, or None (no CasADi, no C compiler: the plant
        steps in Python, the same numbers)."""
        try:
            from seaway.vessel.native import NativeFunction
        except ImportError:
            return None
        fn = NativeFunction(substeps_function(p))
        return cls(fn) if fn.compiled else None

    def run(self, x: Sequence[float], inputs: list[float], n: int) -> list[float]:
        """The state after the first ``n`` (<= MAX_SUBSTEPS) substeps from ``x``; ``inputs`` is
        their ``NU`` inputs each, one substep after the other (n x NU values)."""
        self._x[:] = x
        self._u[:len(inputs)] = inputs
        self._fn()  # type: ignore[operator]
        return self._out[NX * (n - 1):NX * n].tolist()
