"""TorchRL metric loggers by name, as the ``logger`` config group selects them."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

BACKENDS = ("csv", "tensorboard", "wandb", "none")
PACKAGES = {"tensorboard": "tensorboard", "wandb": "wandb"}  # backend -> package it needs
WANDB_PROJECT = "pilerl"


def make_logger(backend: str, run_dir: str | Path, *, experiment_name: str):
    """A TorchRL logger writing under ``run_dir``, or ``None`` for ``backend="none"``.

    Args:
        backend: ``csv``, ``tensorboard``, ``wandb`` or ``none``.
        run_dir: the run's directory (the logger's files go below it).
        experiment_name: sub-directory / run name (``bc``, ``ppo``...).

    Weights & Biases runs offline unless ``WANDB_MODE`` says otherwise (``WANDB_MODE=online``
    after ``wandb login``): its files go to ``run_dir/wandb`` and ``wandb sync`` uploads
    them later. The project is ``WANDB_PROJECT`` (default ``pilerl``).
    """
    from torchrl.record.loggers import get_logger

    if backend not in BACKENDS:
        raise ValueError(f"logger: unknown backend {backend!r}; known: {list(BACKENDS)}")
    if backend == "none":
        return None
    package = PACKAGES.get(backend)
    if package is not None and importlib.util.find_spec(package) is None:
        raise ValueError(f"logger={backend} needs the {package} package: pip install {package}")
    if backend == "wandb":
        mode = os.environ.get("WANDB_MODE", "offline")
        wandb_kwargs = {
            "offline": mode == "offline",
            "project": os.environ.get("WANDB_PROJECT", WANDB_PROJECT),
            "mode": mode,
        }
        return get_logger(
            backend,
            logger_name=str(run_dir),
            experiment_name=experiment_name,
            wandb_kwargs=wandb_kwargs,
        )
    return get_logger(backend, logger_name=str(run_dir), experiment_name=experiment_name)
