"""One episode of any controller as a person reads it: traces, outcome and frames.

``run_episode`` runs the one rollout (``pilerl.sim.rollout``) on a single simulator and
turns its rows into an ``Episode`` of NumPy arrays for plots, CSV traces, reports and
videos.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from tensordict import TensorDictBase

from pilerl.operators import OperatorModule, operator_phases
from pilerl.sim import get_simulator
from pilerl.sim.rollout import (
    Rollout,
    control_period_s,
    make_rollout_env,
    rollout,
    sensor_names,
)
from pilerl.sim.torchrl_env import SimulatorBatchEnv

# per-step ``info`` traces kept for trace CSVs and plots where a simulator reports them
# (the pile loader's bucket state); the outcome and start pose come from the simulator's
# declared success, fill and ``episode_info``
INFO_TRACES = (
    "fill_fraction",
    "cutting_depth_m",
    "wheel_slip_m_s",
    "bucket_pitch_rad",
    "bucket_hinge_height_m",
    "spilled_kg",
)


@dataclass
class Episode:
    """What happened in one episode, one row per control step.

    Attributes:
        time_s: simulated time at each step's end [s].
        sensors: sensor name -> readings (units as in the env's observation space).
        actions: (T, action_dim) controls sent.
        rewards: per-step reward.
        traces: selected ``info`` values per step (``INFO_TRACES`` that the env reports).
        info: every carried ``info`` entry at reset, then after each step [T + 1] (NaN
            where not reported): what the simulator's episode rules read.
        final_info: the last step's ``info``; start_info: ``info`` at reset (the carried
            entries the simulator reports: ``INFO_TRACES`` and its declared ones).
        start_sensors: sensor readings at reset (before the first action).
        terminated, truncated: how the episode ended.
        phases: the controller's phase name at each step, if it reported one.
        frames: rendered RGB frames (empty unless rendering was asked for).
        frame_hz: frames per simulated second in ``frames``.
    """

    time_s: np.ndarray
    sensors: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    traces: dict[str, np.ndarray]
    final_info: dict
    start_info: dict
    start_sensors: dict[str, float] = field(default_factory=dict)
    terminated: bool = False
    truncated: bool = False
    phases: list[str] = field(default_factory=list)
    frames: list[np.ndarray] = field(default_factory=list)
    frame_hz: float = 0.0
    info: dict[str, np.ndarray] = field(default_factory=dict)


def make_episode_env(
    simulator: str, env_kwargs: Mapping[str, object], *, info_keys: tuple[str, ...] = ()
) -> SimulatorBatchEnv:
    """One simulator for ``run_episode``, carrying ``INFO_TRACES``, the simulator's declared
    success, fill and ``episode_info`` entries, and ``info_keys``."""
    plugin = get_simulator(simulator)
    declared = (plugin.success_key, *((plugin.fill_key,) if plugin.fill_key else ()))
    keys = tuple(dict.fromkeys((*INFO_TRACES, *declared, *plugin.episode_info, *info_keys)))
    return make_rollout_env(simulator, env_kwargs, num_envs=1, info_keys=keys)


def run_episode(
    env: SimulatorBatchEnv,
    policy: Callable[[TensorDictBase], TensorDictBase],
    *,
    seed: int,
    render: bool = False,
    max_frame_hz: float = 10.0,
    progress: str | None = None,
) -> Episode:
    """Roll ``policy`` out for one episode of ``env`` (from ``make_episode_env``) from ``seed``.

    Args:
        policy: a TensorDict module writing ``action`` (an ``OperatorModule`` of one
            operator, or an actor).
        render: also collect frames (env made with ``render_mode="rgb_array"``).
        max_frame_hz: render at most this many frames per simulated second (offscreen
            rendering costs more than simulating); ``Episode.frame_hz`` records the rate.
        progress: if given, show a progress bar with this label.
    """
    dt = control_period_s(env)
    stride = max(1, round(1.0 / (dt * max_frame_hz)))
    run = rollout(env, policy, seed=seed, frame_stride=stride if render else 0, progress=progress)
    phases = operator_phases(policy.operators[0]) if isinstance(policy, OperatorModule) else ()
    return episode_of(
        run, 0, dt=dt, sensors=sensor_names(env), phases=phases, frame_hz=1.0 / (dt * stride)
    )


def episode_of(
    run: Rollout,
    index: int,
    *,
    dt: float,
    sensors: list[str],
    phases: tuple[str, ...] = (),
    frame_hz: float = 0.0,
) -> Episode:
    """Episode ``index`` of a rollout as NumPy traces (phase names from ``phases``)."""
    rows = run.episode(index)
    after = rows.get("next")
    info = {k: run.info(index, k) for k in run.info_keys}
    start_info = _reported({k: float(v[0]) for k, v in info.items()})
    final_info = _reported({k: float(v[-1]) for k, v in info.items()})
    steps = len(rows)
    phase_names = (
        [phases[i] for i in rows.get("phase").tolist()] if phases and "phase" in rows else []
    )
    return Episode(
        time_s=np.arange(steps) * dt + dt,
        sensors={k: after.get(k)[:, 0].numpy().astype(np.float64) for k in sensors},
        actions=rows.get("action").numpy(),
        rewards=after.get("reward")[:, 0].numpy().astype(np.float64),
        traces={k: info[k][1:] for k in INFO_TRACES if k in start_info},
        final_info=final_info,
        start_info=start_info,
        start_sensors={k: float(rows.get(k)[0, 0]) for k in sensors},
        terminated=bool(after.get("terminated")[-1, 0]),
        truncated=bool(after.get("truncated")[-1, 0]),
        phases=phase_names,
        frames=run.frames[index] if run.frames else [],
        frame_hz=frame_hz,
        info=info,
    )


def _reported(info: dict[str, float]) -> dict[str, float]:
    """The entries a simulator reported (NaN stands for not reported)."""
    return {k: v for k, v in info.items() if not np.isnan(v)}
