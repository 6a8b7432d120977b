"""Many simulators stepped together (``step_many``, ``pilerl.sim.stepping``) give exactly
what each gives alone: the pile loader's batched soil update is bit for bit its own.

The batch mixes what makes simulators step differently: conditions (materials, grids),
an actuation latency (control steps cut into other chunks), another control rate (other
chunk lengths), a soil option the vectorised pass leaves to the soil's own update, sensor
noise, an episode that ends early and a simulator held back while the others step.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from pilerl_pile_loader.soil import heightfield
from pilerl_pile_loader.task import ScoopTask

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)
from pilerl.rl.envs import make_training_env
from pilerl.sim import make_gym_env
from pilerl.sim.rollout import PARTIAL_STEP_KEY, make_rollout_env, rollout, sensor_names
from pilerl.sim.stepping import batch_steppable, step_together

GYM_ID = "pilerl/PileLoading-v0"
EACH = [
    {"condition": "summer"},
    {"condition": "winter_a", "task": ScoopTask(max_episode_seconds=2.5)},  # ends early
    {"condition": "winter_c", "actuation_latency_s": (0.1, 0.3)},
    {"condition": "winter_d", "control_hz": 10.0},
    {"condition": "winter_b", "soil_options": {"body_resistance": True}},  # updated alone
    {"condition": "summer", "sensor_noise": 0.0},
]
SEED = 21
STEPS = 150  # 7.5 s at 20 Hz: drive in, penetrate, lift, curl
HELD = range(30, 45)  # control steps sub-env 2 is held back (not stepped) in the batch


def scripted_action(step: int, phase: int) -> np.ndarray:
    """[boom, bucket, throttle]: drive in, then lift and curl; ``phase`` shifts the script
    (control steps) so the batch's simulators are in different phases of a scoop."""
    t = (step + phase) * 0.05
    if t < 3.0:
        return np.array([0.0, 0.0, 0.8], np.float32)
    if t < 5.5:
        return np.array([0.5, 0.3, 0.5], np.float32)
    return np.array([0.8, 1.0, 0.1], np.float32)


@pytest.fixture
def batched_soil_updates(monkeypatch) -> list[int]:
    """The sizes of the heightfield's vectorised updates while the test runs."""
    sizes: list[int] = []
    vectorised = heightfield.update_heightfields

    def spy(soils, dts, **kwargs):
        sizes.append(len(soils))
        return vectorised(soils, dts, **kwargs)

    monkeypatch.setattr(heightfield, "update_heightfields", spy)
    return sizes


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


def assert_same_step(together: tuple, alone: tuple, where: str) -> None:
    obs, reward, terminated, truncated, info = together
    obs_a, reward_a, terminated_a, truncated_a, info_a = alone
    assert obs.keys() == obs_a.keys(), where
    for name in obs:
        assert obs[name].dtype == obs_a[name].dtype, f"{where} {name}"
        np.testing.assert_array_equal(obs[name], obs_a[name], err_msg=f"{where} {name}")
    assert (reward, terminated, truncated) == (reward_a, terminated_a, truncated_a), where
    assert info.keys() == info_a.keys(), where
    differ = {k: (info[k], info_a[k]) for k in info if info[k] != info_a[k]}
    assert not differ, f"{where}: info differs (together, alone): {differ}"


def test_simulators_stepped_together_step_as_each_alone(batched_soil_updates):
    envs = [gym.make(GYM_ID, **kwargs) for kwargs in EACH]
    for i, env in enumerate(envs):
        env.reset(seed=SEED + i)
    plan: list[list[np.ndarray | None]] = [[] for _ in envs]
    traces: list[list[tuple | None]] = [[] for _ in envs]
    running = [True] * len(envs)
    for step in range(STEPS):
        moving = [i for i in range(len(envs)) if running[i] and not (i == 2 and step in HELD)]
        actions = [scripted_action(step, 4 * i) for i in moving]
        results = step_together([envs[i] for i in moving], actions)
        for i in range(len(envs)):
            if not running[i]:
                continue
            if i not in moving:
                plan[i].append(None)
                traces[i].append(None)
                continue
            result = results[moving.index(i)]
            plan[i].append(actions[moving.index(i)])
            traces[i].append(result)
            running[i] = not (result[2] or result[3])
    lengths = [len(trace) for trace in traces]
    assert lengths[1] == 50 and min(lengths[:1] + lengths[2:]) > 60, "sub-env 1 ends first"
    for i, kwargs in enumerate(EACH):
        alone = alone_trace(kwargs, SEED + i, plan[i])
        assert len(alone) == len(traces[i]), f"sub-env {i}: episode length"
        for step, (together, own) in enumerate(zip(traces[i], alone, strict=True)):
            if together is not None:
                assert_same_step(together, own, f"sub-env {i} ({kwargs}) step {step}")
    # the vectorised pass ran on several soils at once, and the soils took material in it
    assert batched_soil_updates and max(batched_soil_updates) >= 4
    fills = [trace[-1][4]["fill_fraction"] for trace in traces]
    assert sum(fill > 0.2 for fill in fills) >= 3, f"too few scoops filled: {fills}"


def test_the_batched_env_steps_its_simulators_as_each_alone(batched_soil_updates):
    """Through ``SimulatorBatchEnv`` and the one rollout: an episode ends early (the others
    run on while it is held), every ``info`` entry carried as a column."""
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
    assert batched_soil_updates and max(batched_soil_updates) >= 4


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


def test_fine_tuning_mixtures_step_their_simulators_together(batched_soil_updates):
    """``ConditionMixtureEnv`` passes ``step_many`` on to its episodes' simulators: a
    batched training env gives the rewards and flags of its mixtures stepped alone."""
    conditions = {"summer": 1.0, "winter_a": 1.0, "winter_c": 1.0}
    rewards = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}
    batched = make_training_env("pile_loader", {}, conditions, rewards, num_envs=4, seed=3)
    td = batched.reset()
    outputs = []
    for step in range(80):
        action = scripted_action(step, 0)
        td.set("action", torch.as_tensor(action).expand(4, 3).clone())
        td = batched.step(td)["next"].clone()
        outputs.append((td.get("reward")[:, 0].numpy(), td.get("done")[:, 0].numpy()))
        if td.get("done").any():
            break
    assert batched_soil_updates and max(batched_soil_updates) >= 2
    for i in range(4):
        alone = make_training_env("pile_loader", {}, conditions, rewards, seed=3 + i)
        single = alone.reset()
        for step, (reward, done) in enumerate(outputs):
            single.set("action", torch.as_tensor(scripted_action(step, 0)))
            single = alone.step(single)["next"].clone()
            assert float(single.get("reward")) == float(reward[i]), f"{i} step {step}"
            assert bool(single.get("done")) == bool(done[i]), f"{i} step {step}"


def test_wrappers_that_act_are_never_looked_through():
    """``gymnasium.make``'s wrappers pass steps through once reset and checked; any other
    wrapper keeps its simulator out of a batch (stepped through its own ``step``)."""
    env = gym.make(GYM_ID)
    assert batch_steppable(env) is None  # not reset: OrderEnforcing would refuse a step
    env.reset(seed=0)
    assert batch_steppable(env) is None  # the env checker checks the first two steps
    env.step(np.zeros(3, np.float32))
    env.step(np.zeros(3, np.float32))
    assert batch_steppable(env) is env.unwrapped
    limited = gym.make(GYM_ID, max_episode_steps=5)
    limited.reset(seed=0)
    for _ in range(2):
        limited.step(np.zeros(3, np.float32))
    assert batch_steppable(limited) is None
    toy = make_gym_env("toy_cart")
    toy.reset(seed=0)
    for _ in range(2):
        toy.step(np.zeros(1, np.float32))
    assert batch_steppable(toy) is None  # no step_many: stepped one by one
    results = step_together([toy, env], [np.zeros(1, np.float32), np.zeros(3, np.float32)])
    assert [len(result) for result in results] == [5, 5]


def test_step_together_refuses_mismatched_actions():
    env = gym.make(GYM_ID)
    with pytest.raises(ValueError, match="2 simulators but 1 actions"):
        step_together([env, env], [np.zeros(3)])
