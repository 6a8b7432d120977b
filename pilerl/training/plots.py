"""Training curves a person can look at."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from pilerl.figures import legend_outside, save_figure


def plot_losses(history: list[dict], path: str | Path, *, title: str = "") -> Path:
    """Training and validation MSE per epoch of one run (log scale)."""
    curves = {"train": np.array([[row["train_loss"] for row in history]])}
    if all("validation_loss" in row for row in history):
        curves["validation"] = np.array([[row["validation_loss"] for row in history]])
    return _plot_curves(curves, path, title=title)


def plot_ensemble(
    train_loss: np.ndarray, validation_loss: np.ndarray | None, path: str | Path, *, title: str = ""
) -> Path:
    """Mean +- std over seeds per epoch, arrays (members, epochs): the paper's Fig. 4."""
    curves = {"train": train_loss}
    if validation_loss is not None:
        curves["validation"] = validation_loss
    return _plot_curves(curves, path, title=title)


def _plot_curves(curves: dict[str, np.ndarray], path: str | Path, *, title: str) -> Path:
    fig, ax = plt.subplots(figsize=(6, 4))
    for label, losses in curves.items():
        epochs = np.arange(1, losses.shape[1] + 1)
        mean = losses.mean(0)
        name = label if losses.shape[0] == 1 else f"{label} (mean of {losses.shape[0]} seeds)"
        ax.plot(epochs, mean, marker="." if len(epochs) < 40 else None, label=name)
        if losses.shape[0] > 1:
            std = losses.std(0)
            ax.fill_between(epochs, mean - std, mean + std, alpha=0.25)
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE of the controls")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    legend_outside(ax, fontsize=8)
    return save_figure(fig, path)
