"""Summaries of recorded scoops: per-episode numbers, a CSV trace, a Markdown report.

Every number is in the simulator's words: its declared success and fill, its own episode
columns (``episode_columns``: the pile loader's start pose, finish, slip, spill, lift
and failure mode) and the peak of each sensor, named with its unit
(``peak_drive_pressure_mpa``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from pilerl.io import atomic_path, write_text_atomic
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator

from .episode import Episode


def summarize(ep: Episode, *, simulator: str = DEFAULT_SIMULATOR) -> dict[str, float | bool | str]:
    """The numbers a person checks first after a scoop of ``simulator``."""
    plugin = get_simulator(simulator)
    final = ep.final_info
    success = bool(final.get(plugin.success_key, False))
    fill = float(final.get(plugin.fill_key, np.nan)) if plugin.fill_key else float(success)
    declared = {k: ep.info[k] for k in plugin.episode_info if k in ep.info}
    sensors = {
        name: np.concatenate([[ep.start_sensors[name]], ep.sensors[name]])
        for name in plugin.sensors
        if name in ep.sensors and name in ep.start_sensors
    }
    controls = {name: ep.actions[:, i] for i, name in enumerate(plugin.controls)}
    summary: dict[str, float | bool | str] = {
        "fill_fraction": fill,
        "success": success,
        "duration_s": float(ep.time_s[-1]),
        "return": float(ep.rewards.sum()),
        **plugin.episode_outcome(
            info=declared, sensors=sensors, controls=controls, success=success, where="scoop"
        ),
    }
    for name, readings in ep.sensors.items():
        unit = re.sub(r"\W+", "_", plugin.sensors[name].unit.lower()).strip("_")
        summary[f"peak_{name}_{unit}" if unit else f"peak_{name}"] = float(readings.max())
    return summary


def write_trace_csv(ep: Episode, path: str | Path, *, simulator: str = DEFAULT_SIMULATOR) -> Path:
    """One row per control step: time, sensors, controls (``u_<control>``), traces."""
    columns = {"time_s": ep.time_s, **ep.sensors}
    for i, name in enumerate(get_simulator(simulator).controls[: ep.actions.shape[1]]):
        columns[f"u_{name}"] = ep.actions[:, i]
    columns.update(ep.traces)
    columns["reward"] = ep.rewards
    table = np.column_stack(list(columns.values()))
    path = Path(path)
    with atomic_path(path) as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(columns), comments="", fmt="%.6g")
    return path


def write_scoop_report(
    summaries: dict[str, dict],
    out_dir: str | Path,
    *,
    seed: int,
    figures: list[str],
    videos: list[str],
    simulator: str = DEFAULT_SIMULATOR,
) -> Path:
    """``summary.json`` and ``report.md`` for scoops recorded under several conditions (with
    the simulator's ``report_notes`` on reading them)."""
    out_dir = Path(out_dir)
    write_text_atomic(out_dir / "summary.json", json.dumps(summaries, indent=2))
    keys = list(next(iter(summaries.values())))
    lines = [
        "# Scripted scoops",
        "",
        f"One episode per condition, seed {seed}, scripted operator (pilerl.operators).",
        "",
        "| condition | " + " | ".join(keys) + " |",
        "|---|" + "---:|" * len(keys),
    ]
    for condition, summary in summaries.items():
        cells = [f"{v:.3g}" if isinstance(v, float) else str(v) for v in summary.values()]
        lines.append(f"| {condition} | " + " | ".join(cells) + " |")
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    if videos:
        lines += ["", "## Videos", ""] + [f"- [{v}]({v})" for v in videos]
    notes = get_simulator(simulator).report_notes
    if notes:
        lines += ["", "## Reading the numbers", "", *notes]
    path = out_dir / "report.md"
    write_text_atomic(path, "\n".join(lines) + "\n")
    return path
