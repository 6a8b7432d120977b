"""Test-wide settings: one intra-op thread (2-core machines), and how many worker
processes pytest-xdist starts (``-n auto`` in pyproject.toml).

Rendering is not configured here: the tests run as a new user's shell does, and pilerl
chooses the offscreen backend itself (``pilerl.rendering``).
"""

import os
from pathlib import Path

import pytest
import torch

from pilerl.data import (
    EpisodeStore,
    RecordingPlan,
    build_dataset,
    record_demonstrations,
)
from pilerl.sim import make_gym_env

torch.set_num_threads(1)

# More workers gain little: a test file runs in one worker (--dist loadfile) and the
# longest one (the documents' commands) takes about 6 minutes; each worker holds ~0.4 GB
# and its tests start their own worker pools.
MAX_TEST_WORKERS = 4


def usable_cores() -> int:
    """Cores this process may use: its CPU affinity, capped by a cgroup v2 CPU quota (a
    container started with --cpus=2 on a 64-core host sees 64 CPUs but gets 2)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    try:
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()
        if quota != "max":
            cores = min(cores, max(1, int(quota) // int(period)))
    except (OSError, ValueError):
        pass
    return cores or 1


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per usable core, at most ``MAX_TEST_WORKERS``; none (the
    tests run in this process) for a single test file, where starting workers costs more
    than it saves. ``PYTEST_XDIST_AUTO_NUM_WORKERS`` overrides, as in pytest-xdist."""
    from_env = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if from_env:
        return int(from_env)
    files = {str(arg).split("::")[0] for arg in config.args}
    if len(files) == 1 and next(iter(files)).endswith(".py"):
        return 0
    return min(usable_cores(), MAX_TEST_WORKERS)


@pytest.fixture(scope="session")
def datasets(tmp_path_factory):
    """4 recorded summer demonstrations at 20 Hz as D_I, and 2 winter ones to validate
    (shared by the training and experiment tests)."""
    root = tmp_path_factory.mktemp("bc")
    env = make_gym_env("pile_loader").unwrapped
    stores = {}
    for name, condition, n in (("summer", "summer", 4), ("winter", "winter_c", 2)):
        store = EpisodeStore.create(
            root / name, sensors=env.sensor_units, controls=list(env.control_names)
        )
        plan = RecordingPlan(
            "pile_loader",
            {"condition": condition, "control_hz": 20.0},
            n_episodes=n,
            seed=5,
            expert={"trigger_sensor": "telescope_pressure"},
        )
        record_demonstrations(store, plan, workers=1, progress=False)
        stores[name] = store
    train = build_dataset(
        stores["summer"], root / "d_i", successful_only=False, rate_hz=None, progress=False
    )
    return root, train, stores["winter"].to_tensordict()
