"""The simulator env's shortcuts through TorchRL's per-step bookkeeping give TorchRL's
results: ``step_mdp`` the same entries in the same order, the rollout's stack the same
tensordict, and TensorDict's own code wherever the shortcut does not apply."""

from __future__ import annotations

import functools

import torch
from tensordict import LazyStackedTensorDict, TensorDict, TensorDictBase
from torchrl.envs import EnvBase
from torchrl.envs.utils import _StepMDP

from pilerl.sim import make_torchrl_env
from pilerl.sim.torchrl_steps import FlatStepMDP, _dense_stack, stack_steps

ACTION = torch.tensor([0.15, 0.1, 0.5])


def drive(tensordict: TensorDictBase) -> TensorDictBase:
    """Throttle with the boom and bucket rising, plus an entry of the policy's own."""
    tensordict.set("action", ACTION.expand(*tensordict.batch_size, 3))
    tensordict.set("policy_note", tensordict.get("boom_angle").double())
    return tensordict


def assert_same_tensordict(got: TensorDictBase, want: TensorDictBase) -> None:
    """Same type, batch size, device, names, key order, and every entry equal bit for bit
    in dtype, shape and strides."""
    assert type(got) is type(want)
    assert got.batch_size == want.batch_size
    assert got.device == want.device
    assert got._maybe_names() == want._maybe_names()
    assert list(got.keys()) == list(want.keys())
    for key in want.keys():  # noqa: SIM118 (iterating a TensorDict unbinds it)
        value, expected = got.get(key), want.get(key)
        if isinstance(expected, TensorDictBase):
            assert_same_tensordict(value, expected)
            continue
        assert value.dtype == expected.dtype and value.shape == expected.shape
        assert value.stride() == expected.stride()
        assert torch.equal(value, expected)
        assert value.requires_grad == expected.requires_grad


def stepped(env: EnvBase) -> TensorDictBase:
    """A step's output (root with ``next``) after a reset and ``drive``."""
    return env.step(drive(env.reset()))


def test_step_mdp_places_the_entries_torchrl_places_in_its_order():
    for num_envs in (1, 3):
        env = make_torchrl_env(seed=2, num_envs=num_envs)
        general = _StepMDP(env, exclude_action=False)
        assert isinstance(env._step_mdp, FlatStepMDP)
        step = stepped(env)
        got, want = env._step_mdp(step), general(step)
        assert_same_tensordict(got, want)
        for key in want.keys():  # noqa: SIM118 (the same tensors, not copies)
            assert got.get(key) is want.get(key)


def test_step_mdp_hands_what_is_not_flat_to_torchrl():
    env = make_torchrl_env(seed=2)
    general = _StepMDP(env, exclude_action=False)
    step = stepped(env)
    step.set("memory", TensorDict({"h": torch.ones(4)}, []))  # a nested tensordict
    got, want = env._step_mdp(step), general(step)
    assert_same_tensordict(got, want)
    assert got.get("memory") is not step.get("memory")  # copied, as TorchRL does


def torchrl_only(env: EnvBase) -> EnvBase:
    """``env`` stepping through TorchRL's own ``step``, ``step_mdp`` and ``rollout``."""
    env.step = functools.partial(EnvBase.step, env)
    env.rollout = functools.partial(EnvBase.rollout, env)
    env._cache["_step_mdp"] = _StepMDP(env, exclude_action=False)  # TorchRL's cache
    assert type(env._step_mdp) is _StepMDP
    return env


def test_a_step_is_torchrl_step():
    env, reference = make_torchrl_env(seed=8), torchrl_only(make_torchrl_env(seed=8))
    got, want = drive(env.reset()), drive(reference.reset())
    for _ in range(3):
        got, want = env.step(got), reference.step(want)
        assert_same_tensordict(got, want)
        got, want = drive(env._step_mdp(got)), drive(reference._step_mdp(want))


def test_the_rollout_is_torchrl_rollout_of_the_same_seed():
    for num_envs, kwargs in [
        (1, {"break_when_any_done": False}),  # across an episode's end and reset
        (1, {}),  # stops at the first end
        (3, {"break_when_any_done": False, "break_when_all_done": True}),  # partial steps
    ]:
        env = make_torchrl_env(seed=4, num_envs=num_envs, sensor_noise=0.0)
        reference = torchrl_only(make_torchrl_env(seed=4, num_envs=num_envs, sensor_noise=0.0))
        got, want = env.rollout(130, drive, **kwargs), reference.rollout(130, drive, **kwargs)
        assert_same_tensordict(got, want)
        assert got.names[-1] == "time"


def test_the_stack_is_tensordict_stack_and_keeps_its_exceptions():
    env = make_torchrl_env(seed=6)
    steps = [step.clone() for step in env.rollout(5, drive, break_when_any_done=False).unbind(0)]
    assert _dense_stack(steps, 0) is not None  # the shortcut applies
    assert_same_tensordict(stack_steps(steps, 0), torch.stack(steps, 0))
    # an entry that some steps lack: TensorDict's lazy stack, as without the shortcut
    uneven = [step.clone() for step in steps]
    uneven[2].set("only_here", torch.zeros(1))
    got = stack_steps(uneven, 0)
    assert isinstance(got, LazyStackedTensorDict)
    assert_same_tensordict(got, LazyStackedTensorDict.maybe_dense_stack(uneven, 0))
    # a policy entry whose shape changes: a lazy stack too
    ragged = [step.clone() for step in steps]
    ragged[1].set("policy_note", torch.zeros(2, dtype=torch.float64))
    assert isinstance(stack_steps(ragged, 0), LazyStackedTensorDict)
    # entries with gradients keep them, as torch.stack gives them
    weight = torch.ones(3, requires_grad=True)
    graded = [step.clone().set("action", step.get("action") * weight) for step in steps]
    got = stack_steps(graded, 0)
    assert got.get("action").requires_grad
    assert_same_tensordict(got, LazyStackedTensorDict.maybe_dense_stack(graded, 0))
