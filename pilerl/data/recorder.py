"""Record demonstrations: run operators in a simulator and store schema-v1 episodes.

``record_demonstrations`` draws one operator per episode from the simulator's scripted
expert (its plugin's ``scripted_expert``, given the episode's own generator), runs the
episodes as batched rollouts (``pilerl.sim.rollout``, an ``OperatorModule`` as the policy)
in worker processes (one intra-op thread each) and appends them, in episode order, to an
``EpisodeStore`` from this process only (the store also takes a lock, so several recording
processes may share one dataset).

A rollout's rows already are a schema episode: ``episode_from_rollout`` only picks the
schema's keys, the operator's clean label as ``action`` and, when an operator's executed
command differed from its label (executed-command perturbations), that command as the
extra column ``executed_action``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tqdm import tqdm

from pilerl.operators import OperatorModule
from pilerl.operators.module import ACTION_KEY, LABEL_KEY, PHASE_KEY
from pilerl.runtime import process_pool
from pilerl.sim import get_simulator
from pilerl.sim.rollout import (
    Rollout,
    control_period_s,
    make_rollout_env,
    rollout,
    sensor_names,
)
from pilerl.sim.torchrl_env import SimulatorBatchEnv

from .schema import EpisodeMeta, SchemaError, make_episode
from .store import EpisodeStore

EXECUTED_KEY = "executed_action"  # the executed command, where it differs from the label
START_INFO = ("start_distance_m", "approach_angle_rad")  # kept in EpisodeMeta.start if reported
MAX_EPISODES_PER_ROLLOUT = 8  # TorchRL's per-step cost is paid once for a chunk's episodes


@dataclass(frozen=True)
class RecordingPlan:
    """What to record.

    Attributes:
        simulator: plugin name.
        env_kwargs: simulator arguments (condition, control_hz = the recording rate...).
        n_episodes: how many episodes.
        seed: base seed; episode i uses env seed ``seed * 100_000 + i`` and its own
            operator, drawn from the generator ``numpy.random.default_rng([seed, i])``.
        expert: options of the simulator's scripted expert (the pile loader's:
            ``trigger_sensor``, ``mistake_rate``); ``{}``: its defaults.
    """

    simulator: str
    env_kwargs: dict
    n_episodes: int
    seed: int = 0
    expert: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.n_episodes < 1:
            raise ValueError(f"RecordingPlan.n_episodes: must be >= 1, got {self.n_episodes}")

    def episode_seed(self, index: int) -> int:
        return self.seed * 100_000 + index


def episode_from_rollout(rows: TensorDictBase, *, sensors: Sequence[str], dt: float) -> TensorDict:
    """One episode's rollout rows (batch ``[T]``) as a schema-v1 episode.

    ``action`` is the policy's label (``action_label``) where it wrote one, else the
    executed ``action``; the executed command is kept as ``executed_action`` when it
    differs from the label in any row; ``phase`` is kept when the policy wrote it.
    """
    after = rows.get("next")
    executed = rows.get(ACTION_KEY)
    label = rows.get(LABEL_KEY, executed)
    episode = make_episode(
        sensors={k: rows.get(k) for k in sensors},
        next_sensors={k: after.get(k) for k in sensors},
        actions=label,
        time_s=torch.arange(len(rows), dtype=torch.float64) * dt,
        rewards=after.get("reward"),
        terminated=bool(after.get("terminated")[-1]),
        truncated=bool(after.get("truncated")[-1]),
    )
    if not torch.equal(label, executed):
        episode[EXECUTED_KEY] = executed.to(torch.float32).clone()
    if PHASE_KEY in rows:
        episode[PHASE_KEY] = rows.get(PHASE_KEY).clone()
    return episode


def record_episode(env: SimulatorBatchEnv, operator, *, seed: int) -> tuple[TensorDict, dict, dict]:
    """Run ``operator`` for one episode of ``env`` (one simulator, from ``make_rollout_env``
    with ``info_keys=recorded_info(simulator)``); returns (schema-v1 episode, reset info,
    final info) (the info entries the env carries and the simulator reported)."""
    policy = OperatorModule.for_env([operator], env)
    run = rollout(env, policy, seed=seed)
    rows = run.episode(0)
    episode = episode_from_rollout(rows, sensors=sensor_names(env), dt=control_period_s(env))
    return episode, _info(run, 0, at=0), _info(run, 0, at=-1)


def recorded_info(simulator: str) -> tuple[str, ...]:
    """The ``info`` entries a recording carries: ``START_INFO`` (where the simulator reports
    them) and the simulator's declared success and fill keys."""
    plugin = get_simulator(simulator)
    keys = (*START_INFO, plugin.success_key, *((plugin.fill_key,) if plugin.fill_key else ()))
    return tuple(dict.fromkeys(keys))


def _info(run: Rollout, episode: int, *, at: int) -> dict[str, float]:
    """The carried ``info`` entries the simulator reported at reset (``at=0``) or after the
    last step (``at=-1``) of an episode."""
    values = {k: float(run.info(episode, k)[at]) for k in run.info_keys}
    return {k: v for k, v in values.items() if not math.isnan(v)}


def _record_chunk(
    plan: RecordingPlan, first: int, count: int
) -> list[tuple[TensorDict, EpisodeMeta]]:
    """Worker: record episodes ``first`` .. ``first + count - 1`` of ``plan`` as one
    batched rollout (runs in a child process)."""
    torch.set_num_threads(1)
    plugin = get_simulator(plan.simulator)
    env = make_rollout_env(
        plan.simulator, plan.env_kwargs, num_envs=count, info_keys=recorded_info(plan.simulator)
    )
    dt = control_period_s(env)
    operators = [
        plugin.make_expert(dt=dt, rng=np.random.default_rng([plan.seed, index]), **plan.expert)
        for index in range(first, first + count)
    ]
    sensors = sensor_names(env)
    policy = OperatorModule.for_env(operators, env)
    run = rollout(env, policy, seed=plan.episode_seed(first))
    recorded = []
    for i, operator in enumerate(operators):
        rows = run.episode(i)
        start, final = _info(run, i, at=0), _info(run, i, at=-1)
        success, fill = plugin.score(final) if plugin.success_key in final else (False, math.nan)
        condition = getattr(env.simulators[i].unwrapped, "condition", None)
        style = getattr(operator, "style", None)
        meta = EpisodeMeta(
            rate_hz=1.0 / dt,
            source="sim",
            condition=getattr(condition, "name", str(plan.env_kwargs.get("condition", ""))),
            condition_params=(
                dataclasses.asdict(condition) if dataclasses.is_dataclass(condition) else {}
            ),
            soil=str(plan.env_kwargs.get("soil", "")),
            operator={
                "id": f"scripted-{plan.seed}-{first + i}",
                "kind": "scripted",
                "style": dataclasses.asdict(style) if dataclasses.is_dataclass(style) else {},
            },
            fill_fraction=fill,
            success=success,
            seed=run.seeds[i],
            start={k: start[k] for k in START_INFO if k in start},
        )
        recorded.append((episode_from_rollout(rows, sensors=sensors, dt=dt), meta))
    env.close()
    return recorded


def _chunks(indices: list[int], workers: int) -> list[tuple[int, int]]:
    """(first, count) runs of consecutive ``indices`` (seeds ``s + i`` of one rollout),
    enough to keep ``workers`` busy, at most ``MAX_EPISODES_PER_ROLLOUT`` each."""
    size = min(MAX_EPISODES_PER_ROLLOUT, max(1, math.ceil(len(indices) / max(workers, 1))))
    chunks: list[tuple[int, int]] = []
    for index in indices:
        if chunks and chunks[-1][0] + chunks[-1][1] == index and chunks[-1][1] < size:
            chunks[-1] = (chunks[-1][0], chunks[-1][1] + 1)
        else:
            chunks.append((index, 1))
    return chunks


def _episodes(
    plan: RecordingPlan, indices: list[int], workers: int
) -> Iterator[tuple[TensorDict, EpisodeMeta]]:
    chunks = _chunks(indices, workers)
    if not chunks:  # everything is recorded already
        return
    if workers <= 1 or len(chunks) == 1:
        for first, count in chunks:
            yield from _record_chunk(plan, first, count)
        return
    with process_pool(min(workers, len(chunks))) as pool:
        for recorded in pool.map(_record_chunk, *zip(*[(plan, *c) for c in chunks], strict=True)):
            yield from recorded


def record_demonstrations(
    store: EpisodeStore,
    plan: RecordingPlan,
    *,
    workers: int | None = None,
    progress: bool = True,
) -> list[EpisodeMeta]:
    """Record ``plan.n_episodes`` episodes into ``store``; returns their metadata.

    Recording resumes: episodes already in the store (by seed) are skipped, so an
    interrupted recording can be started again with the same plan. A store holding a
    recording of another plan (simulator, its arguments, seed, operators) is refused
    rather than mixed. Several processes may record the same plan into one store at
    once: each episode is stored once (the store skips seeds it already holds).
    """
    claim_plan(store, plan)
    workers = workers if workers is not None else min(os.cpu_count() or 1, plan.n_episodes)
    todo = _missing_indices(store, plan)
    metas = []
    bar = tqdm(
        total=plan.n_episodes,
        initial=plan.n_episodes - len(todo),
        desc="recording",
        unit="episode",
        disable=not progress,
    )
    for episode, meta in _episodes(plan, todo, workers):
        metas.extend(store.extend([(episode, meta)], identity=_episode_seed))
        bar.update()
        bar.set_postfix(success=f"{sum(m.success for m in store.episodes)}/{len(store)}")
    bar.close()
    return metas


PLAN_ENTRY = "recording_plan"
EXPERT_REVISION = "expert_revision"  # the plan's key for the simulator's ``expert_revision``


def plan_description(plan: RecordingPlan) -> dict:
    """What makes two recordings the same plan (everything but the episode count, and the
    revision of the simulator's expert behind ``plan.expert``'s defaults), as JSON values."""
    description = dataclasses.asdict(plan)
    del description["n_episodes"]
    description[EXPERT_REVISION] = get_simulator(plan.simulator).expert_revision
    return json.loads(json.dumps(description, default=repr))


def claim_plan(store: EpisodeStore, plan: RecordingPlan) -> None:
    """Write ``plan`` into ``store``'s index, or check that it is the plan already there."""
    wanted = plan_description(plan)
    if store.index_entry(PLAN_ENTRY) is None and len(store):
        seeds = {plan.episode_seed(i) for i in range(max(plan.n_episodes, len(store)))}
        foreign = [
            m.id
            for m in store.episodes
            if m.source != "sim"
            or m.seed not in seeds
            or m.condition != str(plan.env_kwargs.get("condition", m.condition))
        ]
        if foreign:
            raise SchemaError(
                f"{store.root}: episodes {foreign[:5]} were not recorded by this plan "
                f"({wanted}); record into another directory"
            )
    # a plan recorded before experts had revisions was recorded by revision 0
    recorded = {EXPERT_REVISION: 0, **store.claim_index_entry(PLAN_ENTRY, wanted)}
    if recorded != wanted:
        changed = sorted(k for k in {*wanted, *recorded} if wanted.get(k) != recorded.get(k))
        then = {k: recorded.get(k) for k in changed}
        now = {k: wanted.get(k) for k in changed}
        why = (
            " (the simulator's scripted expert has changed its default behaviour since: "
            "its expert_revision, docs/simulator_plugins.md)"
            if EXPERT_REVISION in changed
            else ""
        )
        raise SchemaError(
            f"{store.root}: was recorded with another plan ({then}, not {now}){why}; "
            "record into another directory"
        )


def _episode_seed(meta: EpisodeMeta) -> int | None:
    return meta.seed


def _missing_indices(store: EpisodeStore, plan: RecordingPlan) -> list[int]:
    store.refresh()
    recorded = {m.seed for m in store.episodes}
    return [i for i in range(plan.n_episodes) if plan.episode_seed(i) not in recorded]
