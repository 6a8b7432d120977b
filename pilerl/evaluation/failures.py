"""What went wrong in a failed scoop, in the paper's words, decided from what was measured.

The paper: "the main failure cases were early boom rising and no boom rising at all". The
boom counts as *lifted* when its angle has risen ``LIFT_RISE_RAD`` above its angle at the
start of the episode (``first_lift_step``): a controller whose boom command creeps up slowly
lifts the boom all the same, and is named an early boom rise when that happens before the
cutting edge is ``PENETRATION_M`` deep in the pile, not ``no_boom_rise``. A simulator
without a boom-angle sensor falls back to the boom command (> ``LIFT_COMMAND``).
"""

from __future__ import annotations

import math

import numpy as np

LIFT_RISE_RAD = 0.05  # boom-angle rise above its start that counts as a lift [rad]
LIFT_COMMAND = 0.3  # boom control above this is a lift (simulators without a boom angle)
PENETRATION_M = 0.10  # cutting-edge depth in the pile that counts as having dug in [m]
BOOM_ANGLE_SENSOR = "boom_angle"  # the pile loader's boom angle θ1 [rad]
BOOM_CONTROL = "boom"
FAILURE_MODES = ("early_boom_rise", "no_boom_rise", "tipped", "underfilled", "unfinished")


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


__all__ = [
    "BOOM_ANGLE_SENSOR",
    "FAILURE_MODES",
    "LIFT_COMMAND",
    "LIFT_RISE_RAD",
    "PENETRATION_M",
    "failure_mode",
    "first_lift_step",
]
