"""``run_node``: a node (``seaway.runtime.node``) driven in the clock of its run.

The one entry point of every service's loop: it picks the driver (the lockstep clock for the sim's
node, ``seaway.runtime.lockstep_clock``; a lockstep member; or the wall clock), serves the node's
requests and runs it until the service stops. It sits above the drivers it chooses between, so the
node module and the clock's module need not know of each other's drivers.
"""

from __future__ import annotations

from typing import Any

from seaway.runtime.lockstep_clock import ClockNode, LockstepClock
from seaway.runtime.node import LiveDriver, MemberDriver, Node
from seaway.runtime.stamps import StampGate


def run_node(ctx: Any, node: Node, period_s: float, stamps: StampGate | None = None) -> None:
    """Run ``node`` in the mode of ``ctx``'s run (a ``ServiceContext``): in lockstep the clock (a
    ``ClockNode``: periods of ``period_s``) or a member, else (or a node with no ``member``: of
    the wall clock only, as vehicle_io) on the wall clock every ``period_s`` [s]; its requests
    served in each. Returns when ``ctx.stop`` is set, after the node's ``finish``. The node is
    attached before its requests are served (a handler may ask the driver for the time)."""
    driver: Any
    if ctx.run.lockstep and isinstance(node, ClockNode):
        driver = LockstepClock(ctx.bus, node, period_s, ctx.stop, node.stall_s)
    elif ctx.run.lockstep and node.member is not None:
        driver = MemberDriver(ctx.bus, node, stamps)
    else:
        driver = LiveDriver(ctx, node, period_s)
    node.attach(driver)
    for spec, handler in node.requests().items():
        ctx.bus.queryable(spec, handler)
    if isinstance(driver, MemberDriver):
        driver.run(ctx.stop, ctx.ready)
    elif isinstance(driver, LiveDriver):
        driver.run()
    else:
        ctx.ready()
        try:
            driver.run()
        finally:
            node.finish()
