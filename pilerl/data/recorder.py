"""Record demonstrations: run operators in a simulator and store schema-v1 episodes.

``record_demonstrations`` draws one operator per episode from the simulator's scripted
expert (its plugin's ``scripted_expert``, given the episode's generator), runs
the episodes in worker processes (one intra-op thread each) and appends them, in episode
order, to an ``EpisodeStore`` from this process only (the store also takes a lock, so
several recording processes may share one dataset).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
import torch
from tensordict import TensorDict
from tqdm import tqdm

from pilerl.evaluation import Episode, run_episode
from pilerl.runtime import process_pool
from pilerl.sim import get_simulator, make_gym_env

from .schema import EpisodeMeta, SchemaError, make_episode
from .store import EpisodeStore


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


def record_episode(
    env: gym.Env,
    act: Callable[[dict], np.ndarray],
    *,
    seed: int,
    phase: Callable[[], str] | None = None,
    phases: tuple[str, ...] = (),
) -> tuple[TensorDict, dict, dict]:
    """Run one episode; returns (schema-v1 episode, reset info, final info).

    ``phase`` (optional) names the operator's phase at each step; it is stored as the
    extra per-step key ``phase`` (index into ``phases``, the operator's ``PHASES``).
    """
    run = run_episode(env, act, seed=seed, phase=phase)
    return episode_tensordict(run, phases), run.start_info, run.final_info


def episode_tensordict(run: Episode, phases: tuple[str, ...] = ()) -> TensorDict:
    """A run as a schema-v1 episode: each row's readings before and after its action."""
    after = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in run.sensors.items()}
    before = {
        k: torch.cat([torch.tensor([run.start_sensors[k]]), v[:-1]]) for k, v in after.items()
    }
    dt = float(run.time_s[0])
    episode = make_episode(
        sensors=before,
        next_sensors=after,
        actions=torch.as_tensor(run.actions),
        time_s=torch.arange(len(run.actions), dtype=torch.float64) * dt,
        rewards=torch.as_tensor(run.rewards),
        terminated=run.terminated,
        truncated=run.truncated,
    )
    if run.phases:
        episode["phase"] = torch.tensor([phases.index(p) for p in run.phases])
    return episode


def _record_one(plan: RecordingPlan, index: int) -> tuple[TensorDict, EpisodeMeta]:
    """Worker: record episode ``index`` of ``plan`` (runs in a child process)."""
    torch.set_num_threads(1)
    plugin = get_simulator(plan.simulator)
    env = make_gym_env(plan.simulator, **plan.env_kwargs)
    rng = np.random.default_rng([plan.seed, index])
    operator = plugin.make_expert(dt=float(env.unwrapped.dt), rng=rng, **plan.expert)
    operator.reset()
    episode, start, final = record_episode(
        env,
        operator.act,
        seed=plan.episode_seed(index),
        phase=lambda: operator.phase,
        phases=tuple(operator.PHASES),
    )
    success, fill = plugin.score(final)
    style = getattr(operator, "style", None)
    condition = getattr(env.unwrapped, "condition", None)
    meta = EpisodeMeta(
        rate_hz=1.0 / float(env.unwrapped.dt),
        source="sim",
        condition=getattr(condition, "name", str(plan.env_kwargs.get("condition", ""))),
        condition_params=(
            dataclasses.asdict(condition) if dataclasses.is_dataclass(condition) else {}
        ),
        soil=str(plan.env_kwargs.get("soil", "")),
        operator={
            "id": f"scripted-{plan.seed}-{index}",
            "kind": "scripted",
            "style": dataclasses.asdict(style) if dataclasses.is_dataclass(style) else {},
        },
        fill_fraction=fill,
        success=success,
        seed=plan.episode_seed(index),
        start={
            k: float(start[k]) for k in ("start_distance_m", "approach_angle_rad") if k in start
        },
    )
    env.close()
    return episode, meta


def _episodes(
    plan: RecordingPlan, indices: list[int], workers: int
) -> Iterator[tuple[TensorDict, EpisodeMeta]]:
    if workers <= 1:
        for i in indices:
            yield _record_one(plan, i)
        return
    with process_pool(workers) as pool:
        yield from pool.map(_record_one, [plan] * len(indices), indices)


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


def plan_description(plan: RecordingPlan) -> dict:
    """What makes two recordings the same plan (everything but the episode count), as
    JSON values."""
    description = dataclasses.asdict(plan)
    del description["n_episodes"]
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
                f"({wanted}); record into another out_dir"
            )
    recorded = store.claim_index_entry(PLAN_ENTRY, wanted)
    if recorded != wanted:
        changed = sorted(k for k in {*wanted, *recorded} if wanted.get(k) != recorded.get(k))
        then = {k: recorded.get(k) for k in changed}
        now = {k: wanted.get(k) for k in changed}
        raise SchemaError(
            f"{store.root}: was recorded with another plan ({then}, not {now}); "
            "record into another out_dir"
        )


def _episode_seed(meta: EpisodeMeta) -> int | None:
    return meta.seed


def _missing_indices(store: EpisodeStore, plan: RecordingPlan) -> list[int]:
    store.refresh()
    recorded = {m.seed for m in store.episodes}
    return [i for i in range(plan.n_episodes) if plan.episode_seed(i) not in recorded]
