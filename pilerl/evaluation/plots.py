"""Plots a person looks at: sensors, controls and bucket state over one scoop."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from pilerl.figures import legend_outside, save_figure

from .episode import Episode

ANGLES = ("boom_angle", "bucket_angle", "pump_angle")
PRESSURES = ("drive_pressure", "telescope_pressure", "boom_pressure", "bucket_pressure")
CONTROLS = ("boom", "bucket", "throttle")


def plot_scoop(episodes: dict[str, Episode], path: str | Path) -> Path:
    """One column per labelled episode: angles, pressures, controls, fill and depth."""
    columns = len(episodes)
    fig, axes = plt.subplots(4, columns, figsize=(5.5 * columns, 10), sharex="col", squeeze=False)
    for col, (label, ep) in enumerate(episodes.items()):
        t = ep.time_s
        ax = axes[0, col]
        for name in ANGLES:
            if name in ep.sensors:
                ax.plot(t, ep.sensors[name], label=name)
        ax.set_ylabel("angle [rad]")
        ax.set_title(label)
        ax = axes[1, col]
        for name in PRESSURES:
            if name in ep.sensors:
                ax.plot(t, ep.sensors[name], label=name)
        ax.set_ylabel("pressure [MPa]")
        ax = axes[2, col]
        for i, name in enumerate(CONTROLS[: ep.actions.shape[1]]):
            ax.plot(t, ep.actions[:, i], label=name)
        ax.set_ylabel("control [-1, 1]")
        ax = axes[3, col]
        if "fill_fraction" in ep.traces:
            ax.plot(t, ep.traces["fill_fraction"], label="fill fraction")
        if "cutting_depth_m" in ep.traces:
            ax.plot(t, ep.traces["cutting_depth_m"], label="cutting depth [m]")
        ax.axhline(0.5, color="grey", linestyle=":", linewidth=1, label="half full")
        ax.set_xlabel("time [s]")
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
            legend_outside(ax)
    return save_figure(fig, path)
