"""Closed-loop evaluation: run a controller for N seeded episodes per condition.

Episode i of every condition starts from the same seeded pose (start distance, approach
angle), so controllers and conditions are compared on paired starts. Episodes run in
worker processes (one thread each); the records come back in episode order, so the result
does not depend on the number of workers.
"""

from __future__ import annotations

import math
import os
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict
from tqdm import tqdm

from pilerl.io import atomic_path, write_text_atomic
from pilerl.operators import OperatorStyle, ScriptedScoopOperator
from pilerl.runtime import process_pool
from pilerl.sim import make_gym_env

from .failures import FAILURE_MODES, PENETRATION_M, BoomLiftWatch, failure_mode
from .metrics import fill_and_cycle_time, wilson_interval


@dataclass(frozen=True)
class ScriptedController:
    """The scripted operator with a fixed style."""

    style: OperatorStyle = field(default_factory=OperatorStyle)
    name: str = "scripted"

    def build(self, dt: float):
        return ScriptedScoopOperator(self.style, dt=dt)


@dataclass(frozen=True)
class ActorController:
    """A saved actor (``best.pt``) acting deterministically from the observation."""

    checkpoint: str
    name: str = "actor"

    def build(self, dt: float):
        return _ActorOperator(self.checkpoint)


class _ActorOperator:
    def __init__(self, checkpoint: str) -> None:
        from pilerl.policies import load_actor

        self.actor = load_actor(checkpoint)

    def reset(self) -> None:
        pass

    def act(self, obs: dict) -> np.ndarray:
        with torch.no_grad():
            td = TensorDict({k: torch.as_tensor(v) for k, v in obs.items()}, [])
            return self.actor(td)["action"].numpy()


@dataclass(frozen=True)
class EvaluationPlan:
    """What to evaluate.

    Attributes:
        simulator: plugin name.
        env_kwargs: simulator arguments except ``condition``.
        conditions: condition names, each evaluated on the same seeded starts.
        episodes: episodes per condition.
        seed: base seed; episode i uses env seed ``seed * 100_000 + i``.
    """

    simulator: str
    env_kwargs: dict
    conditions: tuple[str, ...]
    episodes: int
    seed: int = 0

    def __post_init__(self) -> None:
        if self.episodes < 1 or not self.conditions:
            raise ValueError(f"EvaluationPlan: need >= 1 episode and >= 1 condition, got {self}")


# One env per (plan, condition) and one operator per controller, kept for the life of a
# worker process: building them costs ~0.15 s and a checkpoint load, against ~0.5 s for an
# episode. ``reset(seed=...)`` restores every state an episode depends on (tested: results do
# not depend on which worker ran which episodes before).
_ENVS: dict[tuple, object] = {}
_OPERATORS: dict[tuple, object] = {}


def _cached_env(plan: EvaluationPlan, condition: str):
    key = (plan.simulator, repr(sorted(plan.env_kwargs.items())), condition)
    if key not in _ENVS:
        _ENVS[key] = make_gym_env(plan.simulator, **plan.env_kwargs, condition=condition)
    return _ENVS[key]


def _cached_operator(controller, dt: float):
    # a checkpoint rewritten in place (a fine-tuning run re-saving its actor) is a new key
    checkpoint = getattr(controller, "checkpoint", None)
    stamp = None
    if checkpoint is not None:
        stat = os.stat(checkpoint)
        stamp = (stat.st_mtime_ns, stat.st_size, stat.st_ino)
    key = (repr(controller), dt, stamp)
    if key not in _OPERATORS:
        _OPERATORS[key] = controller.build(dt)
    return _OPERATORS[key]


def build_envs(plan: EvaluationPlan) -> None:
    """Build (and keep) each condition's env of ``plan`` in this process: a bad condition
    or simulator argument fails here, before any work, and forked workers inherit them."""
    for condition in plan.conditions:
        _cached_env(plan, condition)


def clear_caches() -> None:
    """Close and forget the cached envs and operators of this process."""
    for env in _ENVS.values():
        env.close()
    _ENVS.clear()
    _OPERATORS.clear()


def _run_episode(controller, plan: EvaluationPlan, condition: str, index: int) -> dict:
    torch.set_num_threads(1)
    env = _cached_env(plan, condition)
    operator = _cached_operator(controller, float(env.unwrapped.dt))
    operator.reset()
    seed = plan.seed * 100_000 + index
    obs, start = env.reset(seed=seed)
    lift = BoomLiftWatch(obs, getattr(env.unwrapped, "control_names", ()))
    total, max_slip, time_to_finish, max_depth = 0.0, 0.0, math.nan, 0.0
    penetration_s = math.nan
    while True:
        action = operator.act(obs)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        max_slip = max(max_slip, float(info.get("wheel_slip_m_s", 0.0)))
        max_depth = max(max_depth, float(info.get("cutting_depth_m", 0.0)))
        now = float(info["elapsed_s"])
        lift.observe(action, obs, now)
        if math.isnan(penetration_s) and max_depth >= PENETRATION_M:
            penetration_s = now
        if terminated or truncated:
            if info.get("scoop_finished"):
                time_to_finish = now
            break
    first_lift_s = lift.first_lift_s
    return {
        "controller": controller.name,
        "condition": condition,
        "episode": index,
        "seed": seed,
        "start_distance_m": float(start.get("start_distance_m", math.nan)),
        "approach_angle_rad": float(start.get("approach_angle_rad", math.nan)),
        "fill_fraction": float(info["fill_fraction"]),
        "success": bool(info["success"]),
        "scoop_finished": bool(info.get("scoop_finished", False)),
        "elapsed_s": float(info["elapsed_s"]),
        "time_to_finish_s": time_to_finish,
        "max_wheel_slip_m_s": max_slip,
        "spilled_kg": float(info.get("spilled_kg", 0.0)),
        "return": total,
        "max_cutting_depth_m": max_depth,
        "first_lift_s": first_lift_s,
        "penetration_s": penetration_s,
        "tipped": bool(info.get("tipped", False)),
        "failure_mode": failure_mode(
            success=bool(info["success"]),
            tipped=bool(info.get("tipped", False)),
            finished=bool(info.get("scoop_finished", False)),
            first_lift_s=first_lift_s,
            penetration_s=penetration_s,
        ),
    }


def evaluate(
    controller, plan: EvaluationPlan, *, workers: int | None = None, progress: bool = True
) -> list[dict]:
    """One record per episode, ordered by condition then episode."""
    build_envs(plan)
    jobs = [(c, i) for c in plan.conditions for i in range(plan.episodes)]
    workers = workers if workers is not None else min(os.cpu_count() or 1, len(jobs))
    bar = tqdm(
        total=len(jobs), desc=f"evaluating {controller.name}", unit="episode", disable=not progress
    )
    records = []
    if workers <= 1:
        for condition, index in jobs:
            records.append(_run_episode(controller, plan, condition, index))
            bar.update()
    else:
        with process_pool(workers) as pool:
            for record in pool.map(
                _run_episode, *zip(*[(controller, plan, c, i) for c, i in jobs], strict=True)
            ):
                records.append(record)
                bar.update()
    bar.close()
    return records


def summarize(records: Sequence[dict], *, confidence: float = 0.95) -> dict[str, dict]:
    """Per condition: success rate with its Wilson interval, fill, time, slip and spill.

    With two or more ``winter_*`` conditions, a pooled ``winter`` entry is added: the paper's
    winter tests were spread over days with different ground and material (its A-D).
    """
    conditions = list(dict.fromkeys(r["condition"] for r in records))
    groups = {c: [r for r in records if r["condition"] == c] for c in conditions}
    winter = [c for c in conditions if c.startswith("winter_")]
    if len(winter) >= 2 and WINTER_POOL not in groups:
        groups[WINTER_POOL] = [r for r in records if r["condition"] in winter]
    return {name: summarize_rows(rows, confidence) for name, rows in groups.items()}


WINTER_POOL = "winter"


def summarize_rows(rows: Sequence[dict], confidence: float = 0.95) -> dict:
    """Success (with its Wilson interval), fill, time, slip, spill and failure modes of
    any set of episode records."""
    successes = sum(r["success"] for r in rows)
    low, high = wilson_interval(successes, len(rows), confidence=confidence)
    fills = [r["fill_fraction"] for r in rows]
    finish = [r["time_to_finish_s"] for r in rows if r["success"]]
    return {
        "episodes": len(rows),
        "successes": successes,
        "success_rate": successes / len(rows),
        "success_low": low,
        "success_high": high,
        "fill_mean": statistics.fmean(fills),
        "fill_median": statistics.median(fills),
        "fill_min": min(fills),
        "fill_max": max(fills),
        "time_to_fill_s_mean": statistics.fmean(finish) if finish else math.nan,
        "max_wheel_slip_m_s_mean": statistics.fmean(r["max_wheel_slip_m_s"] for r in rows),
        "spilled_kg_mean": statistics.fmean(r["spilled_kg"] for r in rows),
        "failure_modes": {
            mode: sum(r.get("failure_mode") == mode for r in rows) for mode in FAILURE_MODES
        },
        **fill_and_cycle_time(rows),
    }


def success_metrics(summary: dict[str, dict], prefix: str = "") -> dict[str, float]:
    """Flat ``metrics.json`` entries of a summary: ``<prefix><test>_success_rate``,
    ``_successes`` and ``_episodes`` per condition (counts let sweep summaries pool
    seeds into one Wilson interval)."""
    metrics: dict[str, float] = {}
    for name, row in summary.items():
        metrics[f"{prefix}{name}_success_rate"] = row["success_rate"]
        metrics[f"{prefix}{name}_successes"] = row["successes"]
        metrics[f"{prefix}{name}_episodes"] = row["episodes"]
    return metrics


def write_results(records: Sequence[dict], summary: dict, out_dir: str | Path) -> None:
    """``episodes.csv`` (one row per episode) and ``summary.json``, atomically."""
    import json

    out_dir = Path(out_dir)
    columns = list(records[0])
    lines = [",".join(columns)] + [",".join(str(r[c]) for c in columns) for r in records]
    with atomic_path(out_dir / "episodes.csv") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    clean = {
        c: {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in s.items()}
        for c, s in summary.items()
    }
    write_text_atomic(out_dir / "summary.json", json.dumps(clean, indent=1, allow_nan=False))


__all__ = [
    "FAILURE_MODES",
    "WINTER_POOL",
    "ActorController",
    "EvaluationPlan",
    "ScriptedController",
    "build_envs",
    "clear_caches",
    "evaluate",
    "failure_mode",
    "success_metrics",
    "summarize",
    "summarize_rows",
    "write_results",
]
