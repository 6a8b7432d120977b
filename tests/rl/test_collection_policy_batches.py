"""PPO collects with the fused policy: the same batches as with its ProbabilisticActor."""

from __future__ import annotations

import torch

from pilerl.policies import make_actor, make_stochastic_actor
from pilerl.policies.collection_policy import FusedTanhNormalPolicy, make_collection_policy
from pilerl.rl.collection import make_collector
from pilerl.rl.config import PPOConfig
from pilerl.rl.envs import TrainingEnvFactory
from pilerl.rl.ppo import PPOLearner

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ATTENTION = [*SENSORS, "boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {"sensors": {name: {"mean": 0.0, "std": 1.0} for name in ATTENTION}}
CONDITIONS = {"summer": 1.0, "winter_c": 1.0}
REWARDS = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}


def collect(policy, *, envs: int, batches: int = 2, frames_per_batch: int = 32):
    """``batches`` batches from a seeded single-process collector, torch seeded the same."""
    factory = TrainingEnvFactory("pile_loader", {}, CONDITIONS, REWARDS, num_envs=envs)
    torch.manual_seed(7)
    collector = make_collector(
        factory,
        policy,
        frames_per_batch=frames_per_batch,
        total_frames=batches * frames_per_batch,
        seed=11,
    )
    collected = [batch.clone() for batch in collector]
    collector.shutdown()
    return collected


def test_collector_batches_with_the_fused_policy_equal_the_probabilistic_actors() -> None:
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=ATTENTION)
    stochastic = make_stochastic_actor(actor.eval(), init_scale=0.5)
    for envs in (1, 4):  # GymWrapper and SimulatorBatchEnv
        expected = collect(stochastic, envs=envs)
        got = collect(make_collection_policy(stochastic), envs=envs)
        for want, have in zip(expected, got, strict=True):
            keys = set(want.keys(True, True))
            assert keys == set(have.keys(True, True))
            for key in ("action", "action_log_prob", "action_loc", "action_scale", "bc_action"):
                assert key in keys
            for key in keys:
                assert torch.equal(have[key], want[key]), (envs, key)
        # the samples explore: they are not the cloned action
        assert not torch.equal(got[0]["action"], got[0]["bc_action"])


def test_ppo_collects_with_the_fused_sampler_over_its_own_actor() -> None:
    actor = make_actor("nnetv2", sensors=SENSORS, stats={"sensors": STATS["sensors"]})
    learner = PPOLearner(actor, PPOConfig())
    policy = learner.collection_policy
    assert isinstance(policy, FusedTanhNormalPolicy)
    assert policy.actor is learner.actor  # ClipPPOLoss's actor: the same parameters
    assert {id(p) for p in policy.parameters()} == {id(p) for p in learner.actor.parameters()}
