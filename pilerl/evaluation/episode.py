"""Run one episode of any controller that acts from a dict of named sensor readings."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
from tqdm import tqdm

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
        final_info: the last step's ``info``; start_info: ``info`` at reset.
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


def run_episode(
    env: gym.Env,
    act: Callable[[dict[str, np.ndarray]], np.ndarray],
    *,
    seed: int | None = None,
    render: bool = False,
    max_frame_hz: float = 10.0,
    phase: Callable[[], str] | None = None,
    progress: str | None = None,
) -> Episode:
    """Reset ``env`` with ``seed`` and step it with ``act(observation)`` until it ends.

    Args:
        env: a Gymnasium env with a ``Dict`` observation of named sensors.
        act: controller; takes the observation dict, returns an action array.
        render: also collect ``env.render()`` frames (env made with ``rgb_array``).
        max_frame_hz: render at most this many frames per simulated second (offscreen
            rendering costs more than simulating); ``Episode.frame_hz`` records the rate.
        phase: if given, called before each step to name the controller's phase.
        progress: if given, show a progress bar with this label.
    """
    obs, start_info = env.reset(seed=seed)
    start_sensors = {name: float(np.asarray(v).reshape(-1)[0]) for name, v in obs.items()}
    phases: list[str] = []
    dt = float(env.unwrapped.dt)
    sensors: dict[str, list[float]] = {name: [] for name in obs}
    actions, rewards, times, frames = [], [], [], []
    traces: dict[str, list[float]] = {k: [] for k in INFO_TRACES if k in start_info}
    frame_stride = max(1, round(1.0 / (dt * max_frame_hz)))
    bar = tqdm(desc=progress, unit="step", leave=False, disable=progress is None, mininterval=1.0)
    if render:
        frames.append(env.render())
    while True:
        action = np.asarray(act(obs), dtype=np.float32)
        if phase is not None:
            phases.append(phase())
        obs, reward, terminated, truncated, info = env.step(action)
        for name, value in obs.items():
            sensors[name].append(float(np.asarray(value).reshape(-1)[0]))
        for name in traces:
            traces[name].append(float(info[name]))
        actions.append(action)
        rewards.append(float(reward))
        times.append(len(times) * dt + dt)
        if render and len(times) % frame_stride == 0:
            frames.append(env.render())
        bar.update()
        if terminated or truncated:
            break
    bar.close()
    return Episode(
        time_s=np.asarray(times),
        sensors={k: np.asarray(v) for k, v in sensors.items()},
        actions=np.asarray(actions),
        rewards=np.asarray(rewards),
        traces={k: np.asarray(v) for k, v in traces.items()},
        final_info=info,
        start_info=start_info,
        start_sensors=start_sensors,
        terminated=bool(terminated),
        truncated=bool(truncated),
        phases=phases,
        frames=frames,
        frame_hz=1.0 / (dt * frame_stride),
    )
