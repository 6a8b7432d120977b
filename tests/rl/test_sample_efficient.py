"""Sample-efficient fine-tuning: scoop counting, RLPD's symmetric sampling, LayerNorm critic
ensemble and critic warm-up, residual RL on the frozen clone, the benchmark's statistics."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from tensordict import TensorDict
from test_rl import CONF, S_PRIME, S, tiny_config

from pilerl.evaluation.evaluator import ActorController
from pilerl.policies import actor_policy, load_actor, make_actor, save_actor
from pilerl.policies.checkpoint_file import CheckpointError
from pilerl.rl import EvaluationConfig, FinetuneConfig, RLPDConfig, finetune
from pilerl.rl.envs import BATCH_INFO_KEYS, make_training_env
from pilerl.rl.residual import (
    ResidualWeights,
    controller_for,
    load_residual_actor,
    residual_policy,
    save_residual_actor,
)
from pilerl.rl.rlpd import RLPDLearner
from pilerl.rl.sample_efficiency import (
    area_under_curve,
    curve,
    iqm,
    scoops_to,
    stratified_bootstrap_ci,
    success_at,
)
from pilerl.rl.scoops import count_scoops

ONLINE_REWARD = 1e6  # marks online transitions apart from the demonstrations


@pytest.fixture(scope="module")
def cloned(datasets, tmp_path_factory):
    """(checkpoint of a saved DANNet, demo dataset dir, demo transitions)."""
    root, train, _ = datasets
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=S, stats=train.stats, attention_sensors=S_PRIME)
    path = save_actor(tmp_path_factory.mktemp("rlpd") / "dannet.pt", actor)
    return path, root / "d_i", train.to_tensordict()


def tiny_rlpd(**changes) -> RLPDConfig:
    settings = {
        "frames_per_batch": 64,
        "batch_size": 32,
        "utd_ratio": 0.1,
        "warmup_utd_ratio": 0.1,
        "critic_warmup_batches": 1,
        "critic_hidden": [16, 16],
        "residual_hidden": [8],
        **changes,
    }
    return RLPDConfig(**settings)


def online_batch(learner: RLPDLearner, demos: TensorDict, n: int = 64) -> TensorDict:
    """Transitions shaped like a collected batch, their reward set to ``ONLINE_REWARD``."""
    batch = demos[:n].select(*learner.keys).clone()
    batch.set(("next", "reward"), torch.full_like(batch["next", "reward"], ONLINE_REWARD))
    return batch


def weights(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


# ---------------------------------------------------------------- scoop counting


def collected(done: list[bool], success: list[float], tipped: list[float]) -> TensorDict:
    """A batched env's batch [envs=2, time=len/2] with ``info`` columns as collected."""
    n = len(done)
    info = torch.tensor([[s, t] for s, t in zip(success, tipped, strict=True)], dtype=torch.float64)
    return TensorDict(
        {
            "next": {
                "done": torch.tensor(done).reshape(2, n // 2, 1),
                "info": info.reshape(2, n // 2, 2),
            }
        },
        batch_size=[2, n // 2],
    )


def test_count_scoops_counts_ended_episodes_and_their_failures_and_tips():
    batch = collected(
        done=[False, True, False, True, True, False],
        success=[0.0, 1.0, 0.0, 0.0, 0.0, 1.0],  # ended: success, fail, fail (tipped)
        tipped=[0.0, 0.0, 1.0, 0.0, 1.0, float("nan")],
    )
    count = count_scoops(batch)
    assert (count.frames, count.scoops, count.failed, count.tipped) == (6, 3, 2, 1)


def test_count_scoops_reads_a_single_envs_success_and_refuses_a_batch_without_it():
    done = torch.tensor([[False], [True], [True]])
    batch = TensorDict(
        {"next": {"done": done, "success": torch.tensor([[1.0], [1.0], [0.0]])}}, [3]
    )
    count = count_scoops(batch)
    assert (count.scoops, count.failed, count.tipped) == (2, 1, 0)
    with pytest.raises(KeyError, match="success"):
        count_scoops(TensorDict({"next": {"done": done}}, [3]))


def test_batched_training_env_reports_the_scoop_columns():
    env = make_training_env("pile_loader", {}, {"winter_c": 1.0}, {"reward_fill": 1.0}, num_envs=2)
    rollout = env.rollout(2)
    assert rollout["next", "info"].shape == (2, 2, len(BATCH_INFO_KEYS))
    assert (rollout["next", "info"][..., 0] == 0).all()  # no scoop succeeded in 2 steps


# ---------------------------------------------------------------- RLPD


def test_symmetric_sampling_draws_exactly_half_demonstrations(cloned):
    checkpoint, _, demos = cloned
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(batch_size=64), demos=demos)
    learner.replay.extend(learner._as_stored(online_batch(learner, demos)))
    torch.manual_seed(0)
    for _ in range(3):
        batch = learner.replay.sample()
        online = batch["next", "reward"] == ONLINE_REWARD
        assert batch.numel() == 64 and int(online.sum()) == 32


def test_rlpd_critics_are_a_layer_norm_ensemble(cloned):
    checkpoint, _, demos = cloned
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(critic_ensemble=5), demos=demos)
    assert learner.loss.qvalue_network_params.batch_size == (5,)
    assert any(isinstance(m, torch.nn.LayerNorm) for m in learner.loss.qvalue_network.modules())
    first = learner.loss.qvalue_network_params.flatten_keys()
    differ = [not torch.equal(v[0], v[1]) for v in first.values() if v[0].numel() > 1]
    assert any(differ)  # independently initialised members


def test_critic_warmup_trains_the_critics_and_not_the_actor(cloned):
    checkpoint, _, demos = cloned
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(), demos=demos)
    actor_before = weights(learner.actor)
    critic_before = learner.loss.qvalue_network_params.detach().clone()
    metrics = learner.update(online_batch(learner, demos), warmup=True)
    assert "loss_actor" not in metrics and metrics["updates"] == 6  # round(0.1 * 64)
    assert all(torch.equal(v, weights(learner.actor)[k]) for k, v in actor_before.items())
    after = learner.loss.qvalue_network_params.detach()
    assert any(
        not torch.equal(a, b)
        for a, b in zip(critic_before.values(True, True), after.values(True, True), strict=True)
    )


def test_residual_actor_acts_as_the_clone_at_init_and_keeps_the_clone_frozen(cloned, tmp_path):
    checkpoint, _, demos = cloned
    obs = demos[:32].select(*S_PRIME).clone()
    expected = load_actor(checkpoint)(obs.clone())["action"]
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(residual=True), demos=demos)
    assert residual_policy(learner.deterministic_actor) is not None
    with torch.no_grad():
        at_init = learner.deterministic_actor(obs.clone())["action"]
    torch.testing.assert_close(at_init, expected, atol=0, rtol=0)

    clone_before = weights(residual_policy(learner.actor).clone)
    for _ in range(2):
        metrics = learner.update(online_batch(learner, demos), warmup=False)
    assert "loss_actor" in metrics
    policy = residual_policy(learner.actor)
    assert all(torch.equal(v, weights(policy.clone)[k]) for k, v in clone_before.items())
    with torch.no_grad():
        moved = learner.deterministic_actor(obs.clone())["action"]
    assert not torch.equal(moved, expected)  # the residual learned a correction
    assert (moved - expected).abs().max() <= policy.scale + 1e-6

    # saved and rebuilt (file and evaluation controller): the same actions
    path = save_residual_actor(tmp_path / "residual.pt", learner.actor)
    with torch.no_grad():
        reloaded = load_residual_actor(path)(obs.clone())["action"]
        shipped = ResidualWeights.of(learner.actor).build()(obs.clone())["action"]
    torch.testing.assert_close(reloaded, moved, atol=0, rtol=0)
    torch.testing.assert_close(shipped, moved, atol=0, rtol=0)
    assert isinstance(controller_for(path), ResidualWeights)


def test_a_saved_actor_is_told_apart_by_the_checked_reader(cloned, tmp_path):
    """``controller_for(path)`` reads a residual checkpoint through ``read_checkpoint``: a
    cloned actor's file is handed on as one, a damaged residual file fails there."""
    checkpoint, _, demos = cloned
    assert isinstance(controller_for(checkpoint), ActorController)
    learner = RLPDLearner(load_actor(checkpoint), tiny_rlpd(residual=True), demos=demos)
    path = save_residual_actor(tmp_path / "residual.pt", learner.actor)
    damaged = bytearray(path.read_bytes())
    middle = len(damaged) // 2
    damaged[middle] ^= 0xFF
    (tmp_path / "damaged.pt").write_bytes(bytes(damaged))
    with pytest.raises(CheckpointError, match="damaged.pt"):
        controller_for(tmp_path / "damaged.pt")
    torch.save({"format": "pilerl.residual_actor", "version": 1}, tmp_path / "no_digest.pt")
    with pytest.raises(CheckpointError, match="corrupted"):
        controller_for(tmp_path / "no_digest.pt")


def test_rlpd_learner_needs_demonstrations(cloned):
    checkpoint, _, _ = cloned
    with pytest.raises(ValueError, match="needs demonstrations"):
        RLPDLearner(load_actor(checkpoint), tiny_rlpd(), demos=None)


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"demo_fraction": 0.0}, "algorithm.demo_fraction"),
        ({"demo_fraction": 1.0}, "algorithm.demo_fraction"),
        ({"critic_ensemble": 1}, "algorithm.critic_ensemble"),
        ({"utd_ratio": 0}, "algorithm.utd_ratio"),
        ({"residual_scale": 3.0}, "algorithm.residual_scale"),
        ({"residual_hidden": []}, "algorithm.residual_hidden"),
    ],
)
def test_rlpd_config_names_a_bad_value(changes, field):
    with pytest.raises(ValueError, match=field):
        RLPDConfig(**changes)


def test_scoop_settings_are_checked():
    with pytest.raises(ValueError, match="evaluation.at_scoops"):
        EvaluationConfig(at_scoops=[20, 10])
    with pytest.raises(ValueError, match="max_scoops"):
        FinetuneConfig(max_scoops=-1)


@pytest.mark.parametrize("algorithm", ["rlpd", "rlpd_residual"])
def test_rlpd_configs_compose_to_the_typed_schema(algorithm):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(
            config_name="finetune",
            overrides=[
                f"algorithm={algorithm}",
                "output_dir=/x",
                "checkpoint=/x/b.pt",
                "demos=/x/d",
            ],
        )
    config = OmegaConf.to_object(cfg)
    assert isinstance(config.algorithm, RLPDConfig)
    assert config.algorithm.residual == (algorithm == "rlpd_residual")
    assert config.algorithm.demo_fraction == 0.5


def test_residual_rlpd_smoke_run_counts_scoops_and_saves_a_residual_actor(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(
        checkpoint, demos_dir, tmp_path, tiny_rlpd(residual=True), frames=128, every_frames=128
    )
    results = finetune(config, tmp_path, progress=False)
    assert results["frames"] == 128 and results["batches"] == 2
    assert results["scoops"] >= results["failed_scoops"] >= results["tipped_scoops"] >= 0
    assert results["evaluation_episodes"] == 5  # before, 2 periodic, after (final, best)
    for name in ("best.pt", "final.pt"):
        actor = load_residual_actor(tmp_path / name)
        clone = actor_policy(load_actor(checkpoint)).state_dict()
        kept = residual_policy(actor).clone.state_dict()
        assert all(torch.equal(kept[k], clone[k]) for k in clone)  # the clone stayed frozen
    scalars = tmp_path / "finetune" / "scalars"
    assert (scalars / "scoops.csv").exists() and (scalars / "failed_scoops.csv").exists()


def test_evaluations_on_the_same_starts_are_not_run_twice(cloned, tmp_path):
    checkpoint, demos_dir, _ = cloned
    config = tiny_config(checkpoint, demos_dir, tmp_path, tiny_rlpd(), frames=64, every_frames=64)
    config.evaluation.final_seed = config.evaluation.seed  # periodic and final: same starts
    results = finetune(config, tmp_path, progress=False)
    # before (the clone, also the curve's first point) and at 64 frames (also final, best)
    assert results["evaluation_episodes"] == 2
    evaluations = json.loads((tmp_path / "evaluations.json").read_text())
    assert evaluations[0]["groups"] == results["before"]
    assert evaluations[-1]["groups"] == results["after_final"]


# ---------------------------------------------------------------- the benchmark's statistics


def test_iqm_is_the_mean_of_the_middle_half():
    assert iqm(np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 1000.0])) == pytest.approx(3.5)


def test_stratified_bootstrap_interval_holds_the_iqm_and_is_a_point_for_equal_runs():
    scores = np.array([10.0, 20.0, 30.0, 40.0, 200.0])
    low, high = stratified_bootstrap_ci(scores)
    assert low <= iqm(scores) <= high and low < high
    assert stratified_bootstrap_ci(np.full(5, 7.0)) == (7.0, 7.0)
    # resampled within each task: a task's scores never mix with another's
    tasks = np.array([[0.0, 100.0], [0.0, 100.0], [0.0, 100.0]])
    assert stratified_bootstrap_ci(tasks, statistic=lambda s: float(s[:, 1].mean())) == (
        100.0,
        100.0,
    )


def test_success_curve_reads_as_a_step_function_over_scoops():
    scoops, rate = np.array([0, 10, 24, 45]), np.array([0.5, 0.75, 1.0, 0.75])
    assert success_at(scoops, rate, 40) == 1.0  # the last evaluation at <= 40 scoops
    assert success_at(scoops, rate, 23) == 0.75
    assert scoops_to(scoops, rate, 0.9) == 24
    assert scoops_to(scoops, rate[:2], 0.9) is None
    assert area_under_curve(scoops, rate, 45) == pytest.approx((0.5 * 10 + 0.75 * 14 + 21) / 45)


def test_evaluations_at_one_scoop_count_keep_their_order():
    """Two evaluations with no scoop between them: the later one is the later learning,
    whatever its rate (sorting by rate would credit the better of the two)."""
    evaluations = [
        {"scoops": 10, "groups": {"winter": {"success_rate": 0.9}}},
        {"scoops": 10, "groups": {"winter": {"success_rate": 0.2}}},
        {"scoops": 0, "groups": {"winter": {"success_rate": 0.5}}},
    ]
    scoops, rate = curve(evaluations, "winter")
    assert scoops.tolist() == [0, 10, 10] and rate.tolist() == [0.5, 0.9, 0.2]
    assert success_at(scoops, rate, 10) == 0.2


def fake_run(
    run_dir,
    curve_points: list[tuple[int, float, float]],
    *,
    failed: int,
    wall_s: float,
    budget: int | None = None,
):
    """A finished benchmark run on disk: its evaluations, results, wall time and (where
    given) configured scoop budget."""
    run_dir.mkdir(parents=True)
    evaluations = [
        {
            "frames": 500 * scoops,
            "scoops": scoops,
            "groups": {"winter": {"success_rate": w}, "summer": {"success_rate": s}},
        }
        for scoops, w, s in curve_points
    ]
    last = curve_points[-1][0]
    results = {
        "scoops": last,
        "frames": 500 * last,
        "failed_scoops": failed,
        "tipped_scoops": 1,
        "evaluation_episodes": 5 * len(curve_points),
        "evaluation_s": wall_s / 4,
    }
    (run_dir / "evaluations.json").write_text(json.dumps(evaluations))
    (run_dir / "results.json").write_text(json.dumps(results))
    bench = {"invocations_s": [wall_s / 2, wall_s / 2]}
    if budget is not None:
        bench["scoops_budget"] = budget
    (run_dir / "benchmark.json").write_text(json.dumps(bench))


def test_benchmark_report_tabulates_finished_runs(tmp_path, monkeypatch, capsys):
    out, report = tmp_path / "runs", tmp_path / "report"
    fake_run(
        out / "ppo" / "seed0", [(0, 0.5, 0.0), (24, 0.75, 0.0), (45, 1.0, 1.0)], failed=9, wall_s=60
    )
    fake_run(out / "ppo" / "seed1", [(0, 0.5, 0.0), (40, 0.5, 0.0)], failed=20, wall_s=120)
    fake_run(
        out / "rlpd" / "seed0", [(0, 0.5, 0.0), (10, 1.0, 0.5), (40, 1.0, 1.0)], failed=3, wall_s=30
    )
    script = Path(__file__).resolve().parents[2] / "benchmarks" / "sample_efficiency.py"
    argv = [str(script), "--report-only", "--out", str(out), "--report", str(report)]
    monkeypatch.setattr("sys.argv", argv)
    runpy.run_path(str(script), run_name="__main__")
    table = (report / "sample_efficiency.md").read_text()
    rows = {line.split(" | ")[0].strip("| "): line for line in table.splitlines()[2:]}
    assert "45, >40" in rows["ppo"]  # per seed: reached at 45 scoops, never within 40
    # one of two seeds reached 90%: no IQM of censored counts, the count instead
    assert "not reached by most seeds (1/2)" in rows["ppo"]
    assert "| 10; 10.00 [10.00, 10.00] |" in rows["rlpd"]
    assert "| 1.5 min |" in rows["ppo"] and "| 0.5 min |" in rows["rlpd"]
    assert "14.5 (1.0) of 42" in rows["ppo"]
    assert "| 12 (25% of wall) |" in rows["ppo"]
    data = json.loads((report / "sample_efficiency.json").read_text())
    assert data["runs"]["ppo"][0]["winter_at_40"] == 0.75  # the evaluation at 24 scoops
    assert data["runs"]["ppo"][1]["winter_at_200"] is None  # never got there
    assert (report / "sample_efficiency.png").stat().st_size > 0


def test_benchmark_report_keeps_the_configured_budget_apart_from_the_scoops_reached(
    tmp_path, monkeypatch
):
    """Runs stop at the first batch past their budget: the budget is what was asked, the
    count reached is named as such, and a begun but unfinished run is reported as such."""
    out, report = tmp_path / "runs", tmp_path / "report"
    fake_run(
        out / "td3bc" / "seed0", [(0, 0.0, 0.0), (43, 0.5, 1.0)], failed=9, wall_s=6, budget=40
    )
    fake_run(
        out / "td3bc" / "seed1", [(0, 0.0, 0.0), (47, 1.0, 1.0)], failed=9, wall_s=6, budget=40
    )
    (out / "td3bc" / "seed2").mkdir()  # begun (a last.ckpt would be here), not finished
    script = Path(__file__).resolve().parents[2] / "benchmarks" / "sample_efficiency.py"
    argv = [str(script), "--report-only", "--out", str(out), "--report", str(report)]
    monkeypatch.setattr("sys.argv", argv + ["--methods", "td3bc", "ppo"])
    runpy.run_path(str(script), run_name="__main__")
    data = json.loads((report / "sample_efficiency.json").read_text())
    (row,) = data["rows"]
    assert row["scoops_budget"] == 40 and row["min_scoops_reached"] == 43
    assert [r["scoops"] for r in data["runs"]["td3bc"]] == [43, 47]
    # the AUC spans the configured 40 scoops for both seeds: 0.0 over 0-40
    assert [r["winter_auc"] for r in data["runs"]["td3bc"]] == [0.0, 0.0]
    assert data["unfinished"] == {"td3bc": [2]}
    text = (report / "sample_efficiency.md").read_text()
    assert "td3bc: seeds [2] unfinished" in text and "ppo: no finished run" in text
