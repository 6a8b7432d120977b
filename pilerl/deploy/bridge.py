"""Hardware in the loop with the simulator: the pile-loading simulator plays the machine.

The bridge runs seeded episodes of a simulator and speaks the runtime's UDP protocol: at
each control step it sends the readings (flags ``EPISODE_START`` on the first one), waits
up to ``command_wait_s`` for the command answering them, applies it (or, if none came in
time, the last command received: a late command, counted), steps the simulator, and keeps
the pace of ``speedup`` x real time. After the last step it sends the final readings with
``EPISODE_END``. Episode i of a seed list is the evaluator's episode (same env seed), so
with every command on time the outcome is the in-process evaluator's.

    python -m pilerl.deploy bridge --port 47000 --episodes 3 --speedup 5
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from pilerl.sim import DEFAULT_SIMULATOR, get_simulator, make_gym_env

from .link import LinkFault, MachineLink
from .packets import ControllerState, SensorFlag, SensorLayout
from .watchdog import NEUTRAL

START_WAIT_S = 10.0  # wall-clock wait for the first command of an episode (runtime start-up)


@dataclass(frozen=True)
class BridgeSettings:
    """What the simulated machine runs.

    Attributes:
        simulator: plugin name; env_kwargs: its arguments (``condition``, ``control_hz``...).
        seeds: one episode per env seed (the evaluator's: ``seed * 100_000 + i``).
        speedup: run this many times faster than real time (1 = real time).
        command_wait_s: machine time to wait for the command answering a reading before
            stepping with the last one received; ``None`` = half a control period.
        max_steps: stop an episode after this many control steps (``None``: the env's limit).
        rearm_at_step: send a re-arm request at this step of each episode (fault tests).
    """

    simulator: str = DEFAULT_SIMULATOR
    env_kwargs: dict = field(default_factory=dict)
    seeds: tuple[int, ...] = (0,)
    speedup: float = 1.0
    command_wait_s: float | None = None
    max_steps: int | None = None
    rearm_at_step: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speedup) and self.speedup > 0):
            raise ValueError(f"BridgeSettings.speedup: must be finite and > 0, got {self.speedup}")
        if not self.seeds:
            raise ValueError("BridgeSettings.seeds: need at least one episode seed")
        if self.max_steps is not None and self.max_steps < 1:
            raise ValueError(f"BridgeSettings.max_steps: must be >= 1, got {self.max_steps}")


def _declared_info(plugin, start: dict, final: dict) -> dict:
    """The simulator's declared ``episode_info`` entries at the episode's end (those it
    reports only at reset, such as the pile loader's start pose, from reset; NaN where
    never reported; flags as bools)."""
    values = {}
    for key in plugin.episode_info:
        value = float(final.get(key, start.get(key, math.nan)))
        values[key] = bool(value) if key in plugin.info_flags() else value
    return values


def _readings(obs: dict, layout: SensorLayout) -> np.ndarray:
    return np.array([float(np.asarray(obs[n]).reshape(-1)[0]) for n in layout.names], np.float32)


def run_bridge(
    settings: BridgeSettings,
    runtime_address: tuple[str, int],
    *,
    fault: LinkFault | None = None,
) -> list[dict]:
    """Run ``settings.seeds`` episodes against the runtime; one record per episode."""
    env = make_gym_env(settings.simulator, **settings.env_kwargs)
    layout = SensorLayout.from_env(env, get_simulator(settings.simulator).sensor_units)
    link = MachineLink(layout, runtime_address, fault=fault, speedup=settings.speedup)
    try:
        return [_episode(env, layout, link, settings, seed) for seed in settings.seeds]
    finally:
        link.close()
        env.close()


def _episode(env, layout: SensorLayout, link: MachineLink, settings: BridgeSettings, seed: int):
    period_s = float(env.unwrapped.dt) / settings.speedup
    if settings.command_wait_s is None:
        wait_s = 0.5 * period_s
    else:
        wait_s = settings.command_wait_s / settings.speedup
    obs, start = env.reset(seed=seed)
    first_command = len(link.received)
    first_seq = link.seq
    sent_s, applied = [], []
    late, step, flags = 0, 0, SensorFlag.EPISODE_START
    next_send = time.monotonic()
    started = next_send
    while True:
        link.receive_until(next_send)  # keep the pace; collect stray commands meanwhile
        if settings.rearm_at_step is not None and step == settings.rearm_at_step:
            link.send_rearm()
        seq = link.send_sensors(step, _readings(obs, layout), flags)
        sent_s.append(time.monotonic())
        link.receive_until(
            time.monotonic() + (START_WAIT_S if step == 0 else wait_s), answered_seq=seq
        )
        latest = link.latest_command()
        answered = latest is not None and latest.answered_seq == seq
        late += not answered
        action = NEUTRAL if latest is None else latest.controls
        if latest is not None and latest.state == ControllerState.FAULTED:
            action = NEUTRAL
        applied.append(np.array(action, dtype=np.float32))
        obs, _, terminated, truncated, info = env.step(action)
        step, flags = step + 1, SensorFlag.NONE
        next_send = max(next_send + period_s, time.monotonic())
        out_of_steps = settings.max_steps is not None and step >= settings.max_steps
        if terminated or truncated or out_of_steps:
            break
    end = SensorFlag.EPISODE_END | (SensorFlag.TERMINATED if terminated else SensorFlag.NONE)
    link.receive_until(next_send)
    link.send_sensors(step, _readings(obs, layout), end)
    commands = link.received[first_command:]
    plugin = get_simulator(settings.simulator)
    success = bool(info[plugin.success_key])
    return {
        "seed": seed,
        "fill_fraction": float(info[plugin.fill_key]) if plugin.fill_key else float(success),
        "success": success,
        **_declared_info(plugin, start, info),
        "steps": step,
        "late_commands": late,
        "wall_s": time.monotonic() - started,
        "first_seq": first_seq,
        "fault_onset_s": link.fault_onset_s,
        "sent_s": sent_s,
        "applied": [a.tolist() for a in applied],
        "commands": [
            {
                "arrival_s": c.arrival_s,
                "answered_seq": c.packet.answered_seq,
                "state": int(c.packet.state),
                "faults": c.packet.faults,
                "controls": c.packet.controls.tolist(),
            }
            for c in commands
        ],
    }
