"""Record demonstrations: run operators in a simulator and store schema-v1 episodes.

``record_demonstrations`` draws one operator style per episode (``sample_style``), runs
the episodes in worker processes (one intra-op thread each) and appends them, in episode
order, to an ``EpisodeStore`` from this process only, so the store has a single writer.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import torch
from tensordict import TensorDict
from tqdm import tqdm

from pilerl.operators import ScriptedScoopOperator, phase_index, sample_style
from pilerl.sim import make_gym_env

from .schema import EpisodeMeta, make_episode
from .store import EpisodeStore


@dataclass(frozen=True)
class RecordingPlan:
    """What to record.

    Attributes:
        simulator: plugin name.
        env_kwargs: simulator arguments (condition, control_hz = the recording rate...).
        n_episodes: how many episodes.
        seed: base seed; episode i uses env seed ``seed * 100_000 + i`` and its own style.
        trigger_sensor: the operators' impact cue (see ``sample_style``).
        mistake_rate: share of operators who raise the boom too early.
    """

    simulator: str
    env_kwargs: dict
    n_episodes: int
    seed: int = 0
    trigger_sensor: str = "drive_pressure"
    mistake_rate: float = 0.28

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
) -> tuple[TensorDict, dict, dict]:
    """Run one episode; returns (schema-v1 episode, reset info, final info).

    ``phase`` (optional) names the operator's phase at each step; it is stored as the
    extra per-step key ``phase`` (index into ``pilerl.operators.PHASES``).
    """
    obs, start_info = env.reset(seed=seed)
    names = list(obs)
    before: dict[str, list] = {k: [] for k in names}
    after: dict[str, list] = {k: [] for k in names}
    actions, rewards, phases = [], [], []
    while True:
        action = np.asarray(act(obs), dtype=np.float32)
        if phase is not None:
            phases.append(phase_index(phase()))
        next_obs, reward, terminated, truncated, info = env.step(action)
        for k in names:
            before[k].append(float(obs[k][0]))
            after[k].append(float(next_obs[k][0]))
        actions.append(action)
        rewards.append(float(reward))
        obs = next_obs
        if terminated or truncated:
            break
    dt = float(env.unwrapped.dt)
    n = len(actions)
    episode = make_episode(
        sensors={k: torch.tensor(v) for k, v in before.items()},
        next_sensors={k: torch.tensor(v) for k, v in after.items()},
        actions=torch.tensor(np.array(actions)),
        time_s=torch.arange(n, dtype=torch.float64) * dt,
        rewards=torch.tensor(rewards),
        terminated=bool(terminated),
        truncated=bool(truncated),
    )
    if phases:
        episode["phase"] = torch.tensor(phases, dtype=torch.int64)
    return episode, start_info, info


def _record_one(plan: RecordingPlan, index: int) -> tuple[TensorDict, EpisodeMeta]:
    """Worker: record episode ``index`` of ``plan`` (runs in a child process)."""
    torch.set_num_threads(1)
    style = sample_style(
        np.random.default_rng([plan.seed, index]),
        mistake_rate=plan.mistake_rate,
        trigger_sensor=plan.trigger_sensor,
    )
    env = make_gym_env(plan.simulator, **plan.env_kwargs)
    operator = ScriptedScoopOperator(style, dt=env.unwrapped.dt)
    episode, start, final = record_episode(
        env, operator.act, seed=plan.episode_seed(index), phase=lambda: operator.phase
    )
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
            "style": dataclasses.asdict(style),
        },
        fill_fraction=float(final.get("fill_fraction", math.nan)),
        success=bool(final.get("success", False)),
        seed=plan.episode_seed(index),
        start={
            k: float(start[k]) for k in ("start_distance_m", "approach_angle_rad") if k in start
        },
    )
    env.close()
    return episode, meta


def _episodes(
    plan: RecordingPlan, indices: range, workers: int
) -> Iterator[tuple[TensorDict, EpisodeMeta]]:
    if workers <= 1:
        for i in indices:
            yield _record_one(plan, i)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        yield from pool.map(_record_one, [plan] * len(indices), indices)


def record_demonstrations(
    store: EpisodeStore,
    plan: RecordingPlan,
    *,
    workers: int | None = None,
    progress: bool = True,
) -> list[EpisodeMeta]:
    """Record ``plan.n_episodes`` episodes into ``store``; returns their metadata.

    Recording resumes: episodes already in the store (by count) are skipped, so an
    interrupted recording can be started again with the same plan.
    """
    workers = workers if workers is not None else min(os.cpu_count() or 1, plan.n_episodes)
    todo = range(len(store), plan.n_episodes)
    metas = []
    bar = tqdm(
        total=plan.n_episodes,
        initial=len(store),
        desc="recording",
        unit="episode",
        disable=not progress,
    )
    for episode, meta in _episodes(plan, todo, workers):
        metas.append(store.append(episode, meta))
        bar.update()
        bar.set_postfix(success=f"{sum(m.success for m in store.episodes)}/{len(store)}")
    bar.close()
    return metas
