"""A pytest-xdist scheduler that caps how many workers run swarm tests at once (tests/conftest.py)."""

from __future__ import annotations

from typing import Callable

from xdist.scheduler import LoadFileScheduling


class SwarmCapped(LoadFileScheduling):
    """``--dist loadfile`` (a module whole to one worker, in collection order), except that a worker is
    handed a module that ``swarm(scope)`` calls a swarm module only while fewer than ``cap`` other workers
    still have tests of one to run; until then it takes the first other module, or waits. A worker that
    waits (holding back its last test, as a pytest-xdist worker does until it knows what comes next) is
    offered work again whenever any test ends. A worker that holds a swarm module is never the one kept
    waiting, so the swarm modules always go on."""

    def __init__(self, config, log, swarm: Callable[[str], bool], cap: int) -> None:
        super().__init__(config, log)
        self.swarm, self.cap = swarm, max(cap, 1)

    def _holds_swarm(self, node) -> bool:
        return any(self.swarm(scope) and not all(done.values())
                   for scope, done in self.assigned_work.get(node, {}).items())

    def _assign_work_unit(self, node) -> None:
        busy = sum(self._holds_swarm(other) for other in self.nodes if other is not node)
        scope = next((s for s in self.workqueue if busy < self.cap or not self.swarm(s)), None)
        if scope is None:
            return  # only swarm modules are left, and the cap's workers hold some: wait for one to end
        self.workqueue.move_to_end(scope, last=False)
        super()._assign_work_unit(node)

    def mark_test_complete(self, node, item_index: int, duration: float = 0) -> None:
        super().mark_test_complete(node, item_index, duration)
        for other in self.nodes:
            if other is not node:
                self._reschedule(other)  # a worker with more than two tests to go is left as it is
