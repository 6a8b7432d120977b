"""The earthmoving equation and the bucket's holding volume."""

from __future__ import annotations

import math

import pytest
from pilerl_pile_loader.soil.base import BucketGeometry
from pilerl_pile_loader.soil.earthmoving import cutting_force_n, fee_factors

FACTORS = fee_factors(
    rake_angle_rad=math.radians(65),
    friction_angle_rad=math.radians(38),
    tool_friction_angle_rad=math.radians(25),
)


def force(depth, cohesion=0.0):
    return cutting_force_n(
        FACTORS, depth_m=depth, width_m=1.3, density_kg_m3=1700.0, cohesion_pa=cohesion
    )


def test_no_force_above_the_surface():
    assert force(0.0) == 0.0 and force(-0.2) == 0.0


def test_cohesionless_force_grows_with_depth_squared():
    assert force(0.4) / force(0.2) == pytest.approx(4.0)


def test_cohesion_adds_a_term_linear_in_depth():
    extra_02 = force(0.2, cohesion=5000) - force(0.2)
    extra_04 = force(0.4, cohesion=5000) - force(0.4)
    assert extra_02 > 0 and extra_04 / extra_02 == pytest.approx(2.0)


def test_degenerate_wedge_is_rejected():
    with pytest.raises(ValueError, match="no passive wedge"):
        fee_factors(
            rake_angle_rad=math.radians(89),
            friction_angle_rad=math.radians(45),
            tool_friction_angle_rad=math.radians(45),
        )


def test_bucket_holds_more_when_curled_and_nothing_when_dumping():
    bucket = BucketGeometry()
    repose = math.radians(38)
    dumping, flat, curled = (bucket.holding_volume_m3(p, repose) for p in (-1.0, 0.0, 0.6))
    assert dumping < 0.05 * bucket.rated_volume_m3
    assert 0.5 * bucket.rated_volume_m3 < flat < curled
    assert curled == pytest.approx(bucket.rated_volume_m3 * (1 + bucket.heap_fraction), rel=0.02)
