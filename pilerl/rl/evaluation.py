"""Closed-loop evaluation of a fine-tuning run: pooled success per condition group.

A group pools several conditions into one success rate with a Wilson interval (by
default the simulator's declared groups: the pile loader's "winter" = A-D, the way the
paper's winter tests mixed days). Episodes come from
``pilerl.evaluation.evaluator.evaluate`` on the actor in memory (or a saved one), so
fine-tuned and cloned actors are compared on the same seeded starts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from torch import nn

from pilerl.evaluation.evaluator import (
    ActorController,
    ActorWeights,
    EvaluationPlan,
    evaluate,
    summarize_rows,
)
from pilerl.figures import legend_outside, plt, save_figure
from pilerl.sim import DEFAULT_SIMULATOR

# never NaN, so results.json stays strict JSON (time to fill is NaN without a success)
POOLED_FIELDS = (
    "successes",
    "episodes",
    "success_rate",
    "success_low",
    "success_high",
    "fill_mean",
    "failure_modes",
)


def pool_groups(
    records: Sequence[dict],
    groups: Mapping[str, Sequence[str]],
    *,
    confidence: float = 0.95,
    simulator: str = DEFAULT_SIMULATOR,
) -> dict[str, dict]:
    """Per group, from the evaluator's summary of the episodes in the group's conditions:
    ``POOLED_FIELDS`` (success with its Wilson interval, mean fill, ``simulator``'s failure
    modes)."""
    pooled = {}
    for group, conditions in groups.items():
        rows = [r for r in records if r["condition"] in set(conditions)]
        if not rows:
            raise ValueError(f"evaluation group {group!r}: no episodes in {list(conditions)}")
        summary = summarize_rows(rows, confidence, simulator=simulator)
        pooled[group] = {name: summary[name] for name in POOLED_FIELDS}
    return pooled


def evaluate_groups(
    actor: nn.Module | str | Path,
    groups: Mapping[str, Sequence[str]],
    *,
    simulator: str,
    env_kwargs: Mapping[str, object],
    episodes: int,
    seed: int,
    workers: int = 1,
    confidence: float = 0.95,
) -> tuple[dict[str, dict], list[dict], EvaluationPlan]:
    """(pooled success per group, one record per episode, the plan) of ``actor``: an actor
    in memory (its weights as they are now go to the evaluation workers), a saved one, or
    an evaluation controller (``ActorWeights``, ``pilerl.rl.residual.ResidualWeights``)."""
    conditions = tuple(dict.fromkeys(c for members in groups.values() for c in members))
    plan = EvaluationPlan(
        simulator=simulator,
        env_kwargs=dict(env_kwargs),
        conditions=conditions,
        episodes=episodes,
        seed=seed,
    )
    if isinstance(actor, str | Path):
        controller = ActorController(str(actor))
    elif isinstance(actor, nn.Module):
        controller = ActorWeights.of(actor)
    else:  # a controller already (``pilerl.rl.residual.controller_for``)
        controller = actor
    records = evaluate(controller, plan, workers=workers, progress=False)
    pooled = pool_groups(records, groups, confidence=confidence, simulator=simulator)
    return pooled, records, plan


def plot_success_curve(
    evaluations: Sequence[dict],
    path: str | Path,
    *,
    title: str,
    stage_frames: Sequence[int] = (),
    confidence: float = 0.95,
) -> Path:
    """Success rate vs frames per group, with the Wilson interval as a band."""
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    groups = list(evaluations[0]["groups"]) if evaluations else []
    for group in groups:
        frames = [e["frames"] for e in evaluations]
        rate = [e["groups"][group]["success_rate"] for e in evaluations]
        low = [e["groups"][group]["success_low"] for e in evaluations]
        high = [e["groups"][group]["success_high"] for e in evaluations]
        (line,) = ax.plot(frames, rate, marker="o", label=group)
        ax.fill_between(frames, low, high, color=line.get_color(), alpha=0.2)
    for boundary in stage_frames:
        ax.axvline(boundary, color="grey", linestyle=":", linewidth=1)
    ax.set_xlabel("environment frames (control steps)")
    ax.set_ylabel(f"success rate ({100 * confidence:g}% Wilson band)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if groups:
        legend_outside(ax, fontsize=8)
    return save_figure(fig, path)
