"""TorchRL loggers by name: csv, TensorBoard and Weights & Biases (offline) write files."""

from __future__ import annotations

import pytest

from pilerl.loggers import BACKENDS, LoggerConfig, make_logger


def test_tensorboard_writes_an_event_file(tmp_path):
    logger = make_logger("tensorboard", tmp_path, experiment_name="bc")
    logger.log_scalar("train_loss", 0.5, step=1)
    logger.experiment.flush()
    assert list(tmp_path.rglob("events.out.tfevents.*"))


def test_wandb_runs_offline_and_keeps_its_files_in_the_run(tmp_path, monkeypatch):
    monkeypatch.delenv("WANDB_MODE", raising=False)
    monkeypatch.setenv("WANDB_SILENT", "true")
    logger = make_logger("wandb", tmp_path, experiment_name="bc")
    try:
        logger.log_scalar("train_loss", 0.5, step=1)
    finally:
        logger.experiment.finish()
    runs = list((tmp_path / "wandb").glob("offline-run-*"))
    assert runs and list(runs[0].glob("*.wandb"))


def test_unknown_backends_name_the_known_ones(tmp_path):
    with pytest.raises(ValueError, match="known: \\['csv', 'tensorboard', 'wandb', 'none'\\]"):
        make_logger("comet", tmp_path, experiment_name="bc")
    with pytest.raises(ValueError, match="unknown 'comet'"):
        LoggerConfig(backend="comet")
    assert make_logger("none", tmp_path, experiment_name="bc") is None
    assert set(BACKENDS) == {"csv", "tensorboard", "wandb", "none"}
