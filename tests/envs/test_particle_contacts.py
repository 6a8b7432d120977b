"""The particle pile's contact stiffness set by the material, not by the grain's mass
(``soil_options={"contact_modulus_pa": ...}``, an option; docs/soil_models.md): a grain
pressed by the same stress sinks the same fraction of its diameter at every resolution,
against the bucket's steel and against another grain. MuJoCo's mass-normalised contacts
(``contact_modulus_pa=None``, the default) sink the lighter grains of a finer pile deeper.

The grains are pressed in a one-grain MuJoCo model built from the soil's own contact
parameters (the pile is not compiled), so the test is small and exact."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from pilerl_pile_loader.conditions import CONDITIONS
from pilerl_pile_loader.machine import load_machine_spec
from pilerl_pile_loader.soil import BucketGeometry, PileGeometry
from pilerl_pile_loader.soil.particles import (
    BEVEL_ANGLE_DEG,
    CONE,
    CONTACT_IMPEDANCE_RANGE,
    GRAIN_CONTACT_MODULUS_PA,
    MUJOCO_SOLIMP,
    MUJOCO_SOLREF,
    ParticleSoil,
    contact_parameters,
    steel_contact,
)

import pilerl  # noqa: F401

STRESS_PA = 5e4  # about the bucket's push spread over its face (20-30 kN on 0.5 m^2)
COARSE, FINE = 4.0, 8.0  # grain diameters across the bucket mouth


def _soil_spec(
    mouth_grains: float, condition: str = "summer", *, material=None, **options
) -> tuple[ParticleSoil, mujoco.MjSpec]:
    """The soil's grain size, mass and contact parameters, without compiling its pile
    (``material``: instead of the condition's)."""
    options = {"contact_modulus_pa": GRAIN_CONTACT_MODULUS_PA, **options}
    soil = ParticleSoil(
        material or CONDITIONS[condition].material,
        PileGeometry(),
        BucketGeometry(),
        mouth_grains=mouth_grains,
        **options,
    )
    spec = load_machine_spec()
    soil.add_to_spec(spec)
    return soil, spec


def _copy_contact(source: mujoco.MjsGeom, target: mujoco.MjsGeom) -> None:
    for key in ("priority", "condim", "friction", "solref", "solimp"):
        setattr(target, key, np.array(getattr(source, key)))


def _sink_m(soil: ParticleSoil, spec: mujoco.MjSpec, against: str, force_n: float) -> float:
    """How far [m] one of the soil's grains, pressed down by ``force_n`` (no gravity), sinks
    into the bucket's floor plate (``against="steel"``), or how far two of them, pressed
    together by ``force_n``, overlap (``"grain"``), at rest."""
    grain = spec.body("particle_0").first_geom()
    r = soil.radius_m
    press = mujoco.MjSpec()
    press.option.timestep = 0.002
    press.option.gravity = [0.0, 0.0, 0.0]
    press.option.solver = mujoco.mjtSolver.mjSOL_CG
    press.option.cone = CONE
    press.option.iterations = 200
    press.option.tolerance = 1e-12

    def add_grain(z: float) -> None:
        body = press.worldbody.add_body(pos=[0.0, 0.0, z])
        for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):  # as in the pile
            body.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=list(axis))
        sphere = body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[r, 0, 0])
        sphere.mass = soil.particle_mass_kg
        _copy_contact(grain, sphere)

    if against == "steel":
        plate = press.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[1.0, 1.0, 0.012])
        _copy_contact(spec.geom("bucket_floor"), plate)
        add_grain(0.012 + r)  # just touching
    else:
        add_grain(-r)
        add_grain(r)
    model = press.compile()
    data = mujoco.MjData(model)
    for _ in range(1000):  # 2 s: at rest long before
        data.qfrc_applied[2::3][-1] = -force_n  # the top grain's z joint: down
        if against == "grain":
            data.qfrc_applied[2] = force_n  # the bottom grain's: up
        mujoco.mj_step(model, data)
    assert np.abs(data.qvel).max() < 1e-9
    if against == "steel":
        return -float(data.qpos[2])
    return float(data.qpos[2] - data.qpos[5])


@pytest.mark.parametrize("against", ["steel", "grain"])
def test_a_grain_pressed_by_the_same_stress_sinks_the_same_fraction_of_its_diameter(against):
    fractions = []
    for grains in (COARSE, FINE):
        soil, spec = _soil_spec(grains)
        diameter = 2 * soil.radius_m
        force = STRESS_PA * diameter**2
        sink = _sink_m(soil, spec, against, force)
        # the stiffness asked for: GRAIN_CONTACT_MODULUS_PA x D against steel, half that
        # between two grains
        stiffness = GRAIN_CONTACT_MODULUS_PA * diameter / (1 if against == "steel" else 2)
        assert soil.grain_stiffness_n_m == pytest.approx(GRAIN_CONTACT_MODULUS_PA * diameter)
        assert sink == pytest.approx(force / stiffness, rel=0.02)
        fractions.append(sink / diameter)
    assert fractions[1] == pytest.approx(fractions[0], rel=0.02)
    # the finer grains are much lighter: the mass did not set the stiffness
    assert _soil_spec(COARSE)[0].particle_mass_kg > 7 * _soil_spec(FINE)[0].particle_mass_kg


@pytest.mark.parametrize("against", ["steel", "grain"])
def test_mass_normalised_contacts_sink_the_finer_grains_deeper(against):
    """The phenomenon fixed: with MuJoCo's contacts a grain of mass m sinks ~ (F / m) tau^2,
    so under the same stress (F ~ D^2, m ~ D^3) half the diameter sinks about four times the
    fraction of it."""
    fractions = []
    for grains in (COARSE, FINE):
        soil, spec = _soil_spec(grains, contact_modulus_pa=None)
        diameter = 2 * soil.radius_m
        fractions.append(_sink_m(soil, spec, against, STRESS_PA * diameter**2) / diameter)
    assert fractions[1] > 3 * fractions[0]


def test_contact_parameters_keep_the_stiffness_whatever_the_friction():
    """The pyramidal friction cone stiffens a contact by 2 / (mu^2 (1 + mu^2)); the
    impedance makes up for it: the same stiffness on snow-slick steel (winter_d, tan 10 deg)
    as on gravel, where the coarse grain needs a longer time constant."""
    for condition in ("summer", "winter_c", "winter_d"):
        soil, spec = _soil_spec(COARSE, condition)
        force = STRESS_PA * (2 * soil.radius_m) ** 2
        assert _sink_m(soil, spec, "steel", force) == pytest.approx(
            force / soil.grain_stiffness_n_m, rel=0.02
        )
    # winter_c's steel friction (tan 15 deg) on a 4-grain pile's grain
    tau, d = contact_parameters(5.4, 8e6, 0.27, 0.004)
    assert tau > 0.004 and d == pytest.approx(CONTACT_IMPEDANCE_RANGE[0])


def test_the_env_gives_grains_core_walls_and_bucket_the_contact_parameters():
    options = {"mouth_grains": 4.0, "contact_modulus_pa": GRAIN_CONTACT_MODULUS_PA}
    env = gym.make("pilerl/PileLoading-v0", soil="particles", soil_options=options)
    soil, model = env.unwrapped.soil, env.unwrapped.model
    _, spec = _soil_spec(COARSE)
    grain = spec.body("particle_0").first_geom()
    bucket = spec.geom("bucket_floor")
    for name in ("core_0", "pile_wall_0"):
        np.testing.assert_allclose(model.geom_solimp[model.geom(name).id], grain.solimp)
        np.testing.assert_allclose(model.geom_solref[model.geom(name).id], grain.solref)
    first = model.body_geomadr[model.body("particle_0").id]
    np.testing.assert_allclose(model.geom_solimp[first], grain.solimp)
    for name in ("bucket_floor", "bucket_back", "bucket_top", "bucket_side_l", "bucket_side_r"):
        np.testing.assert_allclose(model.geom_solimp[model.geom(name).id], bucket.solimp)
        np.testing.assert_allclose(model.geom_solref[model.geom(name).id], bucket.solref)
    assert soil.contact_modulus_pa == GRAIN_CONTACT_MODULUS_PA
    # the bucket's steel is stiffer against a grain than two grains are against each other
    assert grain.solimp[0] != bucket.solimp[0]


def test_mass_normalised_contacts_are_the_default_and_leave_the_bucket_at_mujocos():
    default = ParticleSoil(CONDITIONS["summer"].material, PileGeometry(), BucketGeometry())
    assert default.contact_modulus_pa is None
    soil, spec = _soil_spec(COARSE, contact_modulus_pa=None)
    assert soil.grain_stiffness_n_m is None
    np.testing.assert_allclose(spec.geom("bucket_floor").solref, [0.02, 1.0])
    np.testing.assert_allclose(spec.body("particle_0").first_geom().solref, [0.004, 1.0])


def test_default_steel_contacts_are_as_stiff_whatever_the_steel_friction():
    """The phenomenon behind grains thrown out of the pile on ice (docs/soil_models.md):
    with MuJoCo's default contacts the pyramidal cone made a grain's contact with the
    bucket's steel 3.4 times stiffer on winter_c's tan 15 deg than on summer's tan 25 deg,
    nearly a hard constraint, which the pile's capped solver left unresolved. A grain now
    sinks as far into the plate under the same force per kilogram (the contacts stay
    mass-normalised) on every material, summer's being MuJoCo's defaults."""
    acceleration = 1000.0  # [m/s^2]: ~1.5 kN on a 1.5 kg grain, a squeeze under the bucket
    sinks = {}
    for condition in ("summer", "winter_a", "winter_c", "winter_d"):
        soil, spec = _soil_spec(COARSE, condition, contact_modulus_pa=None)
        sinks[condition] = _sink_m(soil, spec, "steel", acceleration * soil.particle_mass_kg)
    # and above the reference friction (the impedance then stiffer than MuJoCo's default)
    rough = dataclasses.replace(CONDITIONS["summer"].material, tool_friction_angle_deg=35.0)
    soil, spec = _soil_spec(COARSE, material=rough, contact_modulus_pa=None)
    sinks["steel at 35 deg"] = _sink_m(soil, spec, "steel", acceleration * soil.particle_mass_kg)
    for condition, sink in sinks.items():
        assert sink == pytest.approx(sinks["summer"], rel=0.02), condition
    # about 2.6 mm: MuJoCo's default impedance (1 - 0.95) x (0.02 s)^2 x 1000 m/s^2 / c,
    # c = 7.6 for tan 25 deg
    assert sinks["summer"] == pytest.approx(0.05 * 0.02**2 * 1000.0 / 7.6, rel=0.1)
    np.testing.assert_allclose(steel_contact(np.tan(np.radians(25.0)))[1], MUJOCO_SOLIMP)
    for angle_deg in (5.0, 10.0, 15.0, 22.0, 30.0, 40.0):
        solref, solimp = steel_contact(np.tan(np.radians(angle_deg)))
        assert solref[0] >= MUJOCO_SOLREF[0]
        low, high = CONTACT_IMPEDANCE_RANGE
        assert low - 1e-12 <= solimp[0] <= solimp[1] <= high


@pytest.mark.parametrize("bad", [0.0, -0.3, float("nan")])
def test_impossible_steel_friction_fails_naming_the_function(bad):
    with pytest.raises(ValueError, match="steel_contact"):
        steel_contact(bad)


@pytest.mark.parametrize("angle_deg", [0.0, 2.0])
def test_too_smooth_steel_fails_naming_the_material_field(angle_deg):
    smooth = dataclasses.replace(CONDITIONS["summer"].material, tool_friction_angle_deg=angle_deg)
    with pytest.raises(ValueError, match="tool_friction_angle_deg must be >= 5 deg"):
        _soil_spec(COARSE, material=smooth, contact_modulus_pa=None)


@pytest.mark.parametrize("bad", [1e3, 1e12, float("nan"), True, "5e7"])
def test_impossible_contact_modulus_fails_naming_the_option(bad):
    with pytest.raises(ValueError, match="contact_modulus_pa"):
        gym.make(
            "pilerl/PileLoading-v0", soil="particles", soil_options={"contact_modulus_pa": bad}
        )


def test_a_stiffness_the_solver_cannot_hold_fails_naming_the_option():
    with pytest.raises(ValueError, match="contact_modulus_pa"):
        _soil_spec(FINE, contact_modulus_pa=5e9)  # impedance above 0.999 for 8 cm grains


# ---- the bevelled cutting edge (soil_options={"bevelled_edge": True})


def test_bevelled_edge_is_a_steel_ramp_over_the_floor_plates_front_face():
    soil, spec = _soil_spec(COARSE, bevelled_edge=True)
    bevel, floor = spec.geom("bucket_bevel"), spec.geom("bucket_floor")
    for key in ("priority", "friction", "solref", "solimp", "contype", "conaffinity"):
        np.testing.assert_allclose(getattr(bevel, key), getattr(floor, key))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    g = model.geom("bucket_bevel").id
    rotation = data.geom_xmat[g].reshape(3, 3)
    # its top face faces forward and up, BEVEL_ANGLE_DEG off the vertical (a level bucket)
    normal = rotation[:, 2]
    assert np.degrees(np.arccos(normal[2])) == pytest.approx(BEVEL_ANGLE_DEG, abs=1e-6)
    assert normal[0] > 0 and abs(normal[1]) < 1e-9
    # the ramp's top face starts ahead of the floor plate, at its underside, and rises over
    # its front face (all but the top 3 mm of the 2.4 cm face lie under the ramp)
    f = model.geom("bucket_floor").id
    floor_rotation = data.geom_xmat[f].reshape(3, 3)
    half = model.geom_size[f]
    front_bottom = data.geom_xpos[f] + floor_rotation @ (half * [1, 0, -1])
    front_top = data.geom_xpos[f] + floor_rotation @ (half * [1, 0, 1])
    top_centre = data.geom_xpos[g] + normal * model.geom_size[g][2]
    assert (front_bottom - top_centre) @ normal < 0
    below_top = front_top - 0.003 * floor_rotation[:, 2]
    assert (below_top - top_centre) @ normal < 0
    tip = top_centre + rotation[:, 0] * model.geom_size[g][0]
    ahead = (tip - front_bottom) @ floor_rotation[:, 0]
    assert ahead == pytest.approx(2 * half[2] / np.tan(np.radians(BEVEL_ANGLE_DEG)), abs=0.01)
    assert not _soil_spec(COARSE)[1].geom("bucket_bevel")  # only with the option


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_impossible_bevelled_edge_fails_naming_the_option(bad):
    with pytest.raises(ValueError, match="bevelled_edge"):
        gym.make("pilerl/PileLoading-v0", soil="particles", soil_options={"bevelled_edge": bad})
