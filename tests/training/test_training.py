"""Behaviour cloning: learning, checkpoints, resume, the recipe."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from test_recipes import run_recipe

from pilerl.policies import load_actor, make_actor
from pilerl.training import BCSettings, train_bc, train_bc_ensemble, validation_loss
from pilerl.training.draw_ahead import MasksAhead

ROOT = Path(__file__).resolve().parents[2]
S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]


def train_bc_recipe(*overrides: str, data_root: Path | None = None):
    """Run recipes/train_bc.py with ``overrides`` (and the fixture's data, if given)."""
    data = (
        []
        if data_root is None
        else [f"train_data={data_root / 'd_i'}", f"validation_data={data_root / 'winter'}"]
    )
    return run_recipe("train_bc.py", *overrides, *data)


def test_bc_lowers_the_validation_loss(datasets):
    _, train, validation = datasets
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=S, stats=train.stats)
    before = validation_loss(actor, validation)
    actor, history = train_bc(
        actor,
        train.to_tensordict(),
        validation,
        BCSettings(epochs=15, batch_size=64),
        progress=False,
    )
    assert len(history) == 15
    assert history[-1]["train_loss"] < 0.7 * history[0]["train_loss"]
    assert history[-1]["validation_loss"] < 0.8 * before


def test_a_killed_run_resumes_to_the_same_weights(datasets, tmp_path):
    _, train, validation = datasets
    data = train.to_tensordict()

    def run(epochs: int, run_dir: Path):
        torch.manual_seed(3)  # the same initial weights every time
        actor = make_actor("nnetv2", sensors=S, stats=train.stats)
        settings = BCSettings(epochs=epochs, batch_size=64, seed=3)
        return train_bc(actor, data, validation, settings, run_dir=run_dir, progress=False)

    straight, _ = run(4, tmp_path / "a")
    run(2, tmp_path / "b")  # "killed" after 2 epochs: last.pt stays behind
    resumed, history = run(4, tmp_path / "b")  # a new process finds last.pt and goes on
    assert [row["epoch"] for row in history] == [1, 2, 3, 4]
    a, b = straight.module.state_dict(), resumed.module.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_packed_dropout_masks_train_deterministically_and_resume(datasets, tmp_path):
    """dropout_masks="packed": other draws than torch's (other weights), the same run for
    the same seed, a killed run resumes to the same weights, the actor keeps its layers."""
    _, train, validation = datasets
    data = train.to_tensordict()

    def run(epochs: int, masks: str, run_dir: Path | None = None):
        torch.manual_seed(3)
        actor = make_actor("dannet", sensors=S, stats=train.stats)
        settings = BCSettings(epochs=epochs, batch_size=64, seed=3, dropout_masks=masks)
        return train_bc(actor, data, validation, settings, run_dir=run_dir, progress=False)

    packed, history = run(4, "packed")
    again, _ = run(4, "packed")
    torch_masks, _ = run(4, "bernoulli")
    weights = packed.module.state_dict()
    assert all(torch.equal(weights[k], v) for k, v in again.module.state_dict().items())
    assert not all(torch.equal(weights[k], v) for k, v in torch_masks.module.state_dict().items())
    assert history[-1]["validation_loss"] < history[0]["validation_loss"]
    layers = [type(m) for m in packed.module.modules() if "Dropout" in type(m).__name__]
    assert layers == [torch.nn.Dropout] * 4  # DANNet's four, put back after training
    run(2, "packed", tmp_path)  # "killed" after 2 epochs
    resumed, _ = run(4, "packed", tmp_path)
    assert all(torch.equal(weights[k], v) for k, v in resumed.module.state_dict().items())
    with pytest.raises(ValueError, match=r"was trained with .*'packed'"):
        run(4, "bernoulli", tmp_path)


def test_resume_takes_none_and_bernoulli_for_the_same_masks(datasets, tmp_path):
    """dropout_masks None and "bernoulli" are both torch's draws in train_bc: a run started
    with one resumes with the other (to the weights of a straight run); packed is refused,
    the differing key named."""
    _, train, validation = datasets
    data = train.to_tensordict()

    def run(epochs: int, masks: str | None, run_dir: Path | None = None):
        torch.manual_seed(3)
        actor = make_actor("dannet", sensors=S, stats=train.stats)
        settings = BCSettings(epochs=epochs, batch_size=64, seed=3, dropout_masks=masks)
        return train_bc(actor, data, validation, settings, run_dir=run_dir, progress=False)

    straight, expected = run(3, None)
    want = straight.module.state_dict()
    for first, then in ((None, "bernoulli"), ("bernoulli", None)):
        run_dir = tmp_path / f"{first}_then_{then}"
        run(2, first, run_dir)  # "killed" after 2 epochs
        resumed, history = run(3, then, run_dir)
        assert history == expected
        assert all(torch.equal(resumed.module.state_dict()[k], want[k]) for k in want)
        with pytest.raises(ValueError, match=r"differ in \['dropout_masks'\]"):
            run(4, "packed", run_dir)
    run(2, "packed", tmp_path / "packed")
    for masks in (None, "bernoulli"):
        with pytest.raises(ValueError, match=r"'packed'.*differ in \['dropout_masks'\]"):
            run(3, masks, tmp_path / "packed")


def test_resume_refuses_a_run_directory_of_another_model(datasets, tmp_path):
    _, train, validation = datasets
    data = train.to_tensordict()
    settings = BCSettings(epochs=2, batch_size=64, seed=3)
    nnetv2 = make_actor("nnetv2", sensors=S, stats=train.stats)
    train_bc(nnetv2, data, validation, settings, run_dir=tmp_path, progress=False)
    dannet = make_actor("dannet", sensors=S, stats=train.stats)
    with pytest.raises(ValueError, match=r"holds a 'nnetv2' actor .* not the 'dannet'"):
        train_bc(dannet, data, validation, settings, run_dir=tmp_path, progress=False)


def test_best_checkpoint_loads_safely_and_acts_the_same(datasets, tmp_path):
    _, train, validation = datasets
    actor, history = train_bc(
        make_actor("annet", sensors=S, stats=train.stats),
        train.to_tensordict(),
        validation,
        BCSettings(epochs=3, batch_size=64),
        run_dir=tmp_path,
        progress=False,
    )
    best = min(range(3), key=lambda i: history[i]["validation_loss"])
    loaded = load_actor(tmp_path / "best.pt")
    assert validation_loss(loaded, validation) == pytest.approx(
        history[best]["validation_loss"], rel=1e-5
    )


def test_clone_keeps_the_final_weights_beside_the_best(datasets, tmp_path):
    from pilerl.training.clone import clone

    _, train, validation = datasets
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=S, stats=train.stats)
    settings = BCSettings(epochs=4, batch_size=64)
    actor, metrics = clone(
        actor, train.to_tensordict(), validation, settings, tmp_path, logger_backend="none",
        title="t",
    )  # fmt: skip
    final = load_actor(tmp_path / "final.pt")
    assert validation_loss(final, validation) == pytest.approx(metrics["validation_loss"])
    assert validation_loss(load_actor(tmp_path / "best.pt"), validation) == pytest.approx(
        metrics["best_validation_loss"]
    )
    a, b = final.module.state_dict(), actor.module.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)  # the weights clone() returns


def test_the_pipeline_clones_the_final_weights_unless_told(tmp_path):
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from pilerl.config import register_configs
    from pilerl.training.settings import BCStepConfig

    register_configs()
    for overrides, chosen in (([], "final.pt"), (["bc.selection=best"], "best.pt")):
        with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
            cfg = compose("pipeline", overrides=[f"output_dir={tmp_path}", *overrides])
        config = OmegaConf.to_object(cfg)
        assert config.finetune.checkpoint == f"{tmp_path}/bc/{chosen}"  # what BC and RL use
    with pytest.raises(ValueError, match=r"bc.selection: unknown 'last'; known: \['final'"):
        BCStepConfig(selection="last")


def test_the_report_names_the_weights_it_calls_cloned(tmp_path):
    from types import SimpleNamespace

    from pilerl.reports.pipeline import cloned_text

    def config(selection: str, checkpoint: Path) -> SimpleNamespace:
        return SimpleNamespace(
            bc=SimpleNamespace(selection=selection),
            finetune=SimpleNamespace(checkpoint=str(checkpoint)),
        )

    assert cloned_text(config("final", tmp_path / "bc" / "final.pt"), tmp_path).startswith(
        "final.pt, the weights after the whole budget"
    )
    assert cloned_text(config("best", tmp_path / "bc" / "best.pt"), tmp_path).startswith(
        "best.pt, the epoch with the lowest validation loss"
    )
    elsewhere = tmp_path / "other" / "actor.pt"
    assert cloned_text(config("final", elsewhere), tmp_path) == (
        f"{elsewhere} (set by finetune.checkpoint, not this run's BC step)."
    )


def test_corrupt_training_checkpoint_is_refused(datasets, tmp_path):
    _, train, _ = datasets
    (tmp_path / "last.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="last.pt: not a readable training checkpoint"):
        train_bc(
            make_actor("nnet", sensors=S, stats=train.stats),
            train.to_tensordict(),
            None,
            BCSettings(epochs=1),
            run_dir=tmp_path,
            progress=False,
        )


def test_random_forest_is_fitted_through_the_same_call(datasets):
    _, train, validation = datasets
    actor, history = train_bc(
        make_actor("rf", sensors=S, stats=train.stats),
        train.to_tensordict(),
        validation,
        BCSettings(),
        progress=False,
    )
    assert len(history) == 1 and history[0]["train_loss"] < history[0]["validation_loss"]


def test_impossible_settings_fail():
    with pytest.raises(ValueError, match="learning_rate"):
        BCSettings(learning_rate=-1.0)
    with pytest.raises(ValueError, match="epochs"):
        BCSettings(epochs=0)
    with pytest.raises(ValueError, match=r"BCSettings.dropout_masks: unknown 'fast'"):
        BCSettings(dropout_masks="fast")


def test_train_bc_recipe_writes_checkpoints_logs_and_plot(datasets, tmp_path):
    root, _, _ = datasets
    result = train_bc_recipe(
        f"hydra.run.dir={tmp_path}",
        "epochs=2",
        "batch_size=64",
        "policy=dannet",
        "sensors=s_pt_sprime",
        data_root=root,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    for name in ("best.pt", "last.pt", "losses.png", "bc/scalars/validation_loss.csv"):
        assert (tmp_path / name).stat().st_size > 0, name
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["epochs"] == 2 and metrics["validation_loss"] > 0
    bad = train_bc_recipe(f"hydra.run.dir={tmp_path / 'bad'}", f"train_data={tmp_path / 'no'}")
    assert bad.returncode != 0 and "not a pilerl dataset" in bad.stderr


def test_train_bc_recipe_chooses_the_dropout_masks_and_draws_ahead(datasets, tmp_path, monkeypatch):
    """The recipe's dropout_masks and draw_ahead keys reach the training; null and
    bernoulli are the same run (also for a run directory recorded before the key), packed
    another; a bad name or combination exits non-zero naming the key, writing nothing."""
    root, _, _ = datasets

    def train(name: str, *overrides: str, policy: str = "dannet"):
        run_dir = f"hydra.run.dir={tmp_path / name}"
        common = ("epochs=2", "batch_size=64", f"policy={policy}", "logger=none")
        return train_bc_recipe(run_dir, *common, *overrides, data_root=root)

    def metrics(name: str) -> dict:
        return json.loads((tmp_path / name / "metrics.json").read_text())

    def skipped(result) -> bool:
        return result.returncode == 0 and "already finished" in result.stdout + result.stderr

    assert train("default").returncode == 0
    drawn = []  # the masks are drawn ahead: draw_ahead reaches train_bc
    next_step = MasksAhead.next_step
    monkeypatch.setattr(MasksAhead, "next_step", lambda feed: drawn.append(1) or next_step(feed))
    assert train("ahead", "draw_ahead=true").returncode == 0
    monkeypatch.undo()
    assert drawn and metrics("ahead") == metrics("default")  # torch's draws: the same run
    assert train("packed", "dropout_masks=packed").returncode == 0
    assert metrics("packed")["train_loss"] != metrics("default")["train_loss"]

    assert skipped(train("default", "dropout_masks=bernoulli"))  # what null stands for
    assert skipped(train("default", "draw_ahead=true"))  # the same results
    refused = train("default", "dropout_masks=packed")
    assert refused.returncode != 0 and "dropout_masks: 'bernoulli' -> 'packed'" in refused.stderr
    record_path = tmp_path / "default" / "run.json"  # as recorded before the key existed
    record = json.loads(record_path.read_text())
    del record["settings"]["dropout_masks"]
    record_path.write_text(json.dumps(record))
    assert skipped(train("default"))
    assert train("default", "dropout_masks=packed").returncode != 0

    # an ensemble draws packed masks unless told; it draws nothing ahead and says so
    assert train("ensemble", "ensemble_seeds=2", policy="annet").returncode == 0
    ahead = train("ensemble_ahead", "ensemble_seeds=2", "draw_ahead=true", policy="annet")
    assert ahead.returncode == 0 and "draw_ahead has no effect" in ahead.stdout + ahead.stderr
    assert metrics("ensemble_ahead") == metrics("ensemble")
    masks = "dropout_masks=bernoulli"
    assert train("ensemble_torch", "ensemble_seeds=2", masks, policy="annet").returncode == 0
    assert metrics("ensemble_torch") != metrics("ensemble")

    for overrides, message in (
        (["dropout_masks=fast"], "dropout_masks: unknown 'fast'; known: ['bernoulli', 'packed']"),
        (["dropout_masks=packed", "draw_ahead=true"], "draw_ahead: draws torch's bernoulli"),
    ):
        bad = train("bad", *overrides)
        assert bad.returncode != 0 and message in bad.stderr, bad.stderr[-2000:]
        written = {path.name for path in (tmp_path / "bad").iterdir()}
        assert written <= {".hydra", "train_bc.log"}, written  # Hydra's own files only


def test_nnet_trains_with_levenberg_marquardt_by_default_and_beats_gradient(datasets):
    _, train, validation = datasets
    data, losses = train.to_tensordict(), {}
    for trainer in (None, "gradient"):
        torch.manual_seed(0)
        actor = make_actor("nnet", sensors=S, stats=train.stats)
        _, history = train_bc(
            actor,
            data,
            validation,
            BCSettings(epochs=3, batch_size=64, trainer=trainer, lm_batch_size=256),
            progress=False,
        )
        losses[trainer] = history[-1]["train_loss"]
    assert losses[None] < 0.5 * losses["gradient"]


def test_trainer_must_fit_the_controller(datasets):
    _, train, _ = datasets
    with pytest.raises(ValueError, match="trainer 'fit' is for the random forest"):
        train_bc(
            make_actor("dannet", sensors=S, stats=train.stats),
            train.to_tensordict(),
            None,
            BCSettings(epochs=1, trainer="fit"),
            progress=False,
        )
    with pytest.raises(ValueError, match="unknown 'adamw'"):
        BCSettings(trainer="adamw")


def _train_with_bcloss(actor, data, validation, settings):
    """The gradient loop as it was written before the contiguous fast path: TorchRL's
    BCLoss on tensordict batches gathered by index (the reference for bit-identity)."""
    from tensordict import TensorDict
    from torchrl.objectives import BCLoss

    policy = actor.module
    torch.manual_seed(settings.seed)
    data = data.select(*policy.in_keys, "action")
    optimizer = torch.optim.RAdam(policy.parameters(), lr=settings.learning_rate)
    loss_module = BCLoss(actor, loss_function="mse")
    history, n = [], data.batch_size[0]
    for epoch in range(settings.epochs):
        policy.train()
        generator = torch.Generator().manual_seed(settings.seed * 1_000_003 + epoch)
        order, total = torch.randperm(n, generator=generator), 0.0
        for start in range(0, n, settings.batch_size):
            batch: TensorDict = data[order[start : start + settings.batch_size]]
            loss = loss_module(batch)["loss_bc"]
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * batch.batch_size[0]
        history.append({"epoch": epoch + 1, "train_loss": total / n})
        history[-1]["validation_loss"] = validation_loss(actor, validation)
    return actor, history, torch.get_rng_state()


def test_gradient_step_matches_the_bcloss_path(datasets):
    """The contiguous-tensor step gives bit-identical losses, weights and RNG state to
    BCLoss on indexed tensordicts (DANNet: dropout draws, s' wider than s)."""
    _, train, validation = datasets
    data = train.to_tensordict()
    wider = [*S, "boom_pressure", "bucket_pressure", "pump_angle"]
    settings = BCSettings(epochs=2, batch_size=100, seed=7)

    def fresh():
        torch.manual_seed(11)
        return make_actor("dannet", sensors=S, stats=train.stats, attention_sensors=wider)

    reference, expected, expected_rng = _train_with_bcloss(fresh(), data, validation, settings)
    actor, history = train_bc(fresh(), data, validation, settings, progress=False)
    assert history == expected
    assert torch.equal(torch.get_rng_state(), expected_rng)
    want = reference.module.state_dict()
    got = actor.module.state_dict()
    assert all(torch.equal(got[k], want[k]) for k in want)


def test_masks_drawn_ahead_give_the_same_run(datasets, tmp_path, monkeypatch):
    """draw_ahead=True: torch's masks drawn on a second thread give bit-identical losses,
    weights and RNG state (DANNet, s' wider than s, a short last batch), with resume."""
    _, train, validation = datasets
    data = train.to_tensordict()
    wider = [*S, "boom_pressure", "bucket_pressure", "pump_angle"]
    assert data.batch_size[0] % 100 != 0  # batches of 100: a short last batch

    def run(draw_ahead: bool, epochs: int = 3, run_dir: Path | None = None):
        torch.manual_seed(11)
        actor = make_actor("dannet", sensors=S, stats=train.stats, attention_sensors=wider)
        settings = BCSettings(epochs=epochs, batch_size=100, seed=7)
        actor, history = train_bc(
            actor, data, validation, settings, run_dir=run_dir, progress=False,
            draw_ahead=draw_ahead,
        )  # fmt: skip
        return actor, history, torch.get_rng_state()

    reference, expected, expected_rng = run(False)
    drawn = []  # the masks really are drawn ahead: one draw per gradient step
    next_step = MasksAhead.next_step
    monkeypatch.setattr(MasksAhead, "next_step", lambda feed: drawn.append(1) or next_step(feed))
    actor, history, rng = run(True)
    monkeypatch.undo()
    assert len(drawn) == 3 * math.ceil(data.batch_size[0] / 100)
    assert history == expected
    assert torch.equal(rng, expected_rng)
    want, got = reference.module.state_dict(), actor.module.state_dict()
    assert all(torch.equal(got[k], want[k]) for k in want)
    layers = [type(m) for m in actor.module.modules() if "Dropout" in type(m).__name__]
    assert layers == [torch.nn.Dropout] * 4  # put back after training
    run(True, epochs=2, run_dir=tmp_path)  # "killed" after 2 epochs
    resumed, history, _ = run(True, run_dir=tmp_path)
    assert history == expected
    assert all(torch.equal(resumed.module.state_dict()[k], want[k]) for k in want)
    with pytest.raises(ValueError, match="draw_ahead draws torch's bernoulli masks"):
        train_bc(
            make_actor("dannet", sensors=S, stats=train.stats), data, None,
            BCSettings(epochs=1, dropout_masks="packed"), progress=False, draw_ahead=True,
        )  # fmt: skip


def test_draw_ahead_with_nothing_to_draw_trains_as_without_and_warns_once(datasets, caplog):
    """draw_ahead where no dropout mask is drawn by a gradient step (NNet's default
    Levenberg-Marquardt, a controller without dropout, the forest's fit): the same run as
    without it, and one warning per call that it has no effect (not an error: it cannot
    change a result, and a sweep over controllers would stop on NNet)."""
    _, train, validation = datasets
    data = train.to_tensordict()
    cases = {
        "levenberg_marquardt trainer's steps are not drawn ahead": ("nnet", {}),
        "'nnetv2' has no dropout layer with p > 0": ("nnetv2", {"dropout": 0.0}),
        "the random forest is fitted": ("rf", {"n_estimators": 2}),
    }
    for reason, (controller, options) in cases.items():
        runs = []
        for draw_ahead in (False, True):
            torch.manual_seed(5)
            actor = make_actor(controller, sensors=S, stats=train.stats, options=options)
            caplog.clear()
            _, history = train_bc(
                actor, data, validation, BCSettings(epochs=2, batch_size=64), progress=False,
                draw_ahead=draw_ahead,
            )  # fmt: skip
            warnings = [r.getMessage() for r in caplog.records if "draw_ahead" in r.getMessage()]
            runs.append((history, warnings))
        (plain, none), (ahead, warned) = runs
        assert ahead == plain and none == []
        assert len(warned) == 1 and "draw_ahead has no effect" in warned[0], warned
        assert reason in warned[0], warned


def test_ensemble_members_equal_separate_runs(datasets):
    _, train, _ = datasets
    data = train.to_tensordict()
    config = make_actor("nnet", sensors=S, stats=train.stats).module.config
    settings = BCSettings(epochs=2, batch_size=64, trainer="gradient")
    result = train_bc_ensemble(config, [0, 1], data, None, settings, progress=False)
    assert result.train_loss.shape == (2, 2)
    for member, seed in zip(result.members, [0, 1], strict=True):
        torch.manual_seed(seed)
        alone, _ = train_bc(
            make_actor("nnet", sensors=S, stats=train.stats), data, None, settings, progress=False
        )
        expected = alone.module.state_dict()
        assert all(torch.equal(member.state_dict()[k], expected[k]) for k in expected)


def test_ensemble_with_dropout_learns_and_members_differ(datasets):
    _, train, validation = datasets
    config = make_actor("dannet", sensors=S, stats=train.stats).module.config
    result = train_bc_ensemble(
        config,
        [0, 1, 2],
        train.to_tensordict(),
        validation,
        BCSettings(epochs=6, batch_size=64),
        progress=False,
    )
    assert result.validation_loss.shape == (3, 6)
    assert (result.validation_loss[:, -1] < result.validation_loss[:, 0]).all()
    assert len(set(result.validation_loss[:, -1].round(8))) == 3


def test_the_ensemble_draws_packed_masks_unless_told_otherwise(datasets):
    """The ensemble's default mask draw is the packed one (one random word per four mask
    elements), and ``dropout_masks="bernoulli"`` gives torch's own draws: other weights."""
    _, train, _ = datasets
    config = make_actor("dannet", sensors=S, stats=train.stats).module.config

    def weights(**masks):
        settings = BCSettings(epochs=1, batch_size=128, **masks)
        result = train_bc_ensemble(
            config, [0, 1], train.to_tensordict(), None, settings, progress=False
        )
        return [m.state_dict() for m in result.members]

    default, packed, bernoulli = (
        weights(),
        weights(dropout_masks="packed"),
        weights(dropout_masks="bernoulli"),
    )
    for got, want, other in zip(default, packed, bernoulli, strict=True):
        assert all(torch.equal(got[k], want[k]) for k in want)
        assert not all(torch.equal(got[k], other[k]) for k in other)


@pytest.mark.parametrize("masks", ["packed", "bernoulli"])
def test_ensemble_passes_train_what_each_group_of_seeds_trains_alone(datasets, masks):
    """Members trained members_per_pass at a time: each pass is the ensemble of its
    seeds alone, bit for bit (DANNet: dropout drawn per pass), with either mask draw."""
    _, train, validation = datasets
    data = train.to_tensordict()
    config = make_actor("dannet", sensors=S, stats=train.stats).module.config
    settings = BCSettings(epochs=1, batch_size=128, dropout_masks=masks)

    def ensemble(seeds, members_per_pass):
        return train_bc_ensemble(
            config,
            seeds,
            data,
            validation,
            settings,
            progress=False,
            members_per_pass=members_per_pass,
        )

    in_passes = ensemble([0, 1, 2], 2)
    alone = [ensemble([0, 1], 2), ensemble([2], 2)]
    assert in_passes.validation_loss.shape == (3, 1)
    assert (in_passes.train_loss == np.concatenate([a.train_loss for a in alone])).all()
    expected = [member for a in alone for member in a.members]
    for got, want in zip(in_passes.members, expected, strict=True):
        assert all(torch.equal(got.state_dict()[k], v) for k, v in want.state_dict().items())
    with pytest.raises(ValueError, match="members_per_pass >= 1"):
        ensemble([0], 0)


def test_train_bc_recipe_ensemble_mode_plots_mean_and_std(datasets, tmp_path):
    root, _, _ = datasets
    result = train_bc_recipe(
        f"hydra.run.dir={tmp_path}",
        "epochs=2",
        "batch_size=64",
        "policy=annet",
        "ensemble_seeds=3",
        data_root=root,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert (tmp_path / "ensemble.png").stat().st_size > 0
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["seeds"] == 3 and metrics["final_loss_std"] > 0


def test_optuna_sweeper_searches_the_learning_rate(datasets, tmp_path):
    root, _, _ = datasets
    result = train_bc_recipe(
        "--multirun",
        "hydra/sweeper=bc_optuna",
        "hydra.sweeper.n_trials=3",
        f"hydra.sweep.dir={tmp_path}",
        "epochs=2",
        "policy=nnetv2",
        "logger=none",
        data_root=root,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    best = yaml.safe_load((tmp_path / "optimization_results.yaml").read_text())
    assert 1e-4 <= best["best_params"]["learning_rate"] <= 1e-2
    assert best["best_params"]["batch_size"] in (128, 256, 512)
    losses = [
        json.loads((tmp_path / str(i) / "metrics.json").read_text())["best_validation_loss"]
        for i in range(3)
    ]
    assert best["best_value"] == pytest.approx(min(losses))
