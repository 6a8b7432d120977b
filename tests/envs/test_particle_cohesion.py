"""Cohesion in the particle soil: the bond force's derivation, its wiring (bonds between
grains only, none to the steel; loose grains at c = 0), and Terzaghi's vertical cut
without the bucket (``soil/particle_cut.py``): a cohesive face below the critical height
stands, one well above it collapses, a loose one slumps."""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from pilerl_pile_loader.conditions import get_condition
from pilerl_pile_loader.soil.particle_cut import critical_height_m, run_cut
from pilerl_pile_loader.soil.particles import (
    COHESION_CALIBRATION,
    HCP_SOLID_FRACTION,
    MACHINE_CONTYPE,
    bond_force_n,
)

import pilerl  # noqa: F401

WINTER_C = get_condition("winter_c").material  # c 2000 Pa, phi 33 deg, 1550 kg/m^3
GRAIN_M = 0.1067  # the default pile's grain: 6 across the 0.64 m bucket mouth
COARSE = {"mouth_grains": 4.0}


def _cut(height_ratio: float, cohesion_pa: float):
    m = WINTER_C
    h_c = critical_height_m(m.cohesion_pa, m.friction_angle_deg, m.density_kg_m3)
    return run_cut(
        height_ratio * h_c, cohesion_pa, m.friction_angle_deg, m.density_kg_m3, GRAIN_M
    ), h_c


# ---- the bond force (particles.bond_force_n)
def test_bond_force_is_rumpf_over_mohr_coulomb_tension():
    c, phi, d = 2000.0, 33.0, 0.1
    tensile = 2 * c * math.tan(math.radians(45 - phi / 2))  # Mohr-Coulomb uniaxial tension
    # Rumpf: tensile = (1 - eps) k F / (pi D^2), with the bonds around a grain summing to 2 G
    expected = math.pi * d**2 * tensile / (2 * HCP_SOLID_FRACTION)
    assert bond_force_n(c, phi, d) == pytest.approx(COHESION_CALIBRATION * expected)
    assert bond_force_n(0.0, phi, d) == 0.0
    # linear in c, and in the grain's cross-section: the same strength at every resolution
    assert bond_force_n(2 * c, phi, d) == pytest.approx(2 * bond_force_n(c, phi, d))
    assert bond_force_n(c, phi, 2 * d) == pytest.approx(4 * bond_force_n(c, phi, d))


def test_negative_cohesion_fails_naming_the_function():
    with pytest.raises(ValueError, match="bond_force_n"):
        bond_force_n(-1.0, 30.0, 0.1)


# ---- the wiring in the env
def make(condition: str, **soil_options) -> gym.Env:
    return gym.make(
        "pilerl/PileLoading-v0",
        soil="particles",
        condition=condition,
        sensor_noise=0.0,
        soil_options={**COARSE, **soil_options},
    )


@pytest.fixture(scope="module")
def winter_env() -> gym.Env:
    env = make("winter_c")
    env.reset(seed=0)
    return env


def _bonds(model: mujoco.MjModel) -> list[int]:
    return [i for i in range(model.nu) if "_bond_" in model.actuator(i).name]


def test_cohesive_grains_each_pull_their_contacts_with_the_bond_force(winter_env):
    soil, model = winter_env.unwrapped.soil, winter_env.unwrapped.model
    bonds = _bonds(model)
    assert len(bonds) == 3 * soil.n_particles  # a motor on each of a grain's three slides
    expected = bond_force_n(WINTER_C.cohesion_pa, WINTER_C.friction_angle_deg, 2 * soil.radius_m)
    assert soil.bond_force_n == pytest.approx(expected)
    assert soil.bonds.bond_n == pytest.approx(expected)
    np.testing.assert_array_equal(model.actuator_trntype[bonds], int(mujoco.mjtTrn.mjTRN_JOINT))
    np.testing.assert_array_equal(model.actuator_gainprm[bonds, 0], 1.0)  # ctrl = force [N]
    np.testing.assert_array_equal(model.actuator_ctrllimited[bonds], 0)
    # the motors drive the grains' slides, and the grains are still allowed to sleep
    grains = np.arange(model.nbody)[soil._bodies]
    slides = model.actuator_trnid[bonds, 0].reshape(-1, 3)
    np.testing.assert_array_equal(model.jnt_bodyid[slides], np.repeat(grains[:, None], 3, 1))
    policy = model.tree_sleep_policy[model.body_treeid[grains]]
    np.testing.assert_array_equal(policy, int(mujoco.mjtSleepPolicy.mjSLEEP_ALLOWED))
    assert winter_env.unwrapped.machine.drive_actuator not in bonds


def test_grains_bond_to_the_pile_not_to_the_steel_or_the_ground(winter_env):
    """A grain's bonded geom touches grains, the static core and the walls (the rest of the
    pile), never the machine or the ground; its unbonded copy (a welded child body,
    outside MuJoCo's body adhesion) touches only the machine and the ground."""
    soil, model = winter_env.unwrapped.soil, winter_env.unwrapped.model
    grains = np.arange(model.nbody)[soil._bodies]
    bonded = model.body_geomadr[grains]
    unbonded = model.body_geomadr[grains + 1]
    np.testing.assert_array_equal(model.body_parentid[grains + 1], grains)
    machine = np.flatnonzero(model.geom_contype == MACHINE_CONTYPE)
    ground = model.geom("ground").id
    core = model.geom("core_0").id
    walls = [model.geom(f"pile_wall_{i}").id for i in range(3)]
    assert len(machine)

    def touch(a, b):
        return (model.geom_contype[a] & model.geom_conaffinity[b]) | (
            model.geom_contype[b] & model.geom_conaffinity[a]
        )

    for g, u in zip(bonded[:5], unbonded[:5], strict=True):
        assert not touch(g, machine).any() and not touch(g, ground)
        assert touch(g, bonded[5]) and touch(g, core) and touch(g, walls).all()
        assert touch(u, machine).all() and touch(u, ground)
        others = np.setdiff1d(np.arange(model.ngeom), [*machine, ground])
        assert not touch(u, others).any()
    assert touch(core, machine).all()  # the machine still meets the static core


def test_cohesion_can_be_switched_off_and_is_off_for_loose_materials():
    for env in (make("winter_c", cohesion=False), make("summer")):
        assert not _bonds(env.unwrapped.model)
        assert env.unwrapped.soil.bond_force_n == 0.0
        env.close()


def test_impossible_cohesion_option_fails_naming_it():
    with pytest.raises(ValueError, match="cohesion"):
        make("winter_c", cohesion="yes")


# ---- Terzaghi's vertical cut (winter_c's material at the default grain size)
def test_a_loose_face_slumps():
    result, _ = _cut(0.75, 0.0)
    assert result.moved_fraction > 0.2
    assert result.face_top_drop_m > 2 * GRAIN_M


@pytest.mark.parametrize("height_ratio", [0.5, 0.75])
def test_a_cohesive_face_below_the_critical_height_stands(height_ratio):
    result, h_c = _cut(height_ratio, WINTER_C.cohesion_pa)
    assert result.height_m == pytest.approx(height_ratio * h_c, abs=GRAIN_M)
    assert result.moved_fraction == 0.0
    assert result.max_displacement_m < GRAIN_M / 2
    assert result.face_top_drop_m < GRAIN_M / 4


def test_a_cohesive_face_well_above_the_critical_height_collapses():
    result, h_c = _cut(1.5, WINTER_C.cohesion_pa)
    assert result.height_m == pytest.approx(1.5 * h_c, abs=GRAIN_M)
    assert result.moved_fraction > 0.2
    assert result.face_top_drop_m > GRAIN_M


@pytest.mark.parametrize(
    ("field", "value"), [("diameter_m", 0.0), ("watch_s", -1.0), ("cohesion_pa", -5.0)]
)
def test_an_impossible_cut_fails_naming_the_field(field, value):
    from pilerl_pile_loader.soil.particle_cut import run_cut

    arguments = {
        "height_m": 0.5,
        "cohesion_pa": 2000.0,
        "friction_angle_deg": 33.0,
        "density_kg_m3": 1550.0,
        "diameter_m": 0.107,
        "watch_s": 1.5,
    }
    with pytest.raises(ValueError, match=f"run_cut: {field}"):
        run_cut(**{**arguments, field: value})
