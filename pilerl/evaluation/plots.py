"""Plots a person looks at: sensors, controls and the task's state over one episode."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from pilerl.figures import legend_outside, save_figure
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator

from .episode import Episode

DEPTH_TRACE = "cutting_depth_m"  # the pile loader's cutting depth [m], drawn beside the fill
HALF_FULL = 0.5  # the fill drawn as a reference line [fraction]


def plot_scoop(
    episodes: dict[str, Episode], path: str | Path, *, simulator: str = DEFAULT_SIMULATOR
) -> Path:
    """One column per labelled episode: a row per sensor unit (the pile loader's angles
    [rad] and pressures [MPa]), the controls, then the fill (and the cutting depth where
    reported)."""
    plugin = get_simulator(simulator)
    units = list(dict.fromkeys(spec.unit for spec in plugin.sensors.values()))
    rows, columns = len(units) + 2, len(episodes)
    fig, axes = plt.subplots(
        rows, columns, figsize=(5.5 * columns, 2.5 * rows), sharex="col", squeeze=False
    )
    for col, (label, ep) in enumerate(episodes.items()):
        t = ep.time_s
        for row, unit in enumerate(units):
            ax = axes[row, col]
            for name, spec in plugin.sensors.items():
                if spec.unit == unit and name in ep.sensors:
                    ax.plot(t, ep.sensors[name], label=name)
            ax.set_ylabel(f"[{unit}]")
        axes[0, col].set_title(label)
        ax = axes[-2, col]
        for i, name in enumerate(plugin.controls[: ep.actions.shape[1]]):
            ax.plot(t, ep.actions[:, i], label=name)
        ax.set_ylabel("control [-1, 1]")
        ax = axes[-1, col]
        if plugin.fill_key and plugin.fill_key in ep.info:
            ax.plot(t, ep.info[plugin.fill_key][1:], label=plugin.fill_key.replace("_", " "))
        if DEPTH_TRACE in ep.traces:
            ax.plot(t, ep.traces[DEPTH_TRACE], label="cutting depth [m]")
        ax.axhline(HALF_FULL, color="grey", linestyle=":", linewidth=1, label="half full")
        ax.set_xlabel("time [s]")
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
            legend_outside(ax)
    return save_figure(fig, path)
