"""Packed dropout masks drawn ahead on a second thread: the run of packed masks drawn in
the step, bit for bit (train_bc's draw_packed_ahead, the recipe's key)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch
from test_training import S, train_bc_recipe

from pilerl.policies import make_actor
from pilerl.training import BCSettings, train_bc
from pilerl.training.draw_ahead import MasksAhead
from pilerl.training.settings import TrainBCConfig

WIDER = [*S, "boom_pressure", "bucket_pressure", "pump_angle"]


def counted(next_step, calls: list):
    """``MasksAhead.next_step`` that also appends to ``calls``."""
    return lambda feed: calls.append(1) or next_step(feed)


def test_packed_masks_drawn_ahead_give_the_run_drawn_in_the_step(datasets, tmp_path, monkeypatch):
    """DANNet (s' wider than s), a short last batch, float32 and float64: equal losses,
    weights and RNG state; a killed run resumes drawing ahead to the same weights."""
    _, train, validation = datasets
    data = train.to_tensordict()
    assert data.batch_size[0] % 100 != 0  # batches of 100: a short last batch

    def run(ahead: bool, epochs: int = 3, run_dir: Path | None = None, dtype=torch.float32):
        torch.manual_seed(11)
        actor = make_actor("dannet", sensors=S, stats=train.stats, attention_sensors=WIDER)
        actor.module.to(dtype)
        settings = BCSettings(epochs=epochs, batch_size=100, seed=7, dropout_masks="packed")
        actor, history = train_bc(
            actor, data, validation, settings, run_dir=run_dir, progress=False,
            draw_packed_ahead=ahead,
        )  # fmt: skip
        return actor, history, torch.get_rng_state()

    for dtype in (torch.float32, torch.float64):
        reference, expected, expected_rng = run(False, dtype=dtype)
        drawn = []  # the masks really are drawn ahead: one draw per gradient step
        monkeypatch.setattr(MasksAhead, "next_step", counted(MasksAhead.next_step, drawn))
        actor, history, rng = run(True, dtype=dtype)
        monkeypatch.undo()
        assert len(drawn) == 3 * math.ceil(data.batch_size[0] / 100)
        assert history == expected
        assert torch.equal(rng, expected_rng)
        want, got = reference.module.state_dict(), actor.module.state_dict()
        assert all(torch.equal(got[k], want[k]) for k in want)
        layers = [type(m) for m in actor.module.modules() if "Dropout" in type(m).__name__]
        assert layers == [torch.nn.Dropout] * 4  # put back after training

    torch_masks, torch_history, _ = run(False, dtype=torch.float32)
    run(True, epochs=2, run_dir=tmp_path)  # "killed" after 2 epochs
    resumed, history, _ = run(True, run_dir=tmp_path)
    assert history == torch_history
    want = torch_masks.module.state_dict()
    assert all(torch.equal(resumed.module.state_dict()[k], want[k]) for k in want)


def test_draw_packed_ahead_needs_packed_masks(datasets):
    _, train, _ = datasets
    data = train.to_tensordict()
    actor = make_actor("dannet", sensors=S, stats=train.stats)
    for masks in (None, "bernoulli"):
        with pytest.raises(ValueError, match="draw_packed_ahead draws packed masks, not 'bern"):
            train_bc(
                actor, data, None, BCSettings(epochs=1, dropout_masks=masks), progress=False,
                draw_packed_ahead=True,
            )  # fmt: skip
    with pytest.raises(ValueError, match="draw_packed_ahead: draws packed masks ahead"):
        TrainBCConfig(train_data="data", output_dir="out", draw_packed_ahead=True)


def test_train_bc_recipe_draws_packed_masks_ahead(datasets, tmp_path, monkeypatch):
    """The recipe's draw_packed_ahead key reaches train_bc and gives the run of packed
    masks drawn in the step (skipped as the same run); without packed masks it exits
    non-zero naming the key, before writing anything."""
    root, _, _ = datasets

    def train(name: str, *overrides: str):
        run_dir = f"hydra.run.dir={tmp_path / name}"
        common = ("epochs=2", "batch_size=64", "policy=dannet", "logger=none")
        return train_bc_recipe(run_dir, *common, *overrides, data_root=root)

    def metrics(name: str) -> dict:
        return json.loads((tmp_path / name / "metrics.json").read_text())

    assert train("packed", "dropout_masks=packed").returncode == 0
    drawn = []
    next_step = MasksAhead.next_step
    monkeypatch.setattr(MasksAhead, "next_step", lambda feed: drawn.append(1) or next_step(feed))
    ahead = train("ahead", "dropout_masks=packed", "draw_packed_ahead=true")
    monkeypatch.undo()
    assert ahead.returncode == 0, ahead.stderr[-2000:]
    assert drawn and metrics("ahead") == metrics("packed")
    again = train("packed", "dropout_masks=packed", "draw_packed_ahead=true")
    assert again.returncode == 0 and "already finished" in again.stdout + again.stderr
    bad = train("bad", "draw_packed_ahead=true")
    assert bad.returncode != 0 and "draw_packed_ahead: draws packed masks" in bad.stderr
    written = {path.name for path in (tmp_path / "bad").iterdir()}
    assert written <= {".hydra", "train_bc.log"}, written
