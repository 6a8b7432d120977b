"""TorchRL metric loggers by name, as the ``logger`` config group selects them."""

from __future__ import annotations

import importlib.util
from pathlib import Path


def make_logger(backend: str, run_dir: str | Path, *, experiment_name: str):
    """A TorchRL logger writing under ``run_dir``, or ``None`` for ``backend="none"``.

    Args:
        backend: ``csv``, ``tensorboard`` or ``none``.
        run_dir: the run's directory (the logger's files go below it).
        experiment_name: sub-directory / run name (``bc``, ``ppo``...).
    """
    from torchrl.record.loggers import get_logger

    if backend == "none":
        return None
    if backend == "tensorboard" and importlib.util.find_spec("tensorboard") is None:
        raise ValueError(
            "logger=tensorboard needs the tensorboard package: pip install tensorboard"
        )
    if backend not in ("csv", "tensorboard"):
        raise ValueError(f"logger: unknown backend {backend!r}; known: csv, tensorboard, none")
    return get_logger(backend, logger_name=str(run_dir), experiment_name=experiment_name)
