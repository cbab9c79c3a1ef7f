"""The suite's own scheduler (tests/swarm_schedule.py): at most ``cap`` workers run swarm modules at once."""

from __future__ import annotations

from types import SimpleNamespace

from swarm_schedule import SwarmCapped


class _Worker:
    def __init__(self, name: str) -> None:
        self.name, self.shutting_down, self.queue = name, False, []
        self.gateway = SimpleNamespace(id=name)

    def send_runtest_some(self, indices) -> None:
        self.queue.extend(indices)

    def shutdown(self) -> None:
        self.shutting_down = True


def _config(workers: int):
    option = SimpleNamespace(loadscopereorder=False, tx=[f"{workers}*popen"], dist="loadfile")
    return SimpleNamespace(option=option, getoption=lambda name, default=None: getattr(option, name, default),
                           getvalue=lambda name: getattr(option, name))


def test_no_more_workers_than_the_cap_run_swarm_modules_and_the_rest_is_not_kept_waiting():
    """Four workers, a cap of two, swarm modules first in the order: two workers take swarm modules and
    two the others, never three in swarms; every test is handed out once, and every worker is shut down."""
    modules = [f"tests/swarm{k}.py" for k in range(8)] + [f"tests/plain{k}.py" for k in range(3)]
    collection = [f"{m}::t{j}" for m in modules for j in range(3)]
    sched = SwarmCapped(_config(4), None, swarm=lambda scope: "swarm" in scope, cap=2)
    workers = [_Worker(f"gw{k}") for k in range(4)]
    for w in workers:
        sched.add_node(w)
        sched.add_node_collection(w, collection)
    sched.schedule()
    ran: list[str] = []
    most, turn = 0, 0
    while any(w.queue for w in workers):
        for w in workers[turn:] + workers[:turn]:  # the workers in turn, as if each test took as long
            # an xdist worker runs a test only once it knows the next one, or that it is shut down
            if len(w.queue) > 1 or (w.queue and w.shutting_down):
                ran.append(collection[w.queue[0]])
                sched.mark_test_complete(w, w.queue.pop(0))
                in_swarm = sum(any("swarm" in s and not all(d.values()) for s, d in sched.assigned_work[x].items())
                               for x in workers)
                most = max(most, in_swarm)
                turn = (workers.index(w) + 1) % len(workers)
                break
        else:
            raise AssertionError(f"every worker waits: {[(w.name, w.queue) for w in workers]}")
    assert sorted(ran) == sorted(collection) and most == 2
    assert all(w.shutting_down for w in workers) and sched.tests_finished
