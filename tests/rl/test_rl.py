"""RL fine-tuning: cloned actors in PPO / TD3+BC, regularisers, smoke runs, resume, config."""

from __future__ import annotations

import copy
import dataclasses
import json
import subprocess
from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from tensordict import TensorDict
from test_recipes import run_recipe
from torchrl.envs.utils import ExplorationType, set_exploration_type

from pilerl.config import register_configs
from pilerl.policies import actor_policy, load_actor, make_actor, save_actor
from pilerl.rl import (
    CollectionConfig,
    CurriculumConfig,
    CurriculumStage,
    EvaluationConfig,
    FinetuneConfig,
    PPOConfig,
    TD3BCConfig,
    finetune,
)
from pilerl.rl.envs import ConditionMixtureEnv, make_training_env
from pilerl.rl.evaluation import evaluate_groups, pool_groups
from pilerl.rl.finetuning import RUN_CHECKPOINT, _Run, flat_metrics, load_cloned_actor
from pilerl.rl.ppo import PPOLearner
from pilerl.rl.td3bc import TD3BCLearner

ROOT = Path(__file__).resolve().parents[2]
CONF = ROOT / "conf"
S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
S_PRIME = [*S, "boom_pressure", "bucket_pressure", "pump_angle"]
REWARDS = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}

register_configs()


@pytest.fixture(scope="module")
def cloned(datasets, tmp_path_factory):
    """(checkpoint of an untrained-but-saved DANNet, demo dataset dir, demo transitions)."""
    root, train, _ = datasets
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=S, stats=train.stats, attention_sensors=S_PRIME)
    path = save_actor(tmp_path_factory.mktemp("rl") / "dannet.pt", actor)
    return path, root / "d_i", train.to_tensordict()


def tiny_config(
    checkpoint, demos, run_dir, algorithm, *, frames: int = 128, every_frames: int = 0
) -> FinetuneConfig:
    """Batches of 64 frames in winter_c and summer, one-episode evaluations."""
    return FinetuneConfig(
        checkpoint=str(checkpoint),
        demos=str(demos),
        algorithm=algorithm,
        curriculum=CurriculumConfig(
            stages=[CurriculumStage(frames=frames, conditions={"winter_c": 1.0, "summer": 1.0})]
        ),
        reward_weights=dict(REWARDS),
        evaluation=EvaluationConfig(
            groups={"winter": ["winter_c"]},
            every_frames=every_frames,
            episodes=1,
            final_episodes=1,
        ),
        output_dir=str(run_dir),
    )


def tiny_ppo() -> PPOConfig:
    return PPOConfig(frames_per_batch=64, epochs=2, minibatch_size=32, critic_warmup_batches=1)


def tiny_td3bc() -> TD3BCConfig:
    return TD3BCConfig(
        frames_per_batch=64, updates_per_batch=4, batch_size=32, critic_warmup_batches=1
    )


def observations(demos: TensorDict, n: int = 32) -> TensorDict:
    return demos[:n].select(*S_PRIME).clone()


# ---------------------------------------------------------------- the cloned actor inside


def test_ppo_actor_loaded_from_bc_acts_like_the_cloned_actor_before_training(cloned):
    checkpoint, _, demos = cloned
    obs = observations(demos)
    expected = load_actor(checkpoint)(obs.clone())["action"]
    learner = PPOLearner(load_actor(checkpoint), PPOConfig())
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        deterministic = learner.actor(obs.clone())["action"]
    torch.testing.assert_close(deterministic, expected, atol=2e-6, rtol=0)
    with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
        sampled = learner.actor(obs.clone())
    assert not torch.allclose(sampled["action"], expected)  # exploration around it
    assert "input_mask" in set(sampled.keys())  # DANNet's attention is kept


def test_td3bc_actor_loaded_from_bc_acts_like_the_cloned_actor_before_training(cloned):
    checkpoint, _, demos = cloned
    obs = observations(demos)
    expected = load_actor(checkpoint)(obs.clone())["action"]
    learner = TD3BCLearner(load_actor(checkpoint), TD3BCConfig(), demos=demos)
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        deterministic = learner.collection_policy(obs.clone())["action"]
    torch.testing.assert_close(deterministic, expected)
    with set_exploration_type(ExplorationType.RANDOM), torch.no_grad():
        noisy = learner.collection_policy(obs.clone())["action"]
    assert not torch.allclose(noisy, expected)


@pytest.mark.parametrize("regularizer", ["bc_demo", "frozen_actor"])
def test_regularizer_has_a_non_zero_gradient_on_the_actor(cloned, regularizer):
    checkpoint, _, demos = cloned
    learner = PPOLearner(
        load_actor(checkpoint),
        PPOConfig(regularizer=regularizer, regularizer_batch_size=64),
        demos=demos,
    )
    with torch.no_grad():  # move away from the frozen copy, else its gradient is 0
        for parameter in learner.policy.parameters():
            parameter.add_(0.05 * torch.randn_like(parameter))
    loss = learner.regularizer_loss(observations(demos, 64))
    assert float(loss) > 0
    loss.backward()
    grads = [p.grad for p in learner.policy.parameters() if p.grad is not None]
    assert grads and sum(float(g.abs().sum()) for g in grads) > 0


def test_frozen_actor_regularizer_is_zero_before_training(cloned):
    checkpoint, _, demos = cloned
    learner = PPOLearner(load_actor(checkpoint), PPOConfig(regularizer="frozen_actor"))
    assert float(learner.regularizer_loss(observations(demos))) == pytest.approx(0.0, abs=1e-12)


# ---------------------------------------------------------------- environment


def test_condition_mixture_draws_seeded_conditions_and_rewards_the_named_parts():
    env = ConditionMixtureEnv("pile_loader", {}, {"summer": 1.0, "winter_c": 3.0}, REWARDS)
    drawn = []
    env.reset(seed=3)
    for _ in range(40):
        drawn.append(env.condition)
        env.reset()
    assert set(drawn) == {"summer", "winter_c"}
    assert drawn.count("winter_c") > drawn.count("summer")
    again = ConditionMixtureEnv("pile_loader", {}, {"summer": 1.0, "winter_c": 3.0}, REWARDS)
    again.reset(seed=3)
    assert again.condition == drawn[0]
    _, reward, *_, info = env.step([0.0, 0.0, 0.8])
    assert reward == pytest.approx(sum(float(info[k][0]) for k in REWARDS))
    assert reward < 0  # the time penalty, nothing filled yet
    env.close()
    again.close()


def test_unknown_reward_part_is_named():
    env = ConditionMixtureEnv("pile_loader", {}, {"summer": 1.0}, {"reward_glory": 1.0})
    env.reset(seed=0)
    with pytest.raises(KeyError, match="reward_glory"):
        env.step([0.0, 0.0, 0.5])
    env.close()


def test_training_env_reports_success_and_reward_parts():
    env = make_training_env("pile_loader", {}, {"winter_c": 1.0}, REWARDS)
    env.set_seed(0)
    rollout = env.rollout(5)
    for key in ("success", "condition_index", *REWARDS):
        assert ("next", key) in rollout.keys(True)
    parts = sum(rollout["next", k] for k in REWARDS)
    torch.testing.assert_close(rollout["next", "reward"], parts)
    batched = make_training_env("pile_loader", {}, {"winter_c": 1.0}, REWARDS, num_envs=2)
    assert batched.rollout(3).batch_size == (2, 3)


def test_pooled_success_has_a_wilson_interval():
    measured = {"time_to_finish_s": 9.0, "max_wheel_slip_m_s": 0.1, "spilled_kg": 0.0}
    records = [
        {"condition": "winter_a", "success": True, "fill_fraction": 0.6, **measured},
        {"condition": "winter_b", "success": False, "fill_fraction": 0.4, **measured},
        {"condition": "summer", "success": True, "fill_fraction": 0.9, **measured},
    ]
    pooled = pool_groups(records, {"winter": ["winter_a", "winter_b"], "summer": ["summer"]})
    assert pooled["winter"]["successes"] == 1 and pooled["winter"]["episodes"] == 2
    assert pooled["winter"]["success_low"] < 0.5 < pooled["winter"]["success_high"]
    with pytest.raises(ValueError, match="'spring'"):
        pool_groups(records, {"spring": ["spring"]})


def constant_actor(checkpoint, path, action_pre_tanh: list[float]):
    """The cloned architecture with its output layer set to a constant pre-tanh action."""
    actor = load_actor(checkpoint)
    output = actor_policy(actor).controller.network.output
    with torch.no_grad():
        output.weight.zero_()
        output.bias.copy_(torch.tensor(action_pre_tanh))
    return save_actor(path, actor)


def test_evaluating_a_rewritten_checkpoint_sees_the_new_weights(cloned, tmp_path):
    """A checkpoint rewritten in place is read anew by the next evaluation: no stale actor."""
    checkpoint, _, _ = cloned
    path = tmp_path / "evaluated.pt"
    kwargs = {"simulator": "pile_loader", "env_kwargs": {}, "episodes": 1, "seed": 0}
    constant_actor(checkpoint, path, [0.0, 0.0, 0.0])  # stands still: nothing scooped
    still, *_ = evaluate_groups(path, {"summer": ["summer"]}, **kwargs)
    constant_actor(checkpoint, path, [0.0, 0.0, 2.0])  # full throttle into the pile
    driving, *_ = evaluate_groups(path, {"summer": ["summer"]}, **kwargs)
    assert still["summer"]["fill_mean"] == 0.0
    assert driving["summer"]["fill_mean"] > 0.0


# ---------------------------------------------------------------- smoke runs and resume


def test_ppo_smoke_run_then_resume_continues_from_the_checkpoint(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo(), frames=128, every_frames=128)
    first = finetune(config, tmp_path, progress=False)
    assert first["frames"] == 128 and first["batches"] == 2
    assert first["conditions"]["before"]["winter_c"]["episodes"] == 1
    for name in ("best.pt", "final.pt", RUN_CHECKPOINT, "success_curve.png", "results.json"):
        assert (tmp_path / name).exists(), name
    assert (tmp_path / "finetune" / "scalars" / "loss_critic.csv").exists()
    trained = actor_policy(load_actor(tmp_path / "final.pt")).state_dict()
    cloned_weights = actor_policy(load_actor(checkpoint)).state_dict()
    assert any(not torch.equal(trained[k], cloned_weights[k]) for k in trained)

    longer = copy.deepcopy(config)
    longer.curriculum.stages[0].frames = 256
    run = _Run(longer, tmp_path, progress=False)
    assert run.resume()
    assert run.state["frames"] == 128 and run.state["before"] == first["before"]
    resumed = run.policy.state_dict()
    assert all(torch.equal(resumed[k], trained[k]) for k in trained)

    second = finetune(longer, tmp_path, progress=False)
    assert second["frames"] == 256 and second["batches"] == 4
    evaluations = json.loads((tmp_path / "evaluations.json").read_text())
    assert [e["frames"] for e in evaluations] == [0, 128, 256]


def test_cross_check_evaluates_before_and_after_on_the_other_simulator_options(
    cloned, tmp_path, monkeypatch
):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo(), frames=64)
    other_soil = {"soil_options": {"intake": "mouth", "body_resistance": True}}
    config = dataclasses.replace(
        config, evaluation=dataclasses.replace(config.evaluation, cross_check_env=other_soil)
    )
    import pilerl.rl.finetuning as finetuning

    soils = []  # the soil options of every evaluation, in order

    def recording(*args, env_kwargs, **kwargs):
        soils.append(dict(env_kwargs["soil_options"]))
        return evaluate_groups(*args, env_kwargs=env_kwargs, **kwargs)

    monkeypatch.setattr(finetuning, "evaluate_groups", recording)
    results = finetune(config, tmp_path, progress=False)
    # before, and before on the other soil (both ahead of training), after (final.pt =
    # best.pt without periodic evaluations), then after on the other soil
    mouth = other_soil["soil_options"]
    assert soils == [{}, mouth, {}, mouth]
    cross = results["cross_check"]
    assert cross["env"] == other_soil
    assert cross["before"]["winter"]["episodes"] == 1
    assert cross["conditions"]["after_best"]["winter_c"]["episodes"] == 1
    flat = flat_metrics(results)
    assert (
        flat["cross_check_after_best_winter_success_rate"]
        == cross["after_best"]["winter"]["success_rate"]
    )
    assert json.loads((tmp_path / "results.json").read_text())["cross_check"] == cross


def test_env_variants_give_the_simulators_of_a_batch_their_options_in_turn():
    mouth = {"soil_options": {"intake": "mouth"}}
    env = make_training_env(
        "pile_loader", {}, {"winter_c": 1.0}, REWARDS, num_envs=4, variants=[{}, mouth]
    )
    intakes = [m.active.unwrapped.soil.intake for m in env._envs]
    assert intakes == ["footprint", "mouth", "footprint", "mouth"]
    with pytest.raises(ValueError, match="multiple of the number of variants"):
        make_training_env(
            "pile_loader", {}, {"winter_c": 1.0}, REWARDS, num_envs=3, variants=[{}, mouth]
        )


def test_finetune_collects_on_env_variants_and_resumes_only_with_them(
    cloned, tmp_path, monkeypatch
):
    checkpoint, demos_dir, _ = cloned
    import pilerl.rl.envs as rl_envs

    built = []  # the soil options of every training simulator built
    original = rl_envs.ConditionMixtureEnv.__init__

    def recording(self, simulator, env_kwargs, *args, **kwargs):
        built.append(dict(env_kwargs["soil_options"]))
        original(self, simulator, env_kwargs, *args, **kwargs)

    monkeypatch.setattr(rl_envs.ConditionMixtureEnv, "__init__", recording)
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo(), frames=64)
    variants = [{}, {"soil_options": {"intake": "mouth", "body_resistance": True}}]
    config = dataclasses.replace(
        config,
        collection=CollectionConfig(envs_per_worker=2, env_variants=variants),
    )
    results = finetune(config, tmp_path, progress=False)
    assert results["frames"] == 64
    assert built == [{}, variants[1]["soil_options"]]  # the collector's two simulators
    state = json.loads((tmp_path / "results.json").read_text())
    assert state["frames"] == 64
    assert _Run(config, tmp_path, progress=False).resume()  # the same variants: resumes
    plain = dataclasses.replace(config, collection=CollectionConfig(envs_per_worker=2))
    with pytest.raises(ValueError, match="new run directory"):
        _Run(plain, tmp_path, progress=False).resume()


def test_cross_check_env_is_checked_when_the_config_is_built(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo())
    for bad, match in (
        ({"soil_options": {"intak": "mouth"}}, "cross_check_env: .*no option.*'intak'"),
        ({"wheels": 6}, "cross_check_env: .*wheels"),
        ({"condition": "summer"}, "cross_check_env: may not set condition"),
    ):
        with pytest.raises(ValueError, match=match):
            dataclasses.replace(
                config, evaluation=dataclasses.replace(config.evaluation, cross_check_env=bad)
            )
    for variants, match in (
        ([{"soil_options": {"intak": "mouth"}}], r"env_variants\[0\]: .*no option.*'intak'"),
        ([{}, {}, {}], "envs_per_worker .8. must be a multiple of their number .3."),
        ([{"condition": "summer"}], r"env_variants\[0\]: may not set condition"),
        ([{"control_hz": 10.0}], r"env_variants\[0\]: may not set control_hz"),
    ):
        with pytest.raises(ValueError, match=match):
            dataclasses.replace(config, collection=CollectionConfig(env_variants=variants))


def test_resume_refuses_a_different_run(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo(), frames=64)
    finetune(config, tmp_path, progress=False)
    other = copy.deepcopy(config)
    other.algorithm.actor_lr = 0.5
    with pytest.raises(ValueError, match="new run directory"):
        _Run(other, tmp_path, progress=False).resume()


def run_finetune_recipe(*overrides: str) -> subprocess.CompletedProcess:
    return run_recipe("finetune.py", *overrides)


def test_finetune_recipe_td3bc_smoke_run_over_two_curriculum_stages(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    overrides = (
        "algorithm=td3bc",
        f"checkpoint={checkpoint}",
        f"demos={demos_dir}",
        "curriculum.stages=[{frames: 64, conditions: {summer: 1}}, "
        "{frames: 64, conditions: {winter_c: 1}}]",
        "algorithm.frames_per_batch=64",
        "algorithm.updates_per_batch=4",
        "algorithm.batch_size=32",
        "algorithm.critic_warmup_batches=1",
        "collection.envs_per_worker=2",
        "+evaluation.groups.winter=[winter_c]",
        "evaluation.every_frames=0",
        "evaluation.episodes=1",
        "evaluation.final_episodes=1",
    )
    result = run_finetune_recipe(*overrides, f"hydra.run.dir={tmp_path}")
    assert result.returncode == 0, result.stderr[-3000:]
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["frames"] == 128
    assert 0 <= metrics["after_best_winter_success_rate"] <= 1
    assert (tmp_path / "finetune" / "scalars" / "loss_qvalue.csv").exists()
    assert (tmp_path / "done.json").exists()
    trained = actor_policy(load_actor(tmp_path / "final.pt")).state_dict()
    cloned_weights = actor_policy(load_actor(checkpoint)).state_dict()
    assert any(not torch.equal(trained[k], cloned_weights[k]) for k in trained)

    # a run recorded before collection.env_variants existed is still this run: skipped
    record = json.loads((tmp_path / "run.json").read_text())
    assert record["settings"].pop("collection.env_variants") == []
    (tmp_path / "run.json").write_text(json.dumps(record))
    again = run_finetune_recipe(*overrides, f"hydra.run.dir={tmp_path}")
    assert again.returncode == 0 and "already finished" in again.stderr + again.stdout, (
        again.stderr[-2000:]
    )


# ---------------------------------------------------------------- bad input, configs


def test_bad_configs_fail_before_any_work(cloned, datasets, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_ppo())

    # every check runs when a config is built (dataclasses.replace builds a new one)
    unknown = copy.deepcopy(config)
    unknown.algorithm.name = "sac"
    with pytest.raises(ValueError, match="algorithm: unknown 'sac'"):
        dataclasses.replace(unknown)

    with pytest.raises(ValueError, match="algorithm.regularizer_weight"):
        dataclasses.replace(config.algorithm, regularizer_weight=-1.0)

    missing = dataclasses.replace(config, checkpoint=str(tmp_path / "nowhere.pt"))
    with pytest.raises(FileNotFoundError, match="nowhere.pt"):
        finetune(missing, tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()

    uneven = CollectionConfig(backend="ray", workers=3)  # 64 frames cannot split over 3
    with pytest.raises(ValueError, match="multiple of collection.workers"):
        dataclasses.replace(config, collection=uneven)

    bad_mixture = [CurriculumStage(frames=128, conditions={"summer": -1.0})]
    with pytest.raises(ValueError, match=r"curriculum.stages\[0\].conditions.summer"):
        dataclasses.replace(config.curriculum, stages=bad_mixture)

    _, train, _ = datasets
    forest = make_actor("rf", sensors=S, stats=train.stats)
    forest.fit(train.to_tensordict())
    rf_path = save_actor(tmp_path / "rf.pt", forest)
    with pytest.raises(ValueError, match="'rf' is not a neural network"):
        load_cloned_actor(rf_path)


@pytest.mark.parametrize("algorithm", ["ppo", "td3bc"])
@pytest.mark.parametrize("curriculum", ["winter_mix", "winter_focus", "summer_to_winter"])
def test_finetune_configs_compose_to_the_typed_schema(algorithm, curriculum):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(
            config_name="finetune",
            overrides=[
                f"algorithm={algorithm}",
                f"curriculum={curriculum}",
                "output_dir=/x",
                "checkpoint=/x/best.pt",
                "demos=/x/d_ii",
            ],
        )
    config = OmegaConf.to_object(cfg)
    assert isinstance(config, FinetuneConfig)
    assert isinstance(config.algorithm, PPOConfig if algorithm == "ppo" else TD3BCConfig)
    assert config.curriculum.name == curriculum
    assert all(isinstance(s, CurriculumStage) for s in config.curriculum.stages)
    assert config.evaluation.groups["winter"] == ["winter_a", "winter_b", "winter_c", "winter_d"]
