"""Test-wide settings: one intra-op thread (2-core machines).

Rendering is not configured here: the tests run as a new user's shell does, and pilerl
chooses the offscreen backend itself (``pilerl.rendering``).
"""

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
