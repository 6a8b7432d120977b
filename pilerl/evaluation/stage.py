"""The evaluation stage: a controller tested in closed loop as its settings say.

``recipes/evaluate.py``, the closed-loop test of ``recipes/train_bc.py`` and the
pipeline's two evaluations call these with their ``evaluation`` settings
(``ClosedLoopConfig``) and their env settings.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pilerl.sim.settings import EnvConfig

from .closed_loop import run_closed_loop
from .evaluator import EvaluationPlan, build_envs
from .settings import ClosedLoopConfig


def closed_loop_plan(settings: ClosedLoopConfig, env: EnvConfig) -> EvaluationPlan:
    """The evaluation plan of ``settings`` in ``env``, its envs built once in this process:
    a bad condition or env setting fails here, before any work (forked episode workers
    inherit the envs)."""
    plan = settings.plan(env)
    build_envs(plan)
    return plan


def evaluate_controller(
    controller: Any,
    plan: EvaluationPlan,
    settings: ClosedLoopConfig,
    out_dir: str | Path,
    *,
    videos: bool = False,
) -> dict[str, dict]:
    """Run ``plan`` with ``controller`` and write episodes, summary, plots (and videos of
    ``settings.video_conditions`` when ``videos``) to ``out_dir``; returns the summary."""
    return run_closed_loop(
        controller,
        plan,
        out_dir,
        workers=settings.workers,
        videos=videos,
        video_conditions=settings.video_conditions,
        render_size=(settings.render_height, settings.render_width),
    )


def success_rate(summary: dict[str, dict], conditions: Sequence[str]) -> float:
    """Successes over episodes, pooled over ``conditions`` (a sweep's objective)."""
    rows = [row for name, row in summary.items() if name in conditions]
    return sum(row["successes"] for row in rows) / sum(row["episodes"] for row in rows)
