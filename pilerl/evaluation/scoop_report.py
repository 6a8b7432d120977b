"""Summaries of recorded scoops: per-episode numbers, a CSV trace, a Markdown report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pilerl.io import atomic_path, write_text_atomic

from .episode import Episode

CONTROL_NAMES = ("boom", "bucket", "throttle")


def summarize(ep: Episode) -> dict[str, float | bool | str]:
    """The numbers a person checks first after a scoop."""
    info = ep.final_info
    summary: dict[str, float | bool | str] = {
        "start_distance_m": float(ep.start_info.get("start_distance_m", float("nan"))),
        "approach_angle_deg": float(np.degrees(ep.start_info.get("approach_angle_rad", np.nan))),
        "fill_fraction": float(info.get("fill_fraction", np.nan)),
        "success": bool(info.get("success", False)),
        "scoop_finished": bool(info.get("scoop_finished", False)),
        "duration_s": float(ep.time_s[-1]),
        "return": float(ep.rewards.sum()),
        "spilled_kg": float(info.get("spilled_kg", np.nan)),
    }
    for name in ("drive_pressure", "telescope_pressure"):
        if name in ep.sensors:
            summary[f"peak_{name}_mpa"] = float(ep.sensors[name].max())
    if "wheel_slip_m_s" in ep.traces:
        summary["peak_wheel_slip_m_s"] = float(ep.traces["wheel_slip_m_s"].max())
    return summary


def write_trace_csv(ep: Episode, path: str | Path) -> Path:
    """One row per control step: time, sensors, controls, traces."""
    columns = {"time_s": ep.time_s, **ep.sensors}
    for i, name in enumerate(CONTROL_NAMES[: ep.actions.shape[1]]):
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
) -> Path:
    """``summary.json`` and ``report.md`` for scoops recorded under several conditions."""
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
    lines += [
        "",
        "## Reading the numbers against the paper",
        "",
        "- The paper's winter failure: wheel slip on ice caps the drive pressure p_d, so an",
        "  operator (or a controller) that waits for p_d to rise before lifting never lifts.",
        "  Compare `peak_drive_pressure_mpa` between summer and the icy conditions (winter_b,",
        "  winter_c): summer reaches the HST relief pressure (25 MPa), ice does not.",
        "- The telescope pressure p_t still rises on ice as the bucket penetrates",
        "  (`peak_telescope_pressure_mpa`), which is why the paper found p_t essential.",
        "- The simulator's numbers are a model's (docs/machine_model.md lists every",
        "  assumption); they are not measurements of the paper's machine.",
    ]
    path = out_dir / "report.md"
    write_text_atomic(path, "\n".join(lines) + "\n")
    return path
