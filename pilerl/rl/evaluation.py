"""Closed-loop evaluation of a fine-tuning run: pooled success per condition group.

A group pools several conditions into one success rate with a Wilson interval ("winter"
= ``winter_a`` .. ``winter_d`` unless configured otherwise, the way the paper's winter
tests mixed days). Episodes come from ``pilerl.evaluation.evaluator.evaluate`` on a saved
actor, so fine-tuned and cloned actors are compared on the same seeded starts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict

from pilerl.evaluation import run_episode, write_mp4
from pilerl.evaluation.evaluator import ActorController, EvaluationPlan, clear_caches, evaluate
from pilerl.evaluation.metrics import wilson_interval
from pilerl.figures import plt, save_figure
from pilerl.policies import SensorPolicy
from pilerl.sim import make_gym_env

VIDEO_SIZE = (240, 320)  # (height, width) [px]


def pool_groups(
    records: Sequence[dict], groups: Mapping[str, Sequence[str]], *, confidence: float = 0.95
) -> dict[str, dict]:
    """Per group: successes, episodes, success rate, Wilson interval, mean fill."""
    pooled = {}
    for group, conditions in groups.items():
        rows = [r for r in records if r["condition"] in set(conditions)]
        if not rows:
            raise ValueError(f"evaluation group {group!r}: no episodes in {list(conditions)}")
        successes = sum(bool(r["success"]) for r in rows)
        low, high = wilson_interval(successes, len(rows), confidence=confidence)
        pooled[group] = {
            "successes": successes,
            "episodes": len(rows),
            "success_rate": successes / len(rows),
            "success_low": low,
            "success_high": high,
            "fill_mean": float(np.mean([r["fill_fraction"] for r in rows])),
        }
    return pooled


def evaluate_groups(
    checkpoint: str | Path,
    groups: Mapping[str, Sequence[str]],
    *,
    simulator: str,
    env_kwargs: Mapping[str, object],
    episodes: int,
    seed: int,
    workers: int = 1,
    confidence: float = 0.95,
) -> tuple[dict[str, dict], list[dict]]:
    """(pooled success per group, one record per episode) of a saved actor.

    The evaluator keeps loaded actors by checkpoint path; fine-tuning rewrites the same
    files (``evaluated.pt``, ``best.pt``), so its caches are cleared first.
    """
    clear_caches()
    conditions = tuple(dict.fromkeys(c for members in groups.values() for c in members))
    plan = EvaluationPlan(
        simulator=simulator,
        env_kwargs=dict(env_kwargs),
        conditions=conditions,
        episodes=episodes,
        seed=seed,
    )
    records = evaluate(ActorController(str(checkpoint)), plan, workers=workers, progress=False)
    return pool_groups(records, groups, confidence=confidence), records


def record_video(
    policy: SensorPolicy,
    path: str | Path,
    *,
    simulator: str,
    env_kwargs: Mapping[str, object],
    condition: str,
    seed: int,
) -> Path:
    """Render one deterministic episode of ``policy`` in ``condition`` to an mp4."""
    env = make_gym_env(
        simulator,
        **dict(env_kwargs),
        condition=condition,
        render_mode="rgb_array",
        render_size=VIDEO_SIZE,
    )

    def act(obs: dict) -> np.ndarray:
        with torch.no_grad():
            readings = TensorDict({k: torch.as_tensor(v) for k, v in obs.items()}, [])
            return policy(*[readings[k] for k in policy.in_keys])[0].numpy()

    try:
        episode = run_episode(env, act, seed=seed, render=True)
    finally:
        env.close()
    return write_mp4(episode.frames, path, fps=episode.frame_hz)


def plot_success_curve(
    evaluations: Sequence[dict], path: str | Path, *, title: str, stage_frames: Sequence[int] = ()
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
    ax.set_ylabel("success rate (95% Wilson band)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if groups:
        ax.legend()
    return save_figure(fig, path)
