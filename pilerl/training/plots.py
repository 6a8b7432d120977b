"""Training curves a person can look at."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pilerl.io import atomic_path  # noqa: E402


def plot_losses(history: list[dict], path: str | Path, *, title: str = "") -> Path:
    """Training and validation MSE per epoch (log scale)."""
    epochs = [row["epoch"] for row in history]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(epochs, [row["train_loss"] for row in history], marker=".", label="train")
    if all("validation_loss" in row for row in history):
        ax.plot(epochs, [row["validation_loss"] for row in history], marker=".", label="validation")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE of the controls")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def plot_ensemble(train_loss, validation_loss, path: str | Path, *, title: str = "") -> Path:
    """Mean +- std over seeds per epoch (arrays of shape (members, epochs)); the paper's
    Fig. 4 style."""
    import numpy as np

    fig, ax = plt.subplots(figsize=(6, 4))
    for label, losses in (("train", train_loss), ("validation", validation_loss)):
        if losses is None:
            continue
        epochs = np.arange(1, losses.shape[1] + 1)
        mean, std = losses.mean(0), losses.std(0)
        ax.plot(epochs, mean, label=f"{label} (mean of {losses.shape[0]} seeds)")
        ax.fill_between(epochs, mean - std, mean + std, alpha=0.25)
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE of the controls")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path
