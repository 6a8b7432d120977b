"""The heightfield's resistance over the buried bucket body (``soil_options=
{"body_resistance": True}``, not the default): the depth it resists at, and what it does
to a bucket pushed into the pile level and curled."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.soil.heightfield import HeightfieldSoil

import pilerl  # noqa: F401

BODY = {"body_resistance": True}
SURFACE_M = 1.2  # flat block pile for the geometry tests
HEADING = np.array([1.0, 0.0])


def _block_soil() -> HeightfieldSoil:
    """A bound heightfield soil whose pile is a flat block ``SURFACE_M`` high."""
    env = gym.make("pilerl/PileLoading-v0", soil_options=BODY)
    env.reset(seed=0)
    soil = env.unwrapped.soil
    soil.heights[:] = SURFACE_M
    return soil


def _bucket_points(soil: HeightfieldSoil, hinge: np.ndarray, pitch_rad: float) -> np.ndarray:
    """World corners of the bucket's inside (back-floor, edge, lip, back-top) for a bucket
    heading along +x and curled back by ``pitch_rad`` (edge up)."""
    c, s = math.cos(pitch_rad), math.sin(pitch_rad)
    local = soil.bucket.polygon  # (x forward, z up)
    x = local[:, 0] * c - local[:, 1] * s
    z = local[:, 0] * s + local[:, 1] * c
    return hinge + np.stack([x, np.zeros_like(x), z], axis=1)


def _depths(soil: HeightfieldSoil, points: np.ndarray) -> tuple[float, float]:
    """(edge depth, body depth) [m] for a bucket at ``points``."""
    edge, lowest = points[1], points[int(np.argmin(points[:, 2]))]
    return soil._edge_depth(edge, HEADING), soil._body_depth(edge, lowest, HEADING)


def test_a_level_bucket_resists_at_its_edge_depth():
    soil = _block_soil()
    points = _bucket_points(soil, np.array([1.0, 0.0, 1.0]), 0.0)
    edge_depth, body_depth = _depths(soil, points)
    assert edge_depth == pytest.approx(SURFACE_M - (1.0 - 0.40))
    assert body_depth == edge_depth


def test_a_buried_curled_bucket_resists_at_its_heel_depth():
    soil = _block_soil()
    pitch = 0.45
    points = _bucket_points(soil, np.array([1.0, 0.0, 1.0]), pitch)
    edge_depth, body_depth = _depths(soil, points)
    heel_z, edge_z = points[0, 2], points[1, 2]
    assert edge_z - heel_z == pytest.approx(0.60 * math.sin(pitch))
    assert edge_depth == pytest.approx(SURFACE_M - edge_z)
    assert body_depth == pytest.approx(SURFACE_M - heel_z)
    assert body_depth > edge_depth + 0.25


def test_a_curled_bucket_whose_heel_is_out_of_the_pile_resists_at_its_edge_depth():
    """Heel in front of the pile's face (on bare ground), edge in the pile: only the edge
    is buried; the heel does not count."""
    soil = _block_soil()
    hinge = np.array([1.0, 0.0, 1.0])
    points = _bucket_points(soil, hinge, 0.45)
    heel_col = round((points[0, 0] + soil.dx - soil._x0) / soil.dx)
    soil.heights[:, : heel_col + 1] = 0.0  # the pile starts between the heel and the edge
    edge_depth, body_depth = _depths(soil, points)
    assert edge_depth > 0.2
    assert body_depth == edge_depth


def _push(soil_options: dict, curl_s: float, seed: int = 0) -> tuple[float, float, float, float]:
    """Throttle 0.6 into the pile from 1.0-1.5 m, boom held, full curl for ``curl_s`` first:
    (furthest edge position past the toe [m], the most the resistance depth exceeded the
    edge depth [m], fill, the most the bucket hinge rose above its height in the first
    second [m])."""
    env = gym.make(
        "pilerl/PileLoading-v0",
        sensor_noise=0.0,
        start_distance_range_m=(1.0, 1.5),
        soil_options=soil_options,
    )
    env.reset(seed=seed)
    sim = env.unwrapped
    site, toe_x = sim.machine.cutting_edge_site, sim.soil.pile.toe_x_m
    furthest, extra, elapsed, start_height, rise = -np.inf, 0.0, 0.0, None, 0.0
    while elapsed < 8.0 - 1e-9:
        bucket = 1.0 if elapsed < curl_s - 1e-9 else 0.0
        _, _, terminated, truncated, info = env.step(np.array([0.0, bucket, 0.6], np.float32))
        elapsed = info["elapsed_s"]
        furthest = max(furthest, float(sim.data.site_xpos[site][0]) - toe_x)
        extra = max(extra, sim.soil.resistance_depth_m - info["cutting_depth_m"])
        if start_height is None and elapsed >= 1.0:
            start_height = info["bucket_hinge_height_m"]
        if start_height is not None:
            rise = max(rise, info["bucket_hinge_height_m"] - start_height)
        if terminated or truncated:
            break
    env.close()
    return furthest, extra, info["fill_fraction"], rise


def test_a_level_push_is_nearly_unchanged_by_body_resistance():
    """Held level, the bucket pitches by a few milliradians in the push, so its heel dips
    below its edge by at most millimetres: the same push within a millimetre."""
    default, _, default_fill, _ = _push({}, curl_s=0.0)
    body, extra, body_fill, _ = _push(BODY, curl_s=0.0)
    assert body == pytest.approx(default, abs=1e-3)
    assert body_fill == pytest.approx(default_fill, abs=1e-3)
    assert extra < 0.01


def test_a_curled_bucket_rides_up_on_its_buried_underside():
    """Curled ~0.45 rad and pushed, the bucket's floor underside wedges into the pile: its
    heel resists deeper than its edge, and the soil's reaction on the face-down floor
    lifts the bucket and the machine's front (as on particles, docs/soil_models.md). The
    default heightfield resists only the raised edge, horizontally: the bucket stays low
    and drives on into the pile."""
    _, default_extra, _, default_rise = _push({}, curl_s=0.6)
    _, body_extra, _, body_rise = _push(BODY, curl_s=0.6)
    assert default_extra == 0.0
    assert body_extra > 0.2  # the heel sits > 0.2 m deeper than the edge
    assert default_rise < 0.02
    assert body_rise > 0.2


def test_the_underside_lift_follows_the_fee_for_a_face_down_blade():
    soil = _block_soil()
    delta = math.radians(soil.material.tool_friction_angle_deg)
    pitch, force, edge_force = 0.45, 9000.0, 3000.0
    ratio = soil._underside_lift_ratio(pitch, force, edge_force)
    assert ratio == pytest.approx((force - edge_force) / math.tan(pitch + delta) / force)
    assert soil._underside_lift_ratio(0.0, force, edge_force) == 0.0  # level: no lift
    assert soil._underside_lift_ratio(pitch, force, force) == 0.0  # nothing below the edge
    assert soil._underside_lift_ratio(math.pi / 2, force, edge_force) == 0.0  # past vertical


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_bad_body_resistance_option_fails_naming_it(bad):
    with pytest.raises(ValueError, match="body_resistance"):
        gym.make("pilerl/PileLoading-v0", soil_options={"body_resistance": bad})
