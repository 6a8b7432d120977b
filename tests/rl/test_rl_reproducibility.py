"""Fine-tuning is reproducible: same seed -> same weights; killed and resumed -> the same
weights as an uninterrupted run (PPO; TD3+BC, RLPD and residual RLPD, whose replay buffers
are checkpointed)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from pilerl.policies import actor_policy, load_actor, make_actor, save_actor
from pilerl.rl import (
    CollectionConfig,
    CurriculumConfig,
    CurriculumStage,
    EvaluationConfig,
    FinetuneConfig,
    PPOConfig,
    RLPDConfig,
    TD3BCConfig,
    finetune,
)
from pilerl.rl.finetuning import RUN_CHECKPOINT
from pilerl.rl.ppo import PPOLearner
from pilerl.rl.residual import load_residual_actor, residual_policy
from pilerl.rl.rlpd import RLPDLearner
from pilerl.rl.run_checkpoint import load_run
from pilerl.rl.td3bc import TD3BCLearner

S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
STATS = {
    "sensors": {name: {"mean": 0.0, "std": 1.0} for name in S},
    "action": {"mean": [0.0, 0.0, 0.0], "std": [1.0, 1.0, 1.0]},
}
REWARDS = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}
FRAMES = 256  # 4 batches of 64, a checkpoint (segment end) every 2


def tiny_run_config(checkpoint: Path, algorithm, *, seed: int = 0) -> FinetuneConfig:
    return FinetuneConfig(
        checkpoint=str(checkpoint),
        demos="no/such/dataset",  # neither learner below reads demonstrations
        algorithm=algorithm,
        curriculum=CurriculumConfig(
            stages=[CurriculumStage(frames=FRAMES, conditions={"winter_c": 1.0, "summer": 1.0})]
        ),
        reward_weights=dict(REWARDS),
        collection=CollectionConfig(envs_per_worker=2),
        evaluation=EvaluationConfig(
            groups={"winter": ["winter_c"]}, every_frames=0, episodes=1, final_episodes=1
        ),
        seed=seed,
        checkpoint_every_frames=128,
        output_dir="unused",
    )


def tiny_ppo() -> PPOConfig:
    return PPOConfig(frames_per_batch=64, epochs=2, minibatch_size=32, critic_warmup_batches=1)


def tiny_td3bc() -> TD3BCConfig:
    return TD3BCConfig(
        frames_per_batch=64,
        updates_per_batch=4,
        batch_size=32,
        demo_fraction=0.0,
        critic_warmup_batches=1,
    )


def tiny_rlpd(*, residual: bool = False, calibrated_critic: bool = False) -> RLPDConfig:
    return RLPDConfig(
        frames_per_batch=64,
        batch_size=32,
        utd_ratio=0.1,
        warmup_utd_ratio=0.1,
        critic_warmup_batches=1,
        critic_hidden=[16, 16],
        residual=residual,
        residual_hidden=[8],
        calibrated_critic=calibrated_critic,
    )


def final_weights(run_dir: Path) -> dict[str, torch.Tensor]:
    return actor_policy(load_actor(run_dir / "final.pt")).state_dict()


def final_residual_weights(run_dir: Path) -> dict[str, torch.Tensor]:
    return residual_policy(load_residual_actor(run_dir / "final.pt")).state_dict()


def assert_same_weights(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> None:
    assert a.keys() == b.keys()
    differing = [k for k in a if not torch.equal(a[k], b[k])]
    assert not differing, f"weights differ in {differing}"


class Killed(Exception):
    """Stands for a SIGKILL in the middle of a run (the real one: test_checkpoint_safety)."""


def run_killed_at_update(monkeypatch, learner_cls, kill_at: int, config, run_dir: Path) -> None:
    """Run ``finetune`` and stop it dead when the learner starts update ``kill_at``."""
    original = learner_cls.update
    calls = {"n": 0}

    def update(self, batch, *, warmup=False):
        calls["n"] += 1
        if calls["n"] == kill_at:
            raise Killed
        return original(self, batch, warmup=warmup)

    with monkeypatch.context() as patch:
        patch.setattr(learner_cls, "update", update)
        with pytest.raises(Killed):
            finetune(config, run_dir, progress=False)


@pytest.fixture(scope="module")
def cloned(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=S, stats=STATS)
    return save_actor(tmp_path_factory.mktemp("repro") / "cloned.pt", actor)


@pytest.fixture(scope="module")
def ppo_reference(cloned, tmp_path_factory) -> tuple[dict, Path]:
    """An uninterrupted PPO run (its demos folder does not exist)."""
    run_dir = tmp_path_factory.mktemp("ppo_reference")
    results = finetune(tiny_run_config(cloned, tiny_ppo()), run_dir, progress=False)
    return results, run_dir


def test_ppo_with_the_frozen_actor_regulariser_needs_no_demos(ppo_reference):
    results, run_dir = ppo_reference
    assert results["frames"] == FRAMES and results["batches"] == 4
    assert (run_dir / "final.pt").is_file()


def test_same_seed_gives_bit_identical_ppo_weights(cloned, ppo_reference, tmp_path):
    _, reference_dir = ppo_reference
    finetune(tiny_run_config(cloned, tiny_ppo()), tmp_path / "again", progress=False)
    reference = final_weights(reference_dir)
    assert_same_weights(final_weights(tmp_path / "again"), reference)
    start = actor_policy(load_actor(cloned)).state_dict()
    assert any(not torch.equal(reference[k], start[k]) for k in start), "nothing was learned"

    finetune(tiny_run_config(cloned, tiny_ppo(), seed=1), tmp_path / "other", progress=False)
    other = final_weights(tmp_path / "other")
    assert any(not torch.equal(other[k], reference[k]) for k in other), "the seed is ignored"


@pytest.mark.parametrize("kill_at", [2, 4])  # before the first checkpoint; after it
def test_killed_ppo_run_resumes_to_the_uninterrupted_weights(
    cloned, ppo_reference, tmp_path, monkeypatch, kill_at
):
    _, reference_dir = ppo_reference
    config = tiny_run_config(cloned, tiny_ppo())
    run_killed_at_update(monkeypatch, PPOLearner, kill_at, config, tmp_path)
    assert (tmp_path / RUN_CHECKPOINT).exists() == (kill_at > 3)
    resumed = finetune(config, tmp_path, progress=False)
    assert resumed["frames"] == FRAMES
    assert_same_weights(final_weights(tmp_path), final_weights(reference_dir))


def test_killed_td3bc_run_resumes_exactly_with_its_replay_buffer(cloned, tmp_path, monkeypatch):
    config = tiny_run_config(cloned, tiny_td3bc())
    finetune(config, tmp_path / "reference", progress=False)

    run_killed_at_update(monkeypatch, TD3BCLearner, 4, config, tmp_path / "killed")
    _, learner_state, _ = load_run(tmp_path / "killed" / RUN_CHECKPOINT)
    assert learner_state["replay"]["size"] == 128  # two batches were in the buffer
    assert learner_state["updates"] == 8
    finetune(config, tmp_path / "killed", progress=False)
    assert_same_weights(final_weights(tmp_path / "killed"), final_weights(tmp_path / "reference"))


@pytest.mark.parametrize(
    "changes",
    [{}, {"residual": True}, {"calibrated_critic": True}],
    ids=["rlpd", "rlpd_residual", "rlpd_calibrated"],
)
def test_killed_rlpd_run_resumes_exactly_with_its_replay_buffer(
    cloned, datasets, tmp_path, monkeypatch, changes
):
    """Killed after its first checkpoint (2 of 4 batches), an RLPD run resumes to the
    uninterrupted run's weights, online replay and update count, bit for bit."""
    residual = changes.get("residual", False)
    config = tiny_run_config(cloned, tiny_rlpd(**changes))
    config.demos = str(datasets[0] / "d_i")  # RLPD samples half of each batch from these
    finetune(config, tmp_path / "reference", progress=False)

    run_killed_at_update(monkeypatch, RLPDLearner, 4, config, tmp_path / "killed")
    _, learner_state, _ = load_run(tmp_path / "killed" / RUN_CHECKPOINT)
    assert learner_state["replay"]["size"] == 128  # two batches were in the buffer
    assert learner_state["updates"] == 12  # 6 critic steps per 64-frame batch at UTD 0.1
    finetune(config, tmp_path / "killed", progress=False)

    weights = final_residual_weights if residual else final_weights
    assert_same_weights(weights(tmp_path / "killed"), weights(tmp_path / "reference"))
    _, resumed, _ = load_run(tmp_path / "killed" / RUN_CHECKPOINT)
    _, reference, _ = load_run(tmp_path / "reference" / RUN_CHECKPOINT)
    assert resumed["updates"] == reference["updates"] == 24
    assert resumed["replay"]["size"] == reference["replay"]["size"] == FRAMES
    assert resumed["replay"]["writer"] == reference["replay"]["writer"]
    assert_same_weights(resumed["replay"]["data"], reference["replay"]["data"])
    assert_same_weights(resumed["loss"], reference["loss"])  # critics and targets too


def test_multiprocess_collection_restarts_its_workers_at_each_segment(cloned, tmp_path):
    """Two worker processes, a checkpoint every 2 batches: segments reseed and reset them."""
    config = tiny_run_config(cloned, tiny_ppo())
    config.collection = CollectionConfig(backend="multiprocess", workers=2, envs_per_worker=1)
    results = finetune(config, tmp_path, progress=False)
    assert results["frames"] == FRAMES and results["batches"] == 4
    _, learner_state, _ = load_run(tmp_path / RUN_CHECKPOINT)
    assert learner_state["optimizer"]["state"], "no update was made"
