"""A batched env's simulators step exactly as each alone: observations, rewards and every
``info`` entry, bit for bit.

The batch mixes what makes simulators step differently: conditions (materials, grids),
an actuation latency (control steps cut into other chunks), another control rate (other
chunk lengths), a soil option (resistance over the buried body), sensor noise, an episode
that ends early and a simulator held back (TorchRL's partial-step mask) while the others
step. The guard for any change that shares work between the simulators of a batch
(issue #18: a batched soil update was tried and measured, docs/performance.md).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from pilerl_pile_loader import open_loop
from pilerl_pile_loader.task import ScoopTask

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)
from pilerl.sim.rollout import PARTIAL_STEP_KEY, make_rollout_env, rollout, sensor_names

GYM_ID = "pilerl/PileLoading-v0"
EACH = [
    {"condition": "summer"},
    {"condition": "winter_a", "task": ScoopTask(max_episode_seconds=2.5)},  # ends early
    {"condition": "winter_c", "actuation_latency_s": (0.1, 0.3)},
    {"condition": "winter_d", "control_hz": 10.0},
    {"condition": "winter_b", "soil_options": {"body_resistance": True}},
    {"condition": "summer", "sensor_noise": 0.0},
]
SEED = 21
STEPS = 150  # 7.5 s at 20 Hz: drive in, penetrate, lift, curl


CURL_FROM_S = 5.5  # the script curls from 5.5 s (the step-identity traces: 6 s)


def scripted_action(step: int, phase: int) -> np.ndarray:
    """The open-loop scoop (``pilerl_pile_loader.open_loop``), ``phase`` steps ahead so the
    batch's simulators are in different phases of a scoop."""
    return open_loop.scripted_action(step, phase=phase, curl_from_s=CURL_FROM_S)


def alone_trace(kwargs: dict, seed: int, actions: list[np.ndarray | None]) -> list[tuple]:
    """Each step's (observation, reward, terminated, truncated, info) of one simulator
    stepped alone; ``None`` in ``actions``: a step it sits out."""
    env = gym.make(GYM_ID, **kwargs)
    env.reset(seed=seed)
    trace = []
    for action in actions:
        if action is None:
            trace.append(None)
            continue
        trace.append(env.step(action))
        if trace[-1][2] or trace[-1][3]:
            break
    env.close()
    return trace


def test_the_batched_env_steps_its_simulators_as_each_alone():
    """Through ``SimulatorBatchEnv`` and the one rollout: an episode ends early (the others
    run on, it is held), every ``info`` entry carried as a column."""
    probe = gym.make(GYM_ID)
    _, info = probe.reset(seed=0)
    info_keys = tuple(info)
    env = make_rollout_env("pile_loader", {}, each=EACH, info_keys=info_keys)

    def policy(td):
        step = policy.step
        policy.step += 1
        rows = [scripted_action(step, 4 * i) for i in range(len(EACH))]
        return td.set("action", torch.as_tensor(np.stack(rows)))

    policy.step = 0
    result = rollout(env, policy, seed=SEED, max_steps=STEPS)
    assert result.lengths[1] < min(result.lengths[0], result.lengths[2])
    fills = [result.info(i, "fill_fraction").max() for i in range(len(EACH))]
    assert sum(fill > 0.2 for fill in fills) >= 3, f"too few scoops fill: {fills}"
    names = sensor_names(env)
    for i, kwargs in enumerate(EACH):
        length = result.lengths[i]
        alone = alone_trace(kwargs, SEED + i, [scripted_action(s, 4 * i) for s in range(length)])
        assert len(alone) == length, f"sub-env {i}: episode length"
        episode = result.episode(i)
        for name in names:
            got = episode.get(("next", name)).numpy()[:, 0]
            expected = np.array([step[0][name][0] for step in alone])
            np.testing.assert_array_equal(got, expected, err_msg=f"sub-env {i} {name}")
        rewards = episode.get(("next", "reward")).numpy()[:, 0]
        np.testing.assert_array_equal(rewards, [step[1] for step in alone])
        for key in info_keys:
            got = result.info(i, key)[1:]
            expected = [float(step[4][key]) for step in alone]
            np.testing.assert_array_equal(got, expected, err_msg=f"sub-env {i} info {key}")


def test_a_held_simulator_keeps_its_readings_and_resumes_as_alone():
    """A partial step (TorchRL's ``_step`` mask) leaves a running simulator untouched; it
    then resumes where it stood, as if it had sat those steps out alone."""
    each = [EACH[0], EACH[3], EACH[2]]  # none ends within the 60 steps
    env = make_rollout_env("pile_loader", {}, each=each)
    env.seed_episodes([SEED + i for i in range(len(each))])
    td = env.reset()
    names = sensor_names(env)
    readings, plan = [], [[] for _ in each]
    for step in range(60):
        mask = torch.tensor([True, True, step not in range(20, 32)])
        actions = [scripted_action(step, 4 * i) for i in range(len(each))]
        td.set("action", torch.as_tensor(np.stack(actions)))
        td.set(PARTIAL_STEP_KEY, mask)
        before = torch.cat([td.get(n)[2] for n in names])
        td = env.step(td)["next"].clone()
        after = torch.cat([td.get(n)[2] for n in names])
        if not mask[2]:
            assert torch.equal(before, after), "a held simulator's readings moved"
        readings.append(torch.stack([td.get(n)[:, 0] for n in names], dim=-1).numpy())
        for i in range(len(each)):
            plan[i].append(actions[i] if mask[i] else None)
    for i, kwargs in enumerate(each):
        alone = alone_trace(kwargs, SEED + i, plan[i])
        for step, own in enumerate(alone):
            if own is not None:
                expected = np.array([own[0][n][0] for n in names])
                np.testing.assert_array_equal(readings[step][i], expected, f"{i} step {step}")
