"""One closed-loop evaluation run: episodes, summary, plots and chosen videos in a directory.

This is what ``recipes/evaluate.py`` and the last step of ``recipes/train_bc.py`` call.
Files written to ``out_dir``:

- ``episodes.csv``: one row per episode (start pose, fill, success, time, slip, spill).
- ``summary.json``: per condition (and pooled ``winter``) success rate with its 95% Wilson
  interval and the fill / time / slip / spill statistics.
- ``success.png``: success rate per condition with interval bars.
- ``fill.png``: the fill-fraction distribution per condition (success threshold marked).
- ``videos/<condition>_episode<i>.mp4`` (``videos=True``): the median-fill episode of each
  condition and its first failure, re-run with rendering (episodes are deterministic per
  seed, so the video shows exactly the evaluated episode).
"""

from __future__ import annotations

import logging
import math
import statistics
from collections.abc import Collection, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from pilerl.figures import legend_outside, plt, save_figure
from pilerl.sim import get_simulator, make_gym_env

from .episode import make_episode_env, run_episode
from .evaluator import EvaluationPlan, evaluate, resolve_controller, summarize, write_results
from .video import annotate_frames, sensor_ranges, write_mp4

log = logging.getLogger(__name__)
SUCCESS_FILL = 0.5  # the paper: a scoop succeeds when the bucket is at least half full


def run_closed_loop(
    controller,
    plan: EvaluationPlan,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    videos: bool = False,
    video_conditions: Sequence[str] | None = None,
    render_size: tuple[int, int] = (360, 640),
    camera: str = "side",
    progress: bool = True,
) -> dict[str, dict]:
    """Evaluate ``controller`` on ``plan`` and write results, plots and videos to ``out_dir``.

    Args:
        controller: ``ScriptedController``, ``ActorController`` or ``ActorWeights``.
        plan: simulator, conditions, episodes per condition and base seed.
        workers: episode processes (default: one per core).
        videos: render the chosen rollouts to mp4.
        video_conditions: render only these conditions' rollouts (``None``: all).
        render_size: video frame (height, width) [px].
        camera: MJCF camera of the videos.

    Returns the summary (as in ``summary.json``).
    """
    out_dir = Path(out_dir)
    checkpoint = getattr(controller, "checkpoint", None)
    if checkpoint is not None:  # a controller cloned at another rate acts differently
        from pilerl.policies.checkpoint import warn_if_other_control_rate

        control_hz = plan.env_kwargs.get("control_hz")
        if control_hz is None:  # the simulator's default rate: ask one env
            probe = make_gym_env(plan.simulator, **plan.env_kwargs, condition=plan.conditions[0])
            control_hz = 1.0 / float(probe.unwrapped.dt)
            probe.close()
        warn_if_other_control_rate(checkpoint, float(control_hz))
    controller = resolve_controller(controller)  # a saved actor is read once, here
    records = evaluate(controller, plan, workers=workers, progress=progress)
    summary = summarize(
        records,
        groups=get_simulator(plan.simulator).condition_groups,
        simulator=plan.simulator,
    )
    # --- results first: a person can read them while the videos render
    write_results(records, summary, out_dir)
    pooled = set(summary) - set(plan.conditions)
    plot_success(summary, out_dir / "success.png", title=controller.name, pooled=pooled)
    plot_fill(records, out_dir / "fill.png", title=controller.name)
    log_summary(controller.name, summary)
    if videos:
        chosen = [
            record
            for record in chosen_rollouts(records)
            if video_conditions is None or record["condition"] in video_conditions
        ]
        for record in tqdm(chosen, desc=f"videos {controller.name}", disable=not progress):
            path = out_dir / "videos" / f"{record['condition']}_episode{record['episode']}.mp4"
            render_rollout(controller, plan, record, path, render_size=render_size, camera=camera)
        log.info("%d videos in %s", len(chosen), out_dir / "videos")
    return summary


def log_summary(name: str, summary: dict[str, dict]) -> None:
    """One log line per condition: successes, rate with its 95% interval, fill (mean and
    quartiles) and the median cycle time of the finished scoops."""
    for condition, row in summary.items():
        log.info(
            "%s %s: %d/%d successful (%.0f%%, 95%% CI %.0f-%.0f%%), mean fill %.2f "
            "(quartiles %.2f-%.2f), median cycle %.1f s",
            name,
            condition,
            row["successes"],
            row["episodes"],
            100 * row["success_rate"],
            100 * row["success_low"],
            100 * row["success_high"],
            row["fill_mean"],
            row.get("fill_p25", math.nan),
            row.get("fill_p75", math.nan),
            row.get("cycle_time_s_median", math.nan),
        )


def chosen_rollouts(records: list[dict]) -> list[dict]:
    """Per condition: the episode with the median fill, and the first failure if any."""
    chosen = []
    for condition in dict.fromkeys(r["condition"] for r in records):
        rows = [r for r in records if r["condition"] == condition]
        median = statistics.median_low([r["fill_fraction"] for r in rows])
        chosen.append(next(r for r in rows if r["fill_fraction"] == median))
        failure = next((r for r in rows if not r["success"]), None)
        if failure is not None and failure is not chosen[-1]:
            chosen.append(failure)
    return chosen


def render_rollout(
    controller,
    plan: EvaluationPlan,
    record: dict,
    path: str | Path,
    *,
    render_size: tuple[int, int] = (360, 640),
    camera: str = "side",
) -> Path:
    """Re-run the evaluated episode ``record`` with rendering and write it as an mp4."""
    controller = resolve_controller(controller)
    env = make_episode_env(
        plan.simulator,
        {
            **plan.env_kwargs,
            "condition": record["condition"],
            "render_mode": "rgb_array",
            "render_size": render_size,
            "camera": camera,
        },
    )
    episode = run_episode(env, controller.policy(env), seed=record["seed"], render=True)
    ranges = sensor_ranges(env.simulators[0])
    env.close()
    fill_key = get_simulator(plan.simulator).fill_key or "fill_fraction"
    if abs(float(episode.final_info.get(fill_key, math.nan)) - record["fill_fraction"]) > 1e-6:
        log.warning("%s: the re-rendered episode differs from the evaluated one", path)
    frames = annotate_frames(
        episode, condition=record["condition"], sensor_ranges=ranges, simulator=plan.simulator
    )
    return write_mp4(frames, path, fps=episode.frame_hz)


def plot_success(
    summary: dict[str, dict], path: str | Path, *, title: str = "", pooled: Collection[str] = ()
) -> Path:
    """Success rate per condition (``pooled`` entries hatched) with 95% Wilson intervals."""
    names = list(summary)
    rates = np.array([summary[n]["success_rate"] for n in names])
    low = rates - np.array([summary[n]["success_low"] for n in names])
    high = np.array([summary[n]["success_high"] for n in names]) - rates
    fig, ax = plt.subplots(figsize=(1.2 + 1.1 * len(names), 3.2))
    bars = ax.bar(names, 100 * rates, yerr=100 * np.vstack([low, high]), capsize=4)
    for bar, name in zip(bars, names, strict=True):
        if name in pooled:
            bar.set_hatch("//")
        n = summary[name]
        ax.annotate(
            f"{n['successes']}/{n['episodes']}",
            (bar.get_x() + bar.get_width() / 2, 2),
            ha="center",
            fontsize=8,
        )
    ax.set_ylim(0, 105)
    ax.set_ylabel("success rate [%] (95% CI)")
    ax.set_title(title)
    return save_figure(fig, path)


def plot_fill(records: list[dict], path: str | Path, *, title: str = "") -> Path:
    """Fill fraction of every episode, one column of points per condition."""
    conditions = list(dict.fromkeys(r["condition"] for r in records))
    fig, ax = plt.subplots(figsize=(1.2 + 1.1 * len(conditions), 3.2))
    for i, condition in enumerate(conditions):
        fills = [r["fill_fraction"] for r in records if r["condition"] == condition]
        offsets = np.linspace(-0.2, 0.2, len(fills)) if len(fills) > 1 else [0.0]
        ax.scatter(i + np.asarray(offsets), fills, s=12)
    ax.axhline(SUCCESS_FILL, color="k", lw=0.8, ls="--", label="success: half full")
    ax.set_xticks(range(len(conditions)), conditions)
    ax.set_ylabel("fill fraction")
    ax.set_title(title)
    legend_outside(ax, fontsize=8)
    return save_figure(fig, path)
