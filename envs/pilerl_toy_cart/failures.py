"""Why a toy-cart episode failed: it overshot the target, or it never got there."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .env import STOP_TOLERANCE, TARGET_M

FAILURE_MODES = ("overshot", "fell_short")


def episode_columns(
    *,
    info: Mapping[str, np.ndarray],
    sensors: Mapping[str, np.ndarray],
    controls: Mapping[str, np.ndarray],
    success: bool,
) -> dict[str, object]:
    """The distance to the target at the end [m], the farthest position reached [m], and
    the failure mode: ``overshot`` (passed the target by more than the stop tolerance) or
    ``fell_short`` (never did, and never stopped on it)."""
    farthest_m = float(np.max(sensors["position"]))
    if success:
        mode = "success"
    elif farthest_m > TARGET_M + STOP_TOLERANCE:
        mode = "overshot"
    else:
        mode = "fell_short"
    return {
        "error_m": float(info["error_m"][-1]),
        "farthest_m": farthest_m,
        "failure_mode": mode,
    }
