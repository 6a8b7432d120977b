"""TorchRL metric loggers by name, as the ``logger`` config group selects them."""

from __future__ import annotations

import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

from pilerl.registry import Registry

# backend -> the package it needs (None: TorchRL alone, or no logger)
LOGGERS: Registry[str | None] = Registry(
    "logger", {"csv": None, "tensorboard": "tensorboard", "wandb": "wandb", "none": None}
)
BACKENDS = tuple(LOGGERS)
WANDB_PROJECT = "pilerl"


@dataclass
class LoggerConfig:
    """A TorchRL metric logger (the ``logger`` config group).

    Attributes:
        backend: ``csv`` (default; files under the run directory), ``tensorboard`` (needs the
            ``tensorboard`` package), ``wandb`` (offline unless ``WANDB_MODE`` says otherwise)
            or ``none``.
    """

    backend: str = "csv"

    def __post_init__(self) -> None:
        LOGGERS.check("logger.backend", self.backend)


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

    LOGGERS.check("logger", backend)
    if backend == "none":
        return None
    package = LOGGERS[backend]
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
