"""Closed-loop evaluation: run a controller for N seeded episodes per condition.

Episode i of every condition starts from the same seeded pose (start distance, approach
angle), so controllers and conditions are compared on paired starts. Episodes run as
rollouts (``pilerl.sim.rollout``): the plan's episodes, condition after condition, are cut
into chunks, each one batched rollout whose simulators may hold different conditions
(episode ``i`` of a condition seeded ``seed * 100_000 + i``; one episode in each of five
conditions is one rollout of five simulators, so TorchRL's per-step cost is paid once for
the five), and the chunks run in worker processes (one thread each). An episode's result
depends neither on its chunk nor on its worker (operators act per episode, actors row by
row), and the records come back in episode order, so the result does not depend on the
number of workers.

A controller is the scripted operator (``ScriptedController``), a saved actor
(``ActorController``) or an actor in memory (``ActorWeights.of(actor)``, what fine-tuning
evaluates): saved and in-memory actors alike reach the workers as their weights.
"""

from __future__ import annotations

import io
import math
import os
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from tqdm import tqdm

from pilerl.io import atomic_path, write_text_atomic
from pilerl.operators import OperatorModule
from pilerl.runtime import process_pool
from pilerl.sim import DEFAULT_SIMULATOR, get_simulator
from pilerl.sim.rollout import (
    Rollout,
    RowByRow,
    control_period_s,
    make_rollout_env,
    rollout,
)
from pilerl.sim.torchrl_env import SimulatorBatchEnv

from .failures import episode_outcome
from .metrics import fill_and_cycle_time, wilson_interval

MAX_EPISODES_PER_ROLLOUT = 8  # TorchRL's per-step cost is paid once for a chunk's episodes


@dataclass(frozen=True)
class ScriptedController:
    """The simulator's nominal scripted expert (its plugin's ``scripted_expert``).

    Attributes:
        options: the expert's options (``{}``: its defaults).
        name: label in plots and tables.
        simulator: whose expert.
    """

    options: Mapping[str, object] = field(default_factory=dict)
    name: str = "scripted"
    simulator: str = DEFAULT_SIMULATOR

    def policy(self, env: SimulatorBatchEnv) -> TensorDictModuleBase:
        """One operator per simulator of ``env``."""
        dt = control_period_s(env)
        expert = get_simulator(self.simulator).make_expert
        operators = [expert(dt=dt, rng=None, **dict(self.options)) for _ in env.simulators]
        return OperatorModule.for_env(operators, env)


@dataclass(frozen=True)
class ActorWeights:
    """An actor as plain data, acting deterministically: what evaluation workers receive.

    Attributes:
        config: the actor's ``ActorConfig`` as JSON.
        weights: its ``SensorPolicy``'s ``state_dict``, ``torch.save``d.
        name: the controller's name in the records.
    """

    config: dict
    weights: bytes
    name: str = "actor"

    @classmethod
    def of(cls, actor: torch.nn.Module, *, name: str = "actor") -> ActorWeights:
        """A copy of the weights of ``actor`` (from ``make_actor`` / ``load_actor``, or its
        ``SensorPolicy``); later changes to ``actor`` do not reach the copy."""
        from pilerl.policies import actor_policy

        policy = actor_policy(actor)
        buffer = io.BytesIO()
        torch.save({k: v.detach().cpu().clone() for k, v in policy.state_dict().items()}, buffer)
        return cls(config=policy.config.to_json(), weights=buffer.getvalue(), name=name)

    def build(self) -> TensorDictModule:
        """The actor, rebuilt in eval mode (drawing nothing from torch's generator)."""
        from pilerl.policies.actors import policy_actor
        from pilerl.policies.checkpoint import rebuild_policy
        from pilerl.policies.config import ActorConfig

        state_dict = torch.load(io.BytesIO(self.weights), weights_only=True)
        where = Path(f"<actor {self.name!r} in memory>")
        policy = rebuild_policy(where, ActorConfig.from_json(self.config), state_dict, "weights")
        return policy_actor(policy).eval()

    def policy(self, env: SimulatorBatchEnv) -> TensorDictModuleBase:
        """The actor for acting only (``inference_actor``: traced, bit-identical outputs,
        ~60% of the module's time per row; the random forest as it is), acting on each
        simulator of ``env`` alone (``RowByRow``)."""
        from pilerl.policies.actors import RandomForestActor, inference_actor

        actor = self.build()
        return RowByRow(actor if isinstance(actor, RandomForestActor) else inference_actor(actor))


@dataclass(frozen=True)
class ActorController:
    """A saved actor (``best.pt``), read when an evaluation starts."""

    checkpoint: str
    name: str = "actor"

    def weights(self) -> ActorWeights:
        from pilerl.policies import load_actor

        return ActorWeights.of(load_actor(self.checkpoint), name=self.name)


def resolve_controller(controller):
    """What workers receive: a ``ScriptedController`` or ``ActorWeights`` (a saved actor is
    read now, an actor in memory copied now)."""
    if isinstance(controller, ActorController):
        return controller.weights()
    if isinstance(controller, torch.nn.Module):
        return ActorWeights.of(controller)
    return controller


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

    def episode_seed(self, index: int) -> int:
        return self.seed * 100_000 + index


# (condition, episode index) of each simulator of a rollout
Chunk = tuple[tuple[str, int], ...]

# One batched env per (plan, conditions of a chunk), kept for the life of the process:
# building a simulator costs ~0.15 s against ~0.5 s for an episode. ``evaluate`` builds them
# before forking its workers, which inherit them. ``reset(seed=...)`` restores every state
# an episode depends on (tested: results do not depend on which episodes ran before).
_ENVS: dict[tuple, SimulatorBatchEnv] = {}


def evaluation_info(simulator: str) -> tuple[str, ...]:
    """The ``info`` entries an evaluation of ``simulator`` carries: its declared success and
    fill keys, then its declared ``episode_info``."""
    plugin = get_simulator(simulator)
    declared = (plugin.success_key, *((plugin.fill_key,) if plugin.fill_key else ()))
    return tuple(dict.fromkeys((*declared, *plugin.episode_info)))


def _cached_env(plan: EvaluationPlan, conditions: tuple[str, ...]) -> SimulatorBatchEnv:
    """Simulators in ``conditions``, one each, as one env."""
    key = (plan.simulator, repr(sorted(plan.env_kwargs.items())), conditions)
    if key not in _ENVS:
        _ENVS[key] = make_rollout_env(
            plan.simulator,
            plan.env_kwargs,
            each=[{"condition": condition} for condition in conditions],
            info_keys=evaluation_info(plan.simulator),
        )
    return _ENVS[key]


def build_envs(plan: EvaluationPlan, *, workers: int = 1) -> None:
    """Build (and keep) the envs that evaluating ``plan`` on ``workers`` processes uses: a
    bad condition or simulator argument fails here, before any work, and forked workers
    inherit them."""
    for chunk in _chunks(plan, workers):
        _cached_env(plan, tuple(condition for condition, _ in chunk))


def clear_caches() -> None:
    """Close and forget the cached envs of this process."""
    for env in _ENVS.values():
        env.close()
    _ENVS.clear()


def _chunks(plan: EvaluationPlan, workers: int) -> list[Chunk]:
    """The episodes of each rollout, in record order (condition after condition): enough
    chunks to keep ``workers`` busy, at most ``MAX_EPISODES_PER_ROLLOUT`` episodes each."""
    episodes = [(c, i) for c in plan.conditions for i in range(plan.episodes)]
    size = min(MAX_EPISODES_PER_ROLLOUT, max(1, math.ceil(len(episodes) / max(workers, 1))))
    return [tuple(episodes[first : first + size]) for first in range(0, len(episodes), size)]


def _run_chunk(controller, plan: EvaluationPlan, chunk: Chunk) -> list[dict]:
    """Records of the chunk's episodes, one rollout."""
    torch.set_num_threads(1)
    env = _cached_env(plan, tuple(condition for condition, _ in chunk))
    run = rollout(env, controller.policy(env), seed=[plan.episode_seed(i) for _, i in chunk])
    return [
        episode_record(
            run,
            k,
            controller=controller.name,
            condition=condition,
            index=index,
            simulator=plan.simulator,
        )
        for k, (condition, index) in enumerate(chunk)
    ]


def episode_record(
    run: Rollout,
    episode: int,
    *,
    controller: str,
    condition: str,
    index: int,
    simulator: str = DEFAULT_SIMULATOR,
) -> dict:
    """One row of ``episodes.csv``: episode ``episode`` of ``run`` (evaluation index
    ``index``): its success and fill (the simulator's declared keys; without a fill key
    the fill is the success as 0/1) and return, then the simulator's own columns and its
    ``failure_mode`` (``pilerl.evaluation.failures``)."""
    plugin = get_simulator(simulator)
    success = float(run.info(episode, plugin.success_key)[-1])
    success = bool(0.0 if math.isnan(success) else success)
    fill = float(run.info(episode, plugin.fill_key)[-1]) if plugin.fill_key else float(success)
    rewards = run.episode(episode).get(("next", "reward"))[:, 0].numpy().astype(np.float64)
    return {
        "controller": controller,
        "condition": condition,
        "episode": index,
        "seed": run.seeds[episode],
        "fill_fraction": fill,
        "success": success,
        "return": float(np.cumsum(rewards)[-1]),  # summed step by step, as the env reported
        **episode_outcome(run, episode, plugin, success=success),
    }


def evaluate(
    controller, plan: EvaluationPlan, *, workers: int | None = None, progress: bool = True
) -> list[dict]:
    """One record per episode, ordered by condition then episode.

    ``controller``: ``ScriptedController``, ``ActorController`` (a saved actor),
    ``ActorWeights`` or an actor module in memory (its weights are copied now and sent to
    the workers).
    """
    controller = resolve_controller(controller)
    workers = (
        workers
        if workers is not None
        else min(os.cpu_count() or 1, plan.episodes * len(plan.conditions))
    )
    chunks = _chunks(plan, workers)
    build_envs(plan, workers=workers)
    bar = tqdm(
        total=plan.episodes * len(plan.conditions),
        desc=f"evaluating {controller.name}",
        unit="episode",
        disable=not progress,
    )
    records = []
    if workers <= 1 or len(chunks) == 1:
        for chunk in chunks:
            records.extend(_run_chunk(controller, plan, chunk))
            bar.update(len(chunk))
    else:
        jobs = [(controller, plan, chunk) for chunk in chunks]
        with process_pool(min(workers, len(chunks))) as pool:
            for chunk_records in pool.map(_run_chunk, *zip(*jobs, strict=True)):
                records.extend(chunk_records)
                bar.update(len(chunk_records))
    bar.close()
    return records


def summarize(
    records: Sequence[dict],
    *,
    confidence: float = 0.95,
    groups: Mapping[str, Sequence[str]] | None = None,
    simulator: str = DEFAULT_SIMULATOR,
) -> dict[str, dict]:
    """Per condition: success rate with its Wilson interval, fill, the simulator's own
    numbers (the pile loader's time, slip and spill) and failure modes.

    For each of ``groups`` (the simulator's declared condition groups) with two or more
    tested conditions, a pooled entry is added: the pile loader's ``winter`` pools A-D,
    the way the paper's winter tests were spread over days with different ground.
    """
    conditions = list(dict.fromkeys(r["condition"] for r in records))
    rows = {c: [r for r in records if r["condition"] == c] for c in conditions}
    for group, members in (groups or {}).items():
        tested = [c for c in members if c in rows]
        if len(tested) >= 2 and group not in rows:
            rows[group] = [r for r in records if r["condition"] in tested]
    return {
        name: summarize_rows(group, confidence, simulator=simulator) for name, group in rows.items()
    }


def summarize_rows(
    rows: Sequence[dict], confidence: float = 0.95, *, simulator: str = DEFAULT_SIMULATOR
) -> dict:
    """Success (with its Wilson interval), fill, the simulator's own summary numbers
    (``summary_columns``) and a count of each of its declared failure modes, of any set of
    episode records of ``simulator``."""
    plugin = get_simulator(simulator)
    successes = sum(r["success"] for r in rows)
    low, high = wilson_interval(successes, len(rows), confidence=confidence)
    fills = [r["fill_fraction"] for r in rows]
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
        **plugin.summary_numbers(rows),
        "failure_modes": {
            mode: sum(r.get("failure_mode") == mode for r in rows) for mode in plugin.failure_modes
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
    "ActorController",
    "ActorWeights",
    "EvaluationPlan",
    "ScriptedController",
    "build_envs",
    "clear_caches",
    "episode_record",
    "evaluate",
    "resolve_controller",
    "success_metrics",
    "summarize",
    "summarize_rows",
    "write_results",
]
