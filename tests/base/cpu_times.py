"""A pytest plugin that measures each test's CPU time, for comparing the suite's cost
between commits on a loaded machine (wall time there is noise).

    PILERL_CPU_TIMES=cpu.tsv python -m pytest -q -p cpu_times -n 0

appends one line per test to ``cpu.tsv``: node id, CPU seconds (user + system, fixture
setup and teardown included) and wall seconds. The CPU time counts this process, its
children that were waited for (``RUSAGE_CHILDREN``: subprocesses, joined worker pools)
and the growth of its live descendants (``/proc``: worker pools that outlive a test).
Without the variable the plugin records nothing. It works in pytest-xdist's workers too,
but compare files written the same way: workers build the session fixtures once each and
share the cores, so ``-n 0`` (one process) is the comparable setting.
"""

from __future__ import annotations

import os
import resource
import time
from pathlib import Path

import pytest

TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def _descendants(pid: int) -> list[int]:
    found, todo = [], [pid]
    while todo:
        parent = todo.pop()
        try:
            for task in os.listdir(f"/proc/{parent}/task"):
                children = Path(f"/proc/{parent}/task/{task}/children").read_text().split()
                found += [int(c) for c in children]
                todo += [int(c) for c in children]
        except OSError:  # gone meanwhile, or no /proc (not Linux)
            pass
    return found


def _live_cpu_s() -> dict[int, float]:
    """CPU seconds used so far by each live descendant process."""
    used = {}
    for pid in _descendants(os.getpid()):
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            used[pid] = (int(fields[11]) + int(fields[12])) / TICKS_PER_S  # utime, stime
        except (OSError, IndexError, ValueError):
            pass
    return used


def _reaped_cpu_s() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    out = os.environ.get("PILERL_CPU_TIMES")
    if not out:
        yield
        return
    reaped, live, wall = _reaped_cpu_s(), _live_cpu_s(), time.perf_counter()
    yield
    wall = time.perf_counter() - wall
    live_after = _live_cpu_s()
    # live at the end: their growth; live before and gone since: in RUSAGE_CHILDREN once
    # reaped, less what they had used before this test
    grown = sum(s - live.get(p, 0.0) for p, s in live_after.items())
    grown -= sum(s for p, s in live.items() if p not in live_after)
    cpu = _reaped_cpu_s() - reaped + grown
    with open(out, "a") as f:
        f.write(f"{item.nodeid}\t{cpu:.2f}\t{wall:.2f}\n")
