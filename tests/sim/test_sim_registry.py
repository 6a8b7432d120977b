"""The simulator plugin registry: discovery by name, errors, Gymnasium and TorchRL wiring."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
import torch
from torchrl.envs.utils import check_env_specs

import pilerl  # noqa: F401  (registers the plugins with Gymnasium)
from pilerl.sim import (
    SimulatorPlugin,
    UnknownSimulatorError,
    available_simulators,
    get_simulator,
    make_gym_env,
    make_torchrl_env,
)


def test_both_plugins_are_found_by_name():
    assert {"pile_loader", "toy_cart"} <= set(available_simulators())
    assert get_simulator("pile_loader").gym_id == "pilerl/PileLoading-v0"


def test_unknown_simulator_lists_known_ones():
    with pytest.raises(UnknownSimulatorError) as error:
        get_simulator("excavator")
    assert "excavator" in str(error.value)
    assert "pile_loader" in str(error.value) and "toy_cart" in str(error.value)


def test_importing_pilerl_registers_gym_ids():
    assert "pilerl/PileLoading-v0" in gym.registry
    assert "pilerl/ToyCart-v0" in gym.registry


def test_toy_plugin_runs_through_the_same_api():
    env = make_gym_env("toy_cart")
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        obs, reward, *_ = env.step(np.array([1.0], np.float32))
    assert obs["velocity"][0] > 0 and reward < 0
    check_env_specs(make_torchrl_env("toy_cart", seed=0))


VALID = {
    "name": "x",
    "gym_id": "ns/X-v0",
    "entry_point": "m:C",
    "sensors": {"position": {"unit": "m", "low": -1.0, "high": 1.0}},
    "controls": ["force"],
    "conditions": {"nominal": "the only one"},
    "options": "m:Options",
}


@pytest.mark.parametrize(
    ("declaration", "message"),
    [
        ({**VALID, "gym_id": "bad id"}, "gym_id"),
        ({**VALID, "entry_point": "no colon"}, "entry_point"),
        ({k: v for k, v in VALID.items() if k != "entry_point"}, "missing fields ['entry_point']"),
        ({**VALID, "colour": 1}, "unknown"),
        (["not", "a", "mapping"], "must be a mapping"),
    ],
)
def test_malformed_plugin_declarations_are_rejected(declaration, message):
    with pytest.raises((ValueError, TypeError), match=message.replace("[", r"\[")):
        SimulatorPlugin.from_declaration(declaration, where="entry point 'test'")


def test_batched_torchrl_env_steps_several_simulators_in_one_process():
    env = make_torchrl_env("toy_cart", num_envs=3, seed=0)
    check_env_specs(env)
    rollout = env.rollout(4)
    assert rollout.batch_size == (3, 4)
    assert rollout["position"].shape == (3, 4, 1)
    # seeded differently per sub-env: the three carts start at different positions
    assert len(set(rollout["position"][:, 0, 0].tolist())) == 3


def test_num_envs_must_be_positive():
    with pytest.raises(ValueError, match="num_envs"):
        make_torchrl_env("toy_cart", num_envs=0)


def test_native_batched_env_resets_only_the_finished_simulators():
    env = make_torchrl_env("toy_cart", num_envs=2, seed=1)
    reset = env.reset()
    start = reset["position"].clone()
    assert start[0] != start[1]  # seeds 1 and 2
    rollout = env.rollout(150, break_when_any_done=False)  # ToyCart truncates at 100 steps
    done = rollout["next", "done"].squeeze(-1)
    assert done[:, 99].all() and not done[:, :99].any()
    assert rollout.batch_size == (2, 150)


def test_importing_a_plugin_is_cheap_and_needs_nothing_from_pilerl():
    """The declarations name the env, options and expert as strings: nothing heavy loads."""
    code = (
        "import sys, pilerl_pile_loader, pilerl_toy_cart\n"
        "heavy = [m for m in sys.modules if m.split('.')[0] in "
        "('pilerl', 'mujoco', 'torch', 'gymnasium')]\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


@pytest.mark.parametrize("name", ["pile_loader", "toy_cart"])
def test_condition_groups_and_mixtures_resolve_by_name(name):
    plugin = get_simulator(name)
    everything = plugin.resolve_conditions(["all"], where="test")
    held_out = plugin.condition_groups.get("held_out", ())  # never in "all" (issue #16)
    assert everything == tuple(c for c in plugin.conditions if c not in held_out)
    for group, members in plugin.condition_groups.items():
        assert plugin.resolve_conditions([group], where="test") == members
        assert plugin.resolve_mixture({group: 2.0}, where="test") == dict.fromkeys(members, 2.0)
    with pytest.raises(ValueError, match="unknown condition 'spring'.*conditions"):
        plugin.resolve_conditions(["spring"], where="test")
    with pytest.raises(ValueError, match="weighted twice"):
        plugin.resolve_mixture({"all": 1.0, everything[0]: 1.0}, where="test")


def test_the_pile_loaders_winter_group_is_a_to_d_and_pools_in_summaries():
    plugin = get_simulator("pile_loader")
    winter = ("winter_a", "winter_b", "winter_c", "winter_d")
    held_out = ("wet_clay", "frozen_crust", "dry_sand")  # issue #16: a condition-shift test
    assert plugin.condition_groups == {"winter": winter, "held_out": held_out}
    # held-out conditions are evaluated only where named: not in "all" nor the default pools
    assert plugin.pooled_groups() == {"winter": winter, "summer": ("summer",)}
    assert not set(held_out) & set(plugin.resolve_conditions(["all"], where="test"))
    assert plugin.fill_key == "fill_fraction" and "reward_success" in plugin.reward_parts


def test_worker_processes_step_the_simulators_one_process_would():
    """``make_torchrl_env(workers=2)`` (a TorchRL ``ParallelEnv``)
    seeds its sub-envs in worker order: the same episodes as one process's batch."""

    def push(td):
        return td.set("action", torch.full((*td.batch_size, 1), 0.5))

    parallel = make_torchrl_env("toy_cart", workers=2, seed=5)
    try:
        in_workers = parallel.rollout(20, push)
    finally:
        parallel.close()
    in_process = make_torchrl_env("toy_cart", num_envs=2, seed=5).rollout(20, push)
    assert in_workers.batch_size == in_process.batch_size == (2, 20)
    assert in_workers["position"][0, 0] != in_workers["position"][1, 0]
    assert torch.equal(in_workers["next", "position"], in_process["next", "position"])
