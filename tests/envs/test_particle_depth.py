"""The particle soil's cutting depth (``ParticleSoil.cutting_depth_m``): the heightfield's
definition (the edge's mean depth below the pile surface one cell ahead of it) over the
grains that belong to the pile.

On the coarse pile (4 grains across the mouth, as the scooping tests). The machine is
placed by its root joint and the kinematics recomputed, no physics step: the reading is
checked against the undisturbed pile's surface, where it is known."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from pilerl_pile_loader.soil.particles import EDGE_SAMPLE_SPAN, EDGE_SAMPLES

import pilerl  # noqa: F401

COARSE = {"mouth_grains": 4.0}
DT_S = 0.05
THROTTLE = np.array([0.0, 0.0, 0.6], np.float32)  # bucket flat, boom down


@pytest.fixture(scope="module")
def env() -> gym.Env:
    return gym.make(
        "pilerl/PileLoading-v0",
        soil="particles",
        soil_options=COARSE,
        sensor_noise=0.0,
        start_distance_range_m=(1.0, 1.0),
        approach_angle_range_deg=(0.0, 0.0),
    )


def edge_position(env: gym.Env) -> np.ndarray:
    sim = env.unwrapped
    return sim.data.site_xpos[sim.machine.cutting_edge_site].copy()


def place_edge_at(env: gym.Env, x_m: float) -> float:
    """Slide the machine along x (its heading at reset) so that the cutting edge lies at
    world ``x_m``; recount the soil. Returns the depth it reads."""
    sim = env.unwrapped
    sim.data.qpos[0] += x_m - edge_position(env)[0]  # the machine's free joint: root x
    mujoco.mj_kinematics(sim.model, sim.data)
    sim.soil.update(DT_S)
    return sim.soil.cutting_depth_m()


def undisturbed_depth(env: gym.Env, below_m: float = 0.0) -> float:
    """The heightfield's definition on the pile's undisturbed surface lowered by
    ``below_m``: mean over the sample points across the edge, one cell ahead, of the
    surface's height above the edge."""
    soil = env.unwrapped.soil
    edge = edge_position(env)
    offsets = np.linspace(-EDGE_SAMPLE_SPAN / 2, EDGE_SAMPLE_SPAN / 2, EDGE_SAMPLES)
    y = edge[1] + offsets * soil.bucket.width_m - soil.zone_offset_y_m
    x = np.full_like(y, edge[0] + soil.pile.cell_size_m)
    surface = soil.pile.surface_height(x, y, soil.repose_angle_rad) - below_m
    return float(np.maximum(surface - edge[2], 0.0).mean())


def test_depth_is_zero_off_the_pile_and_follows_its_face(env):
    env.reset(seed=0)
    soil = env.unwrapped.soil
    toe = soil.pile.toe_x_m
    assert soil.cutting_depth_m() == 0.0  # at the start, 1 m before the toe
    for x in (toe - 3.0, toe - 0.5, toe - 0.2):
        assert place_edge_at(env, x) == 0.0
    depths = []
    for x in (toe + 0.2, toe + 0.4, toe + 0.6, toe + 0.8):
        depth = place_edge_at(env, x)
        # the grains' tops lie within a radius of the surface they were laid under
        assert depth == pytest.approx(undisturbed_depth(env), abs=soil.radius_m), x
        depths.append(depth)
    assert np.all(np.diff(depths) > 0.0)
    assert depths[-1] > 0.4


def test_a_grain_in_the_air_ahead_of_the_edge_is_not_the_pile_surface(env):
    """The contact solver could throw grains metres high (winter_c, default pile: 48 m,
    before the bucket plates' contacts were fixed); one passing over the edge read as
    metres of cutting depth."""
    env.reset(seed=0)
    sim = env.unwrapped
    soil = sim.soil
    depth = place_edge_at(env, soil.pile.toe_x_m + 0.4)
    edge = edge_position(env)
    # the grain farthest from the edge (it covers none of the sample points), thrown up to
    # 3 m above the ground just ahead of the edge
    far = int(np.argmax(np.linalg.norm(soil.particle_positions() - edge, axis=1)))
    target = edge + [soil.pile.cell_size_m, 0.0, 0.0]
    target[2] = 3.0
    qpos = sim.data.qpos[soil._qpos].reshape(-1, 3)  # slide joints: displacements [m]
    qpos[far] += target - soil.particle_positions()[far]
    sim.data.qpos[soil._qpos] = qpos.ravel()
    mujoco.mj_kinematics(sim.model, sim.data)
    np.testing.assert_allclose(soil.particle_positions()[far], target, atol=1e-9)
    soil.update(DT_S)
    assert soil.cutting_depth_m() == depth


def test_with_the_grains_gone_the_static_core_is_the_surface(env):
    env.reset(seed=0)
    sim = env.unwrapped
    soil = sim.soil
    x = soil.pile.toe_x_m + 0.8
    with_grains = place_edge_at(env, x)
    qpos = sim.data.qpos[soil._qpos].reshape(-1, 3)
    qpos[:, 0] -= 20.0  # every grain 20 m back, far from the edge
    sim.data.qpos[soil._qpos] = qpos.ravel()
    depth = place_edge_at(env, x)
    # the core's top lattice sites lie the active depth below the surface, within a radius
    expected = undisturbed_depth(env, below_m=soil.active_depth_m)
    assert expected > 0.1
    assert depth == pytest.approx(expected, abs=soil.radius_m)
    assert depth < with_grains - 0.3


def test_driving_in_raises_the_depth_from_zero_within_the_pile_height(env):
    env.reset(seed=0)
    soil = env.unwrapped.soil
    readings = []
    for _ in range(40):
        *_, terminated, truncated, info = env.step(THROTTLE)
        readings.append((edge_position(env)[0], info["cutting_depth_m"]))
        assert not (terminated or truncated)
    edge_x, depth = np.array(readings).T
    before_toe = edge_x < soil.pile.toe_x_m - soil.pile.cell_size_m - soil.radius_m
    assert before_toe.any() and np.all(depth[before_toe] == 0.0)
    assert depth.max() > 0.2
    assert depth.max() <= soil.pile.height_m
