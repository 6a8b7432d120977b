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
    full, _ = _trace(kwargs, seed, shortcut=False)
    short, far_updates = _trace(kwargs, seed, shortcut=True)
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


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize(
    "soil_options", [{}, {"body_resistance": True}, {"intake": "mouth", "measure_mouth": True}]
)
def test_just_outside_the_far_box_the_shortcut_writes_what_the_full_update_writes(soil_options):
    """Hinges within 0.3 m outside the box, on every side (the scripted drives never reach
    the pile's sides), with random bucket rotations, heading and load: the shortcut and the
    full update leave the same heights, load, spill, depths, soil dampers and payload.
    A box shrunk to the grid plus the polygon's reach fails this test."""
    env = gym.make(GYM_ID, soil_options=soil_options).unwrapped
    env.reset(seed=0)
    soil, model, data, machine = env.soil, env.model, env.data, env.machine
    box = soil._far_box
    dampers = [model.actuator(k).id for k in ("soil_push", "soil_side", "soil_lift")]
    start_heights = soil.heights.copy()
    rng = np.random.default_rng(0)
    for _ in range(300):
        x, y = rng.uniform(box[0] - 0.3, box[1] + 0.3), rng.uniform(box[2] - 0.3, box[3] + 0.3)
        side, out = rng.integers(4), rng.uniform(0.0, 0.3)
        x = box[0] - out if side == 0 else box[1] + out if side == 1 else x
        y = box[2] - out if side == 2 else box[3] + out if side == 3 else y
        z, yaw, load = rng.uniform(-0.5, 1.5), rng.uniform(-math.pi, math.pi), rng.uniform(0, 3e3)
        rotation = _random_rotation(rng)
        results = []
        for far_box in (box, NEVER_FAR):
            soil.heights[:] = start_heights
            soil._pile_changed()
            soil.bucket_load_kg, soil.spilled_kg = load, 0.0
            soil._mouth_previous, soil._mouth_credit_m3 = None, 0.5
            data.xpos[machine.bucket_body] = (x, y, z)
            data.xmat[machine.bucket_body] = rotation.ravel()
            heading = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0]]
            data.xmat[machine.front_frame_body] = np.array([*heading, [0, 0, 1]]).ravel()
            soil._far_box = far_box
            soil.update(0.025)
            results.append(
                (
                    soil.heights.tobytes(),
                    soil.bucket_load_kg,
                    soil.spilled_kg,
                    soil._depth_m,
                    soil.resistance_depth_m,
                    model.actuator_gear[dampers].tobytes(),
                    model.actuator_forcerange[dampers].tobytes(),
                    model.actuator_biasprm[dampers].tobytes(),
                    model.body_mass.tobytes(),
                )
            )
        soil._far_box = box
        assert results[0] == results[1], f"hinge ({x:.3f}, {y:.3f}, {z:.3f}) m outside the box"
