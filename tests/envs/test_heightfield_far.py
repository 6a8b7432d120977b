"""The heightfield's shortcut far from the pile: ``HeightfieldSoil.update`` skips the bucket
polygon, the intake and the depth samples while the bucket's hinge lies outside the box
``_bind_far_box`` computes (issue #18, speed). The shortcut must change nothing: a
simulator whose box covers the whole plane (so every update takes the full path) steps
bit for bit as one with the box, over approaches from every start distance and angle the
env draws, with and without the soil options that read the same depths.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.open_loop import scripted_action

import pilerl  # noqa: F401

GYM_ID = "pilerl/PileLoading-v0"
STEPS = 130  # 6.5 s: the approach, the drive into the pile, the lift and the curl
NEVER_FAR = (-math.inf, math.inf, -math.inf, math.inf)


def _trace(kwargs: dict, seed: int, *, shortcut: bool) -> tuple[list, int]:
    """Every step's readings, reward, end flags, numeric info and soil-damper parameters;
    and how many updates took the shortcut."""
    env = gym.make(GYM_ID, **kwargs).unwrapped
    soil = env.soil
    if not shortcut:
        soil._far_box = NEVER_FAR
    far_updates = 0
    update = soil.update

    def counted(dt: float) -> None:
        nonlocal far_updates
        x_min, x_max, y_min, y_max = soil._far_box
        x, y = soil._xpos[env.machine.bucket_body][:2]
        far_updates += not (x_min <= x <= x_max and y_min <= y <= y_max)
        update(dt)

    soil.update = counted
    obs, _ = env.reset(seed=seed)
    trace = []
    for step in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(scripted_action(step))
        numbers = [v for v in info.values() if isinstance(v, float | int | bool)]
        dampers = [env.model.actuator(n).id for n in ("soil_push", "soil_side", "soil_lift")]
        trace.append(
            (
                np.concatenate(list(obs.values())).tobytes(),
                np.array([reward, terminated, truncated, *numbers]).tobytes(),
                env.model.actuator_gear[dampers].tobytes(),
                env.model.actuator_forcerange[dampers].tobytes(),
                env.model.actuator_biasprm[dampers].tobytes(),
                env.data.qpos.tobytes(),
            )
        )
        if terminated or truncated:
            break
    env.close()
    return trace, far_updates


@pytest.mark.parametrize(
    ("kwargs", "seed"),
    [
        ({"condition": "summer"}, 0),
        ({"condition": "winter_b", "approach_angle_range_deg": (-30.0, -30.0)}, 1),
        ({"condition": "summer", "start_distance_range_m": (5.0, 5.0)}, 2),
        ({"condition": "winter_c", "soil_options": {"body_resistance": True}}, 3),
        ({"condition": "summer", "soil_options": {"measure_mouth": True}}, 4),
    ],
)
def test_the_far_shortcut_steps_as_the_full_update(kwargs, seed):
    full, never = _trace(kwargs, seed, shortcut=False)
    short, far_updates = _trace(kwargs, seed, shortcut=True)
    assert never == 0
    assert far_updates > 10, "the drive never took the shortcut: the test means nothing"
    assert len(short) == len(full)
    for step, (got, expected) in enumerate(zip(short, full, strict=True)):
        assert got == expected, f"step {step}: the shortcut changed the simulator's numbers"


def test_the_far_box_contains_every_point_an_update_reads_near_the_pile():
    """The box is the grid grown by the bucket's reach: a hinge just inside it may put a
    footprint corner or a depth sample on the grid, one well outside cannot."""
    env = gym.make(GYM_ID).unwrapped
    soil = env.soil
    x_min, x_max, y_min, y_max = soil._far_box
    reach = float(np.linalg.norm(soil._polygon_local, axis=1).max()) + soil.bucket.width_m / 2
    assert x_min < soil._x0 - reach and x_max > soil._x0 + (soil.ncol - 1) * soil.dx + reach
    assert y_min < soil._y0 - reach and y_max > soil._y0 + (soil.nrow - 1) * soil.dy + reach
