"""The particle soil (``soil="particles"``): a settled pile, exact mass bookkeeping,
determinism, a scoop that puts particles in the bucket, and the resolution (grains across
the bucket mouth, fill measured the same way at every resolution).

The scoops run on a coarse pile (``COARSE``, 4 grains across the mouth) to keep the suite
fast; the default resolution is built once and checked without scooping."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from pilerl_pile_loader.soil import SOIL_MODELS
from pilerl_pile_loader.soil.particles import (
    ACTIVE_DEPTH_M,
    COVER_RADIUS_RATIO,
    FOOTPRINT_MARGIN_M,
    MAX_PARTICLES,
    MOUTH_GRAINS,
    ParticleSoil,
)

import pilerl  # noqa: F401

DRIVE_IN = np.array([0.0, 0.0, 0.5], np.float32)  # half throttle, bucket flat
CURL_AND_RAISE = np.array([0.8, 0.8, 0.0], np.float32)
DRIVE_STEPS = 48  # 2.4 s at 20 Hz: 1 m to the toe, then into the pile until it stalls
MAX_STEPS = 120
COARSE = {"mouth_grains": 4.0}  # the scooping tests' resolution (fast)


def make(**kwargs) -> gym.Env:
    kwargs = {
        "start_distance_range_m": (1.0, 1.0),
        "approach_angle_range_deg": (0.0, 0.0),
        "soil_options": COARSE,
        **kwargs,
    }
    return gym.make("pilerl/PileLoading-v0", soil="particles", **kwargs)


def scoop(env: gym.Env, seed: int, steps: int = MAX_STEPS) -> list[dict]:
    """Drive in, then curl and raise until the scoop ends; the info of every step."""
    env.reset(seed=seed)
    infos = []
    for k in range(steps):
        *_, terminated, truncated, info = env.step(DRIVE_IN if k < DRIVE_STEPS else CURL_AND_RAISE)
        infos.append(info)
        if terminated or truncated:
            break
    return infos


@pytest.fixture(scope="module")
def env() -> gym.Env:
    return make(sensor_noise=0.0)


@pytest.fixture(scope="module")
def default_env() -> gym.Env:
    return gym.make("pilerl/PileLoading-v0", soil="particles", sensor_noise=0.0)


@pytest.fixture(scope="module")
def scoop_infos(env) -> list[dict]:
    return scoop(env, seed=0)


def test_registered_and_without_soil_actuators(env):
    soil = env.unwrapped.soil
    assert SOIL_MODELS["particles"] is ParticleSoil
    assert isinstance(soil, ParticleSoil)
    model = env.unwrapped.model
    names = {model.actuator(i).name for i in range(model.nu)}
    assert not names & {"soil_push", "soil_lift", "soil_side"}
    assert 0 < soil.n_particles <= MAX_PARTICLES
    # the particles carry their own mass: the payload body stays massless
    assert model.body_mass[model.body("payload").id] == pytest.approx(1e-6)


def test_particle_mass_is_the_bulk_mass_of_the_zone(env):
    soil = env.unwrapped.soil
    bulk_kg = soil.material.density_kg_m3 * soil.zone_volume_m3
    assert soil.n_particles * soil.particle_mass_kg == pytest.approx(bulk_kg)
    # the zone is the pile between its toe and the back wall, down to ACTIVE_DEPTH_M below
    # its surface (the face rises at the repose angle; deeper lies the static core)
    slope = np.tan(soil.repose_angle_rad)
    length = soil.x_back_m - soil.pile.toe_x_m
    full_depth_x = ACTIVE_DEPTH_M / slope  # where the face is ACTIVE_DEPTH_M high
    assert length > full_depth_x
    section_m2 = 0.5 * full_depth_x * ACTIVE_DEPTH_M + (length - full_depth_x) * ACTIVE_DEPTH_M
    assert soil.zone_volume_m3 == pytest.approx(2 * soil.half_width_m * section_m2, rel=0.02)
    masses = env.unwrapped.model.body_mass[soil._bodies]
    np.testing.assert_allclose(masses, soil.particle_mass_kg)


def test_pile_is_at_rest_in_its_shape_after_reset(env):
    soil, data = env.unwrapped.soil, env.unwrapped.data
    env.reset(seed=3)
    assert soil.particle_counts == (soil.n_particles, 0, 0)
    assert soil.pile_mass_kg == pytest.approx(soil.initial_mass_kg)
    assert soil.cutting_depth_m() == 0.0
    # asleep, where the settled lattice put them (shifted sideways to the bucket path)
    assert not np.any(data.qvel[soil._dofs])
    expected = soil.lattice + np.reshape(soil._settled_qpos, (-1, 3))
    expected[:, 1] += soil.zone_offset_y_m
    np.testing.assert_allclose(soil.particle_positions(), expected, atol=1e-3)  # < 1 mm
    assert np.abs(soil._settled_qpos).max() < 0.25 * soil.radius_m  # settling barely moved them
    # every centre under the undisturbed pile surface (plus its radius of lattice roughness)
    pos = expected - [0.0, soil.zone_offset_y_m, 0.0]
    surface = soil.pile.surface_height(pos[:, 0], pos[:, 1], soil.repose_angle_rad)
    assert np.all(pos[:, 2] <= surface + soil.radius_m)
    # the moving grains lie within ACTIVE_DEPTH_M of the surface, the static core deeper
    assert np.all(surface - soil.lattice[:, 2] <= ACTIVE_DEPTH_M + 1e-9)
    core = soil.core
    core_surface = soil.pile.surface_height(core[:, 0], core[:, 1], soil.repose_angle_rad)
    assert len(core) > 0 and np.all(core_surface - core[:, 2] > ACTIVE_DEPTH_M)


def test_zone_follows_the_bucket_path(env):
    for seed in (0, 1, 2):
        _, info = env.reset(seed=seed)
        assert env.unwrapped.soil.zone_offset_y_m == pytest.approx(info["aim_offset_m"], abs=1e-6)


def test_mass_is_conserved_at_every_step(env, scoop_infos):
    soil = env.unwrapped.soil
    for info in scoop_infos:
        total = info["pile_mass_kg"] + info["bucket_load_kg"] + info["spilled_kg"]
        assert total == pytest.approx(soil.initial_mass_kg, rel=1e-12)
    assert sum(soil.particle_counts) == soil.n_particles


def test_driving_in_then_curling_puts_particles_in_the_bucket(scoop_infos):
    last = scoop_infos[-1]
    assert last["scoop_finished"]
    assert last["fill_fraction"] > 0.0
    assert last["bucket_load_kg"] > 0.0
    # the cutting edge went into the pile and stalled there
    assert max(info["cutting_depth_m"] for info in scoop_infos[:DRIVE_STEPS]) > 0.2
    assert scoop_infos[DRIVE_STEPS - 1]["forward_speed_m_s"] < 0.3


def test_same_seed_gives_the_same_particles(env, scoop_infos):
    soil = env.unwrapped.soil
    first_positions = soil.particle_positions().copy()
    other = make(sensor_noise=0.0)
    # a pile built and settled again is the same pile, to the bit
    np.testing.assert_array_equal(other.unwrapped.soil._settled_qpos, soil._settled_qpos)
    infos = scoop(other, seed=0)
    assert [i["fill_fraction"] for i in infos] == [i["fill_fraction"] for i in scoop_infos]
    np.testing.assert_array_equal(other.unwrapped.soil.particle_positions(), first_positions)
    # and the same environment again, after a reset with another seed in between
    other.reset(seed=5)
    infos_again = scoop(other, seed=0)
    assert infos_again[-1]["fill_fraction"] == scoop_infos[-1]["fill_fraction"]
    np.testing.assert_array_equal(other.unwrapped.soil.particle_positions(), first_positions)


def _teleport(env: gym.Env, index: int, world_xyz: np.ndarray) -> None:
    """Put particle ``index`` at a world position and recount (wakes its pile)."""
    u = env.unwrapped
    soil, model, data = u.soil, u.model, u.data
    adr = soil._qpos.start + 3 * index
    data.qpos[adr : adr + 3] = world_xyz - soil.lattice[index]
    data.qvel[soil._dofs.start + 3 * index] = 1e-12  # a sleeping body ignores new qpos
    mujoco.mj_forward(model, data)
    soil.update(0.0)


def test_tallies_follow_the_definitions(env):
    u = env.unwrapped
    soil, data, machine = u.soil, u.data, u.machine
    env.reset(seed=0)
    n = soil.n_particles
    # inside the bucket: the centre of the interior polygon, in the bucket frame
    centre_xz = soil.bucket.centroid_xz()
    rotation = data.xmat[machine.bucket_body].reshape(3, 3)
    inside = data.xpos[machine.bucket_body] + rotation @ [centre_xz[0], 0.0, centre_xz[1]]
    _teleport(env, 0, inside)
    assert soil.particle_counts == (n - 1, 1, 0)
    assert soil.bucket_load_kg == pytest.approx(soil.particle_mass_kg)
    # on the ground well in front of the toe: spilled
    toe = soil.pile.toe_x_m
    _teleport(env, 1, np.array([toe - FOOTPRINT_MARGIN_M - 0.5, 2.0, soil.radius_m]))
    assert soil.particle_counts == (n - 2, 1, 1)
    # in the air off the footprint: not (yet) spilled
    _teleport(env, 1, np.array([toe - FOOTPRINT_MARGIN_M - 0.5, 2.0, 2.0]))
    assert soil.particle_counts == (n - 1, 1, 0)
    total = soil.pile_mass_kg + soil.bucket_load_kg + soil.spilled_kg
    assert total == pytest.approx(soil.initial_mass_kg, rel=1e-12)


def test_default_resolution_spans_the_bucket_mouth_with_six_grains(default_env):
    soil = default_env.unwrapped.soil
    mouth_m = np.linalg.norm(soil.bucket.lip_xz - soil.bucket.cutting_edge_xz)
    assert soil.mouth_length_m == pytest.approx(mouth_m)
    assert soil.mouth_diameters == pytest.approx(mouth_m / (2 * soil.radius_m))
    assert soil.mouth_diameters == pytest.approx(MOUTH_GRAINS)  # not capped by max_particles
    assert soil.mouth_diameters >= 6.0
    assert soil.n_particles <= MAX_PARTICLES


def test_finer_pile_is_an_option(env, default_env):
    coarse, fine = env.unwrapped.soil, default_env.unwrapped.soil
    assert coarse.mouth_diameters == pytest.approx(COARSE["mouth_grains"])
    assert fine.n_particles > 2 * coarse.n_particles
    assert fine.radius_m < coarse.radius_m
    total = fine.n_particles * fine.particle_mass_kg
    assert total == pytest.approx(coarse.n_particles * coarse.particle_mass_kg, rel=0.15)


def test_max_particles_caps_the_moving_grains():
    soil = gym.make(
        "pilerl/PileLoading-v0", soil="particles", soil_options={"max_particles": 150}
    ).unwrapped.soil
    assert soil.n_particles <= 150
    assert soil.mouth_diameters < MOUTH_GRAINS  # the radius grew to fit the cap


def _fill_bucket_with_lattice(env: gym.Env) -> int:
    """Teleport particles onto the bucket's inside packed like the pile
    (``packed_bucket_sites``) and recount; return how many."""
    u = env.unwrapped
    soil, data, machine = u.soil, u.data, u.machine
    local = soil.packed_bucket_sites()
    assert len(local) <= soil.n_particles
    rotation = data.xmat[machine.bucket_body].reshape(3, 3)
    world = data.xpos[machine.bucket_body] + local @ rotation.T
    n = len(world)
    qpos = data.qpos[soil._qpos].reshape(-1, 3)
    qpos[:n] = world - soil.lattice[:n]
    data.qpos[soil._qpos] = qpos.ravel()
    data.qvel[soil._dofs][: 3 * n] = 1e-12  # a sleeping body ignores new qpos
    mujoco.mj_forward(u.model, data)
    soil.update(0.0)
    return n


@pytest.mark.parametrize("which", ["coarse", "default"])
def test_fill_of_a_packed_bucket_is_measured_consistently(which, env, default_env):
    """Each grain carries the bulk mass of its share of the pile, so grains packed into the
    bucket as densely as in the pile read the bucket's rated (struck) capacity, less the
    gaps a grain wide along its plates: ``packed_bucket_fill``, measured by the tallies."""
    env = env if which == "coarse" else default_env
    env.reset(seed=0)
    n = _fill_bucket_with_lattice(env)
    soil = env.unwrapped.soil
    assert soil.particle_counts == (soil.n_particles - n, n, 0)
    assert soil.fill_fraction == pytest.approx(soil.packed_bucket_fill, rel=1e-9)
    rated_kg = soil.material.density_kg_m3 * soil.bucket.rated_volume_m3
    assert soil.fill_fraction == pytest.approx(n * soil.particle_mass_kg / rated_kg, rel=1e-9)
    total = soil.pile_mass_kg + soil.bucket_load_kg + soil.spilled_kg
    assert total == pytest.approx(soil.initial_mass_kg, rel=1e-12)
    env.reset(seed=0)
    assert soil.particle_counts == (soil.n_particles, 0, 0)


def test_packed_bucket_fill_approaches_the_rated_capacity_with_resolution(env, default_env):
    coarse, fine = env.unwrapped.soil, default_env.unwrapped.soil
    assert coarse.packed_bucket_fill < fine.packed_bucket_fill <= 1.0
    assert fine.packed_bucket_fill > 0.85


@pytest.mark.parametrize(
    ("option", "bad"),
    [
        ("mouth_grains", 0.5),
        ("mouth_grains", 13.0),
        ("mouth_grains", float("nan")),
        ("mouth_grains", True),
        ("mouth_grains", "6"),
        ("solver_iterations", 0),
        ("solver_iterations", 2.5),
    ],
)
def test_impossible_resolution_fails_naming_the_option(option, bad):
    with pytest.raises(ValueError, match=option):
        gym.make("pilerl/PileLoading-v0", soil="particles", soil_options={option: bad})


# ---- fill as measured on a seeded scoop, and the bulk-volume measure (fill_measure)
VOLUME = {**COARSE, "fill_measure": "volume"}


def test_scripted_scoop_fills_as_recorded(scoop_infos):
    """The coarse pile's seeded drive-in-and-curl scoop reads 0.47 (measured with 30 CG
    iterations in session 30; 0.58 with 20, when the test was written, and 0.34 with the
    softer 0.01 s contacts): a broken contact model, grain size or tally moves it far."""
    assert scoop_infos[-1]["fill_fraction"] == pytest.approx(0.47, abs=0.08)


@pytest.fixture(scope="module")
def volume_env() -> gym.Env:
    return make(sensor_noise=0.0, soil_options=VOLUME)


def test_volume_measure_changes_the_fill_not_the_physics(volume_env, scoop_infos):
    infos = scoop(volume_env, seed=0)
    soil = volume_env.unwrapped.soil
    # the same scoop to the bit: the measure only reads the grains
    assert [i["bucket_load_kg"] for i in infos] == [i["bucket_load_kg"] for i in scoop_infos]
    rated_m3 = soil.bucket.rated_volume_m3
    final = infos[-1]["fill_fraction"]
    assert final == pytest.approx(soil.load_bulk_volume_m3() / rated_m3, rel=1e-12)
    # a scooped load lies looser than the pile it came from: its bulk volume is larger
    assert final > scoop_infos[-1]["fill_fraction"]
    assert final == pytest.approx(0.57, abs=0.08)  # 30 CG iterations (20: 0.68)


def test_bulk_volume_of_one_grain_is_its_column(volume_env):
    """One grain in the bucket covers the columns within COVER_RADIUS_RATIO radii of its
    centre, each filled from the floor to the grain's top."""
    env = volume_env
    u = env.unwrapped
    soil, data, machine = u.soil, u.data, u.machine
    env.reset(seed=0)
    assert soil.fill_fraction == 0.0
    centre_xz = soil.bucket.centroid_xz()
    rotation = data.xmat[machine.bucket_body].reshape(3, 3)
    hinge = data.xpos[machine.bucket_body]
    _teleport(env, 0, hinge + rotation @ [centre_xz[0], 0.0, centre_xz[1]])
    assert soil.particle_counts[1] == 1
    assert abs(machine.bucket_pitch()) < 0.01  # the floor is level at the start
    floor_z = hinge[2] + soil.bucket.polygon[0, 1]
    top_z = soil.particle_positions()[0, 2] + soil.radius_m
    disk_m2 = np.pi * (COVER_RADIUS_RATIO * soil.radius_m) ** 2
    expected_m3 = disk_m2 * (top_z - floor_z)
    assert soil.bucket_load_volume_m3 == pytest.approx(expected_m3, rel=0.1)


@pytest.mark.parametrize("which", ["coarse", "default"])
def test_bulk_volume_of_a_packed_bucket_matches_its_mass(which, env, default_env):
    """A bucket packed as densely as the pile has its bulk volume equal to its mass at
    bulk density (the two measures agree, up to the columns' discretisation)."""
    env = env if which == "coarse" else default_env
    env.reset(seed=0)
    _fill_bucket_with_lattice(env)
    soil = env.unwrapped.soil
    rated_m3 = soil.bucket.rated_volume_m3
    assert soil.load_bulk_volume_m3() / rated_m3 == pytest.approx(soil.fill_fraction, abs=0.05)
    env.reset(seed=0)


def test_unknown_fill_measure_fails_naming_the_option():
    with pytest.raises(ValueError, match="fill_measure"):
        gym.make("pilerl/PileLoading-v0", soil="particles", soil_options={"fill_measure": "kg"})


def test_contact_time_constant_is_an_option():
    env = make(soil_options={**COARSE, "contact_timeconst_s": 0.004})
    soil, model = env.unwrapped.soil, env.unwrapped.model
    first = model.body_geomadr[model.body("particle_0").id]
    np.testing.assert_allclose(model.geom_solref[first], [0.004, 1.0])
    assert soil.contact_timeconst_s == 0.004


@pytest.mark.parametrize("bad", [0.001, 0.5, float("nan"), True, "0.01"])
def test_impossible_contact_time_constant_fails_naming_the_option(bad):
    with pytest.raises(ValueError, match="contact_timeconst_s"):
        gym.make(
            "pilerl/PileLoading-v0", soil="particles", soil_options={"contact_timeconst_s": bad}
        )
