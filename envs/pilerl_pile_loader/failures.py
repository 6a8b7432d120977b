"""What went wrong in a failed scoop, in the paper's words, decided from what was measured.

The paper: "the main failure cases were early boom rising and no boom rising at all". The
boom counts as *lifted* when its angle has risen ``LIFT_RISE_RAD`` above its angle at the
start of the episode (``first_lift_step``): a controller whose boom command creeps up slowly
lifts the boom all the same, and is named an early boom rise when that happens before the
cutting edge is ``PENETRATION_M`` deep in the pile, not ``no_boom_rise``. Without a
boom-angle reading the rule falls back to the boom command (> ``LIFT_COMMAND``).

pilerl's evaluation calls ``episode_columns`` for every episode and ``summary_columns``
for every summary (the declaration names them, ``words.py``); this module is plain NumPy
and imports nothing from pilerl.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence

import numpy as np

LIFT_RISE_RAD = 0.05  # boom-angle rise above its start that counts as a lift [rad]
LIFT_COMMAND = 0.3  # boom control above this is a lift (without a boom angle)
PENETRATION_M = 0.10  # cutting-edge depth in the pile that counts as having dug in [m]
BOOM_ANGLE_SENSOR = "boom_angle"  # the boom angle θ1 [rad]
BOOM_CONTROL = "boom"
FAILURE_MODES = ("early_boom_rise", "no_boom_rise", "tipped", "underfilled", "unfinished")
# ``info`` entries an evaluation records from every step, with their units
EPISODE_INFO = {
    "start_distance_m": "m",
    "approach_angle_rad": "rad",
    "scoop_finished": "bool",
    "elapsed_s": "s",
    "wheel_slip_m_s": "m/s",
    "cutting_depth_m": "m",
    "spilled_kg": "kg",
    "tipped": "bool",
}


def first_lift_step(angles_rad: np.ndarray | None, boom_commands: np.ndarray | None) -> int | None:
    """The step of an episode after which the boom was first lifted, or None: the rule of
    lift rule over a whole recorded episode. ``angles_rad``: the boom angle at reset
    then after each step (T + 1 values; None without a boom-angle sensor); ``boom_commands``:
    the boom command of each step (T values; None without a boom control)."""
    if angles_rad is not None:
        lifted = np.flatnonzero(angles_rad[1:] > angles_rad[0] + LIFT_RISE_RAD)
    elif boom_commands is not None:
        lifted = np.flatnonzero(np.asarray(boom_commands) > LIFT_COMMAND)
    else:
        return None
    return int(lifted[0]) if len(lifted) else None


def failure_mode(
    *,
    success: bool,
    tipped: bool,
    first_lift_s: float,
    penetration_s: float,
    finished: bool = True,
) -> str:
    """``success``, or why not: ``tipped``; ``no_boom_rise`` (the boom was never lifted);
    ``early_boom_rise`` (lifted before the edge was ``PENETRATION_M`` deep in the pile);
    ``underfilled`` (dug in, lifted and finished the scoop less than half full);
    ``unfinished`` (dug in and lifted, but not curled and raised before the time limit).

    ``first_lift_s``: when the boom was first lifted (``first_lift_step``), NaN if never;
    ``penetration_s``: when the edge first reached ``PENETRATION_M``, NaN if never [s]."""
    if success:
        return "success"
    if tipped:
        return "tipped"
    if math.isnan(first_lift_s):
        return "no_boom_rise"
    if math.isnan(penetration_s) or first_lift_s < penetration_s:
        return "early_boom_rise"
    return "underfilled" if finished else "unfinished"


def episode_columns(
    *,
    info: Mapping[str, np.ndarray],
    sensors: Mapping[str, np.ndarray],
    controls: Mapping[str, np.ndarray],
    success: bool,
) -> dict[str, object]:
    """A scoop's columns of its evaluation record: start pose, finish, slip, spill, depth,
    first lift and penetration times [s], and the failure mode.

    ``info``: each ``EPISODE_INFO`` entry at reset then after each step (NaN where not
    reported); ``sensors``: readings at reset then after each step; ``controls``: the
    command of each step."""

    def final(key: str, default: float = math.nan) -> float:
        value = float(info[key][-1])
        return default if math.isnan(value) else value

    def trace(key: str) -> np.ndarray:  # after each step, 0 where not reported
        return np.nan_to_num(info[key][1:], nan=0.0)

    elapsed = info["elapsed_s"][1:]
    depth = trace("cutting_depth_m")
    angles = sensors.get(BOOM_ANGLE_SENSOR)
    lifted = first_lift_step(angles, controls.get(BOOM_CONTROL))
    dug_in = np.flatnonzero(depth >= PENETRATION_M)
    first_lift_s = float(elapsed[lifted]) if lifted is not None else math.nan
    penetration_s = float(elapsed[dug_in[0]]) if len(dug_in) else math.nan
    tipped = bool(final("tipped", 0.0))
    finished = bool(final("scoop_finished", 0.0))
    return {
        "start_distance_m": float(info["start_distance_m"][0]),
        "approach_angle_rad": float(info["approach_angle_rad"][0]),
        "scoop_finished": finished,
        "elapsed_s": final("elapsed_s"),
        "time_to_finish_s": final("elapsed_s") if finished else math.nan,
        "max_wheel_slip_m_s": max(0.0, float(trace("wheel_slip_m_s").max())),
        "spilled_kg": final("spilled_kg", 0.0),
        "max_cutting_depth_m": max(0.0, float(depth.max())),
        "first_lift_s": first_lift_s,
        "penetration_s": penetration_s,
        "tipped": tipped,
        "failure_mode": failure_mode(
            success=success,
            tipped=tipped,
            finished=finished,
            first_lift_s=first_lift_s,
            penetration_s=penetration_s,
        ),
    }


def summary_columns(rows: Sequence[Mapping[str, object]]) -> dict[str, float]:
    """Beside success and fill: mean time to fill of the successful scoops [s], mean peak
    wheel slip [m/s] and mean spill [kg]."""
    finish = [r["time_to_finish_s"] for r in rows if r["success"]]
    return {
        "time_to_fill_s_mean": statistics.fmean(finish) if finish else math.nan,
        "max_wheel_slip_m_s_mean": statistics.fmean(r["max_wheel_slip_m_s"] for r in rows),
        "spilled_kg_mean": statistics.fmean(r["spilled_kg"] for r in rows),
    }
