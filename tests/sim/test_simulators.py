"""Every installed simulator honours the plugin contract, and the core runs on it.

One loop over ``available_simulators()`` (the pile loader and the toy cart here; a
third-party plugin installed beside them is tested the same way): its declared words
match its env, its TorchRL specs check, a seed replays an episode, and the library
records demonstrations with its scripted expert, clones them, evaluates in closed loop
and fine-tunes by RL on a tiny budget, all by the simulator's name; records and
summaries carry its declared failure modes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torchrl.envs.utils import check_env_specs

from pilerl.data import EpisodeStore, RecordingPlan, build_dataset, record_demonstrations
from pilerl.evaluation import ActorController, ScriptedController
from pilerl.evaluation.evaluator import EvaluationPlan, evaluate, summarize
from pilerl.policies import make_actor
from pilerl.rl import (
    CollectionConfig,
    CurriculumConfig,
    CurriculumStage,
    EvaluationConfig,
    FinetuneConfig,
    PPOConfig,
    finetune,
)
from pilerl.sim import available_simulators, get_simulator, make_gym_env, make_torchrl_env
from pilerl.sim.plugin import ALL_CONDITIONS
from pilerl.sim.settings import EnvConfig, settings_class
from pilerl.training import BCSettings, train_bc

SIMULATORS = available_simulators()


def test_the_toy_cart_and_the_pile_loader_are_both_in_the_loop():
    assert {"pile_loader", "toy_cart"} <= set(SIMULATORS)


@pytest.mark.parametrize("name", SIMULATORS)
def test_declared_words_match_the_env(name):
    plugin = get_simulator(name)
    defaults = settings_class(name)()
    assert defaults.simulator == name and defaults.condition in plugin.conditions
    env = make_gym_env(name, **defaults.make_kwargs())
    spaces = env.observation_space.spaces
    assert set(spaces) == set(plugin.sensors)
    for sensor, spec in plugin.sensors.items():
        assert float(spaces[sensor].low.min()) == pytest.approx(spec.low)
        assert float(spaces[sensor].high.max()) == pytest.approx(spec.high)
    assert env.action_space.shape == (len(plugin.controls),)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.zeros(len(plugin.controls), np.float32))
    assert plugin.success_key in info and (plugin.fill_key is None or plugin.fill_key in info)
    assert set(plugin.reward_parts) <= set(info)
    assert reward == pytest.approx(sum(info[part] for part in plugin.reward_parts), abs=1e-9)
    env.close()
    for condition in plugin.conditions:  # every declared condition builds
        make_gym_env(name, **defaults.make_kwargs(condition=condition)).close()
    with pytest.raises(ValueError, match=r"has no option\(s\) \['no_such_option'\]"):
        defaults.make_kwargs(no_such_option=1)
    with pytest.raises(ValueError, match="unknown condition 'no_such_condition'"):
        defaults.make_kwargs(condition="no_such_condition")


@pytest.mark.parametrize("name", SIMULATORS)
def test_torchrl_specs_check_and_a_seed_replays_an_episode(name):
    check_env_specs(make_torchrl_env(name, seed=0))
    check_env_specs(make_torchrl_env(name, num_envs=2, seed=0))
    plugin = get_simulator(name)

    def rollout(seed: int) -> list[np.ndarray]:
        env = make_gym_env(name)
        expert = plugin.make_expert(dt=float(env.unwrapped.dt))
        expert.reset()
        obs, _ = env.reset(seed=seed)
        readings = []
        for _ in range(40):
            action = expert.act(obs)
            assert action.dtype == np.float32 and action.shape == (len(plugin.controls),)
            obs, _, terminated, truncated, _ = env.step(action)
            readings.append(np.concatenate([obs[s] for s in plugin.sensors]))
            if terminated or truncated:
                break
        env.close()
        return readings

    first, again, other = rollout(3), rollout(3), rollout(4)
    assert len(first) == len(again)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other, strict=False))


@pytest.mark.parametrize("name", SIMULATORS)
def test_record_clone_evaluate_and_finetune_by_name(name, tmp_path):
    plugin = get_simulator(name)
    env = EnvConfig(simulator=name)
    first = next(iter(plugin.conditions))
    # --- record two demonstrations with the simulator's scripted expert
    store = EpisodeStore.create(
        tmp_path / "demos", sensors=plugin.sensor_units, controls=list(plugin.controls)
    )
    plan = RecordingPlan(name, env.make_kwargs(), n_episodes=2, seed=0)
    metas = record_demonstrations(store, plan, workers=1, progress=False)
    assert len(metas) == 2 and store.n_samples > 2
    assert all(m.fill_fraction >= 0.0 and m.condition == first for m in metas)  # may heap > 1
    phases = store.load(0)["phase"]  # the expert's phase at each step, by index
    assert int(phases.max()) < len(plugin.make_expert(dt=0.05).PHASES)
    # --- clone them (a few epochs) and evaluate the clone and the expert
    dataset = build_dataset(
        store, tmp_path / "dataset", successful_only=False, rate_hz=None, progress=False
    )
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=list(plugin.sensors), stats=dataset.stats)
    settings = BCSettings(epochs=2, batch_size=64)
    train_bc(
        actor, dataset.to_tensordict(), None, settings, run_dir=tmp_path / "bc", progress=False
    )
    checkpoint = tmp_path / "bc" / "best.pt"
    kwargs = env.make_kwargs()
    kwargs.pop("condition")
    conditions = plugin.resolve_conditions([ALL_CONDITIONS], where="test")[:2]
    plan = EvaluationPlan(name, kwargs, conditions, episodes=1, seed=1)
    scripted = evaluate(ScriptedController(simulator=name), plan, workers=1, progress=False)
    cloned = evaluate(ActorController(str(checkpoint)), plan, workers=1, progress=False)
    for records in (scripted, cloned):
        assert [r["condition"] for r in records] == list(conditions)
        assert all(r["fill_fraction"] >= 0.0 and math.isfinite(r["return"]) for r in records)
    summary = summarize(scripted, groups=plugin.condition_groups, simulator=name)
    assert set(conditions) <= set(summary)
    # --- the simulator's own failure modes and columns, in its words
    for row in summary.values():
        assert list(row["failure_modes"]) == list(plugin.failure_modes)
    for record in (*scripted, *cloned):
        assert record["failure_mode"] in ("success", *plugin.failure_modes)
        assert (record["failure_mode"] == "success") == record["success"]
    # --- a tiny PPO fine-tune on the declared default curriculum (an empty mixture),
    # rewarded by every declared part
    config = FinetuneConfig(
        checkpoint=str(checkpoint),
        env=env,
        algorithm=PPOConfig(
            frames_per_batch=32, epochs=1, minibatch_size=16, critic_warmup_batches=1
        ),
        curriculum=CurriculumConfig(stages=[CurriculumStage(frames=64, conditions={})]),
        collection=CollectionConfig(envs_per_worker=2),
        evaluation=EvaluationConfig(
            groups={"first": [first]}, every_frames=0, episodes=1, final_episodes=1
        ),
        output_dir=str(tmp_path / "finetune"),
    )
    results = finetune(config, tmp_path / "finetune", progress=False)
    assert results["frames"] >= 64
    assert (tmp_path / "finetune" / "best.pt").is_file()


def test_scoop_and_evaluate_run_on_a_simulator_that_does_not_render(tmp_path):
    """The toy cart declares no rendering: ``videos=auto`` (the default) makes no videos
    instead of passing it render keywords, and scoop expands condition groups."""
    from test_recipes import run_recipe

    assert not get_simulator("toy_cart").renders and get_simulator("pile_loader").renders
    scoop = run_recipe(
        "scoop.py", f"hydra.run.dir={tmp_path / 'scoop'}", "env=toy_cart", "conditions=[all]"
    )
    assert scoop.returncode == 0, scoop.stderr[-2000:]
    for condition in get_simulator("toy_cart").conditions:
        assert (tmp_path / "scoop" / f"trace_{condition}.csv").is_file()
    assert not list((tmp_path / "scoop").glob("*.mp4"))
    evaluated = run_recipe(
        "evaluate.py",
        f"hydra.run.dir={tmp_path / 'evaluate'}",
        "env=toy_cart",
        "evaluation.episodes=2",
        "evaluation.videos=auto",
    )
    assert evaluated.returncode == 0, evaluated.stderr[-2000:]
    assert (tmp_path / "evaluate" / "summary.json").is_file()
    refused = run_recipe(
        "evaluate.py",
        f"hydra.run.dir={tmp_path / 'refused'}",
        "env=toy_cart",
        "evaluation.episodes=2",
        "evaluation.videos=true",
    )
    assert refused.returncode != 0 and "does not render" in refused.stdout + refused.stderr
