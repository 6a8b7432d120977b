"""The simulators refuse ``step`` after an episode ended (no reward paid after the end),
and TorchRL's rollout and collector never step an ended episode."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from pilerl_pile_loader.env import PileLoadingEnv
from pilerl_pile_loader.task import ScoopTask
from pilerl_toy_cart.env import MAX_STEPS, ToyCartEnv
from torchrl.collectors import Collector

from pilerl.sim import make_torchrl_env


def step_until_the_end(env, action) -> int:
    steps, ended = 0, False
    while not ended:
        _, _, terminated, truncated, _ = env.step(action)
        ended, steps = terminated or truncated, steps + 1
    return steps


@pytest.mark.parametrize(
    "make_env, action",
    [
        (ToyCartEnv, np.zeros(1, np.float32)),
        (
            lambda: PileLoadingEnv(task=ScoopTask(max_episode_seconds=0.5), control_hz=20.0),
            np.zeros(3, np.float32),
        ),
    ],
    ids=["toy_cart", "pile_loader"],
)
def test_step_after_the_end_is_refused_until_reset(make_env, action):
    env = make_env()
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(action)  # never started
    env.reset(seed=0)
    steps = step_until_the_end(env, action)
    for _ in range(3):  # however often the caller insists: no further step, no reward
        with pytest.raises(RuntimeError, match="episode has ended"):
            env.step(action)
    env.reset(seed=0)
    assert step_until_the_end(env, action) == steps  # a new episode runs as before


def test_toy_cart_truncates_after_its_step_limit():
    env = ToyCartEnv()
    env.reset(seed=1)
    assert step_until_the_end(env, np.zeros(1, np.float32)) == MAX_STEPS


@pytest.mark.parametrize("num_envs", [1, 2])
@pytest.mark.parametrize("break_when_any_done", [True, False])
def test_torchrl_rollouts_never_step_an_ended_episode(num_envs, break_when_any_done):
    """``rollout`` stops (or resets the finished simulators) at the end: no RuntimeError."""
    env = make_torchrl_env("toy_cart", num_envs=num_envs, seed=0)
    steps = 2 * MAX_STEPS + 5
    rollout = env.rollout(steps, break_when_any_done=break_when_any_done)
    done = rollout["next", "done"]
    if break_when_any_done:
        assert done[..., -1, :].any() and rollout.batch_size[-1] <= MAX_STEPS
    else:
        assert rollout.batch_size[-1] == steps and done.sum() >= 2 * num_envs


def test_torchrl_collector_resets_ended_episodes():
    env = make_torchrl_env("toy_cart", seed=0)
    collector = Collector(env, policy=None, frames_per_batch=MAX_STEPS, total_frames=3 * MAX_STEPS)
    ends = 0
    for batch in collector:  # 3 episodes' worth of steps, each ended one reset
        ends += int(batch["next", "done"].sum())
        assert torch.isfinite(batch["next", "reward"]).all()
    collector.shutdown()
    assert ends >= 2
