"""A fixed open-loop scoop: the pile loader's controls as a function of the step count.

Tests and benchmarks drive the simulator with it where their numbers must not move when
the scripted expert (``operator.py``) is tuned: the pinned step-identity traces
(``tests/envs/test_step_identity.py``), the batched-versus-alone identity test
(``tests/sim/test_batched_env_identity.py``) and the soil-update benchmark
(``benchmarks/soil_update_speed.py``). It lives in the plugin because the action is the
plugin's: its control order (``sensors.CONTROL_NAMES``: boom, bucket, throttle) and its
command range.

The script has three parts: drive in (throttle 0.8), lift while still pushing (boom 0.5,
bucket 0.3, throttle 0.5) from ``lift_from_s`` (3 s), curl and lift (boom 0.8, bucket 1.0,
throttle 0.1) from ``curl_from_s``. Its clock counts steps of 0.05 s (20 Hz) whatever the
simulator's control rate: a 10 Hz simulator given the same steps runs the same commands at
half the pace.
"""

from __future__ import annotations

import numpy as np

SCRIPT_STEP_S = 0.05  # the script's clock, s per step (20 Hz)
LIFT_FROM_S = 3.0  # drive in before, lift from here on, s
CURL_FROM_S = 6.0  # curl from here on, s (the step-identity traces' script)
DRIVE_IN = (0.0, 0.0, 0.8)  # [boom, bucket, throttle]
LIFT = (0.5, 0.3, 0.5)
CURL = (0.8, 1.0, 0.1)


def scripted_action(
    step: int, *, phase: int = 0, lift_from_s: float = LIFT_FROM_S, curl_from_s: float = CURL_FROM_S
) -> np.ndarray:
    """The [boom, bucket, throttle] command (float32) of step ``step`` of the script.

    Args:
        step: control steps since the reset.
        phase: steps the script is ahead (a batch's simulators in different parts of a
            scoop: simulator i at ``phase=4 * i``).
        lift_from_s: when the lift starts, in the script's seconds.
        curl_from_s: when the curl starts, in the script's seconds.
    """
    t = (step + phase) * SCRIPT_STEP_S
    if t < lift_from_s:
        return np.array(DRIVE_IN, np.float32)
    if t < curl_from_s:
        return np.array(LIFT, np.float32)
    return np.array(CURL, np.float32)
