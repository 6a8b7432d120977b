"""A cloned DANNet fills the bucket in the summer simulator (short closed-loop check)."""

from __future__ import annotations

import gymnasium as gym
import torch
from tensordict import TensorDict

import pilerl  # noqa: F401
from pilerl.data import EpisodeStore, RecordingPlan, build_dataset, record_demonstrations
from pilerl.policies import make_actor
from pilerl.sim import get_simulator
from pilerl.training import BCSettings, train_bc

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]


def test_cloned_dannet_succeeds_in_summer(tmp_path):
    plugin = get_simulator("pile_loader")
    store = EpisodeStore.create(
        tmp_path / "raw", sensors=plugin.sensor_units, controls=list(plugin.controls)
    )
    # the main job's 30 demonstrations: 12 left a clone that lifts before the pile
    plan = RecordingPlan(
        "pile_loader", {"condition": "summer", "control_hz": 20.0}, n_episodes=30, seed=11
    )
    record_demonstrations(store, plan, workers=2, progress=False)
    d_ii = build_dataset(
        store, tmp_path / "d_ii", successful_only=True, rate_hz=None, progress=False
    )
    assert len(d_ii) >= 4  # enough successful demonstrations to learn from
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=d_ii.stats)
    actor, _ = train_bc(actor, d_ii.to_tensordict(), None, BCSettings(epochs=40), progress=False)
    fills, successes = [], 0
    for seed in range(4):
        sim = gym.make("pilerl/PileLoading-v0", condition="summer")
        obs, _ = sim.reset(seed=1000 + seed)
        while True:
            with torch.no_grad():
                action = actor(TensorDict({k: torch.as_tensor(v) for k, v in obs.items()}, []))
            obs, _, terminated, truncated, info = sim.step(action["action"].numpy())
            if terminated or truncated:
                break
        fills.append(info["fill_fraction"])
        successes += info["success"]
    assert successes >= 3, fills
