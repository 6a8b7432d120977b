"""The fused collection policy samples exactly what the ProbabilisticActor samples."""

from __future__ import annotations

import contextlib

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import ProbabilisticActor, TanhNormal

from pilerl.policies import NEURAL_CONTROLLERS, make_actor, make_stochastic_actor
from pilerl.policies.collection_policy import FusedTanhNormalPolicy, make_collection_policy

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ATTENTION = [*SENSORS, "boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {"sensors": {name: {"mean": 1.0, "std": 2.0} for name in ATTENTION}}
CASES = [*[(name, None) for name in NEURAL_CONTROLLERS], ("dannet", ATTENTION)]
CASE_IDS = [f"{name}-{'s_prime' if att else 's'}" for name, att in CASES]
# what PPO's batches hold from the policy (ClipPPOLoss reads action and action_log_prob)
POLICY_KEYS = ("action", "action_log_prob", "action_loc", "action_scale", "bc_action")


def stochastic_actor(name: str, attention: list[str] | None, *, train: bool):
    actor = make_actor(name, sensors=SENSORS, stats=STATS, attention_sensors=attention)
    stochastic = make_stochastic_actor(actor.train(train))
    with torch.no_grad():  # a learned scale per control, some tiny, some wide
        stochastic.module[0].module[1].module.state_independent_scale.copy_(
            torch.tensor([-6.0, -1.6, 0.7])
        )
    return stochastic


def observations(shape: tuple[int, ...], spread: float) -> TensorDict:
    """Readings; a large ``spread`` drives tanh into TorchRL's safe-tanh clamp."""
    return TensorDict(
        {name: 1.0 + spread * torch.randn(*shape, 1) for name in ATTENTION}, batch_size=shape
    )


def sample(policy, data: TensorDict, *, seed: int, grad: bool) -> TensorDict:
    """``policy``'s RANDOM-mode output from torch's generator seeded ``seed``, with the
    generator's state afterwards under ``"rng_after"``."""
    torch.manual_seed(seed)
    context = contextlib.nullcontext() if grad else torch.no_grad()
    with context, set_exploration_type(ExplorationType.RANDOM):
        out = policy(data.clone())
    out.set_non_tensor("rng_after", torch.get_rng_state())
    return out


@pytest.mark.parametrize(("name", "attention"), CASES, ids=CASE_IDS)
@pytest.mark.parametrize("train", [False, True], ids=["eval", "dropout"])
@pytest.mark.parametrize("grad", [False, True], ids=["no_grad", "grad"])
def test_fused_samples_are_bit_identical_to_the_probabilistic_actor(
    name: str, attention: list[str] | None, train: bool, grad: bool
) -> None:
    stochastic = stochastic_actor(name, attention, train=train)
    fused = make_collection_policy(stochastic)
    for shape in [(), (8,), (2, 8)]:
        for spread in (1.0, 1e4):  # 1e4: many actions end in the clamp at 1 - 1e-6
            data = observations(shape, spread)
            expected = sample(stochastic, data, seed=3, grad=grad)
            got = sample(fused, data, seed=3, grad=grad)
            assert set(got.keys(True, True)) == set(expected.keys(True, True))
            for key in expected.keys(True, True):
                assert torch.equal(got[key], expected[key]), (key, shape, spread)
            for key in POLICY_KEYS:
                assert key in got.keys(True, True)
            assert got["action_log_prob"].shape == shape
            # the same draws from torch's generator: what follows draws the same too
            assert torch.equal(got["rng_after"], expected["rng_after"])


def test_the_clamp_is_reached_and_log_probs_stay_finite() -> None:
    stochastic = stochastic_actor("dannet", ATTENTION, train=False)
    got = sample(make_collection_policy(stochastic), observations((64,), 1e4), seed=0, grad=False)
    assert (got["action"].abs() == 1.0 - torch.finfo(torch.float32).resolution).any()
    assert torch.isfinite(got["action_log_prob"]).all()


@pytest.mark.parametrize("mode", [ExplorationType.DETERMINISTIC, None], ids=["det", "unset"])
def test_other_exploration_types_are_the_probabilistic_actor_itself(mode) -> None:
    stochastic = stochastic_actor("nnetv2", None, train=False)
    fused = make_collection_policy(stochastic)
    data = observations((8,), 1.0)
    context = contextlib.nullcontext() if mode is None else set_exploration_type(mode)
    with context, torch.no_grad():
        expected, got = stochastic(data.clone()), fused(data.clone())
    for key in expected.keys(True, True):
        assert torch.equal(got[key], expected[key]), key
    torch.testing.assert_close(got["action"], got["bc_action"], atol=1e-6, rtol=0)


def test_parameters_are_the_actors_and_updates_act_at_once() -> None:
    stochastic = stochastic_actor("dannet", ATTENTION, train=False)
    fused = make_collection_policy(stochastic)
    assert [id(p) for p in fused.parameters()] == [id(p) for p in stochastic.parameters()]
    assert {f"actor.{n}" for n, _ in stochastic.named_parameters()} == {
        n for n, _ in fused.named_parameters()
    }
    data = observations((8,), 1.0)
    before = sample(fused, data, seed=1, grad=False)
    with torch.no_grad():
        for parameter in stochastic.parameters():
            parameter.add_(0.05)
    expected = sample(stochastic, data, seed=1, grad=False)
    got = sample(fused, data, seed=1, grad=False)
    assert not torch.equal(got["action"], before["action"])
    for key in POLICY_KEYS:
        assert torch.equal(got[key], expected[key]), key


def test_actors_of_another_shape_are_refused() -> None:
    actor = make_actor("nnetv2", sensors=SENSORS, stats=STATS)
    with pytest.raises(TypeError, match="make_stochastic_actor"):
        FusedTanhNormalPolicy(actor)
    stochastic = make_stochastic_actor(actor)
    normal = ProbabilisticActor(
        stochastic.module[0],
        in_keys={"loc": "action_loc", "scale": "action_scale"},
        out_keys=["action"],
        distribution_class=torch.distributions.Normal,
        return_log_prob=True,
    )
    with pytest.raises(TypeError, match="TanhNormal"):
        FusedTanhNormalPolicy(normal)
    wide = ProbabilisticActor(
        stochastic.module[0],
        in_keys={"loc": "action_loc", "scale": "action_scale"},
        out_keys=["action"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -2.0, "high": 2.0},
        return_log_prob=True,
    )
    with pytest.raises(TypeError, match="low=-1, high=1"):
        FusedTanhNormalPolicy(wide)
    no_scale = ProbabilisticActor(
        TensorDictModule(
            lambda loc: (loc, loc.abs()), in_keys=["action_loc"], out_keys=["loc", "scale"]
        ),
        in_keys=["loc", "scale"],
        out_keys=["action"],
        distribution_class=TanhNormal,
        return_log_prob=True,
    )
    with pytest.raises(TypeError, match="parameter modules"):
        FusedTanhNormalPolicy(no_scale)
