"""Why an evaluated episode failed, in the simulator's words.

The core spells no failure mode: each simulator declares its own (``failure_modes``) and,
optionally, the rule that names them (``episode_columns``; the pile loader's boom-lift
rule is ``pilerl_pile_loader.failures``). This module hands that rule what an episode
measured, as plain NumPy arrays, and checks what it answers
(``SimulatorPlugin.episode_outcome``). A simulator without a rule records the last value
of each ``info`` entry it declares, and names every failure ``failed``.
"""

from __future__ import annotations

import numpy as np

from pilerl.sim.plugin import FAILED, SUCCESS, SimulatorPlugin
from pilerl.sim.rollout import Rollout


def episode_trace(
    run: Rollout, episode: int, plugin: SimulatorPlugin
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(info, sensors, controls) of episode ``episode`` of ``run``: each declared
    ``episode_info`` entry the rollout carried, float64 [T + 1] (at reset, then after each
    step; NaN where not reported); each sensor's readings [T + 1], float64; each control's
    commands [T], as sent."""
    rows = run.episode(episode)
    info = {key: run.info(episode, key) for key in plugin.episode_info if key in run.info_keys}
    sensors = {}
    for name in plugin.sensors:
        if name in rows.keys():  # noqa: SIM118 (a TensorDict refuses ``in`` on itself)
            before, after = rows.get(name), rows.get(("next", name))
            sensors[name] = np.concatenate([before[:1].reshape(-1), after.reshape(-1)]).astype(
                np.float64
            )
    actions = rows.get("action").numpy()
    controls = {name: actions[:, i] for i, name in enumerate(plugin.controls)}
    return info, sensors, controls


def episode_outcome(
    run: Rollout, episode: int, plugin: SimulatorPlugin, *, success: bool
) -> dict[str, object]:
    """The simulator's columns of the record of episode ``episode`` of ``run``, with its
    ``failure_mode`` (``success``, or one of the simulator's declared failure modes)."""
    info, sensors, controls = episode_trace(run, episode, plugin)
    return plugin.episode_outcome(
        info=info,
        sensors=sensors,
        controls=controls,
        success=success,
        where=f"simulator {plugin.name!r}, episode seed {run.seeds[episode]}",
    )


__all__ = ["FAILED", "SUCCESS", "episode_outcome", "episode_trace"]
