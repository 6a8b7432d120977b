"""PileLoading-v0: API contracts, determinism, bad input and rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pilerl_pile_loader.sensors import SENSOR_NAMES
from torchrl.envs.utils import check_env_specs

import pilerl  # noqa: F401
from pilerl.sim import make_torchrl_env


def make(**kwargs):
    return gym.make("pilerl/PileLoading-v0", **kwargs)


def test_passes_gymnasium_check_env():
    check_env(make(condition="summer").unwrapped)


def test_passes_torchrl_check_env_specs_with_named_sensor_keys():
    env = make_torchrl_env(condition="winter_b", seed=0)
    check_env_specs(env)
    rollout = env.rollout(5)
    for name in SENSOR_NAMES:
        assert rollout[name].shape == (5, 1)
    assert rollout["action"].shape == (5, 3)


def test_observation_has_all_seven_named_sensors_in_range():
    env = make()
    obs, _ = env.reset(seed=0)
    assert tuple(obs) == SENSOR_NAMES
    assert env.observation_space.contains(obs)


@pytest.mark.parametrize(("control_hz", "dt"), [(20.0, 0.05), (3.0, 0.334)])
def test_dt_is_the_control_period(control_hz, dt):
    env = make(control_hz=control_hz)
    assert env.unwrapped.dt == pytest.approx(dt)
    assert env.unwrapped.model.opt.timestep == pytest.approx(0.002)  # 500 Hz physics
    env.reset(seed=0)
    *_, info = env.step(np.zeros(3, np.float32))
    assert info["elapsed_s"] == pytest.approx(dt)


def rollout(seed, steps=40, **kwargs):
    env = make(**kwargs)
    obs, info = env.reset(seed=seed)
    trace = [np.concatenate(list(obs.values()))]
    for t in range(steps):
        obs, *_ = env.step(np.array([0.2 * np.sin(t / 5), 0.1, 0.6], np.float32))
        trace.append(np.concatenate(list(obs.values())))
    return info, np.array(trace)


def test_same_seed_gives_identical_trajectory():
    info_a, trace_a = rollout(seed=7)
    info_b, trace_b = rollout(seed=7)
    assert info_a["start_distance_m"] == info_b["start_distance_m"]
    np.testing.assert_array_equal(trace_a, trace_b)


def test_different_seeds_give_different_start_poses():
    starts = {round(rollout(seed=s, steps=0)[0]["start_distance_m"], 6) for s in range(4)}
    angles = {round(rollout(seed=s, steps=0)[0]["approach_angle_rad"], 6) for s in range(4)}
    assert len(starts) == 4 and len(angles) == 4
    for s in range(4):
        info, _ = rollout(seed=s, steps=0)
        assert 1.0 <= info["start_distance_m"] <= 5.0
        assert abs(np.degrees(info["approach_angle_rad"])) <= 10.0


def test_start_distance_is_the_gap_between_cutting_edge_and_pile_toe():
    env = make(start_distance_range_m=(2.0, 2.0), approach_angle_range_deg=(0.0, 0.0))
    env.reset(seed=0)
    u = env.unwrapped
    edge_x = u.data.site_xpos[u.machine.cutting_edge_site][0]
    assert u.soil.pile.toe_x_m - edge_x == pytest.approx(2.0, abs=0.02)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"condition": "spring"}, "unknown condition 'spring'"),
        ({"soil": "sand"}, "unknown soil model 'sand'"),
        ({"soil_options": {"max_particles": 50}}, r"'heightfield' has no option\(s\)"),
        ({"soil": "particles", "soil_options": {"grain": 1}}, r"its options: \['max_particles'"),
        ({"soil": "particles", "soil_options": {"max_particles": 3}}, "max_particles"),
        ({"condition_overrides": {"material": {"density_kg_m3": -1.0}}}, "density_kg_m3"),
        ({"physics_hz": 100.0}, "physics_hz"),
        ({"control_hz": 0.0}, "control_hz"),
        ({"start_distance_range_m": (5.0, 1.0)}, "start_distance_range_m"),
        ({"sensor_noise": -1.0}, "sensor_noise"),
        ({"sensor_noise": {"drive_pressure": float("nan")}}, "sensor_noise"),
        ({"sensor_noise": {"speedometer": 0.1}}, r"unknown sensor\(s\) \['speedometer'\]"),
        ({"render_mode": "depth_array"}, "render_mode"),
    ],
)
def test_bad_configuration_fails_with_a_clear_message(kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.array([np.nan, 0.0, 0.0]), r"non-finite values in \['boom'\]"),
        (np.array([0.0, 0.0, np.inf]), r"non-finite values in \['throttle'\]"),
        (np.zeros(2), r"shape \(3,\)"),
        (np.zeros((1, 3)), r"shape \(3,\)"),
    ],
)
def test_bad_actions_raise_and_leave_the_state_untouched(action, message):
    env = make().unwrapped
    env.reset(seed=0)
    qpos = env.data.qpos.copy()
    with pytest.raises(ValueError, match=message):
        env.step(action)
    np.testing.assert_array_equal(env.data.qpos, qpos)
    assert np.isfinite(env.data.qpos).all()


def test_out_of_range_actions_are_clipped():
    env_a, env_b = make().unwrapped, make().unwrapped
    env_a.reset(seed=1)
    env_b.reset(seed=1)
    obs_a, *_ = env_a.step(np.array([5.0, -5.0, 3.0]))
    obs_b, *_ = env_b.step(np.array([1.0, -1.0, 1.0]))
    for name in obs_a:
        np.testing.assert_array_equal(obs_a[name], obs_b[name])


def test_rgb_array_render_shows_a_scene():
    env = make(render_mode="rgb_array", render_size=(120, 160))
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # not a blank image
    env.close()


def test_noise_is_configurable_per_sensor():
    env = make(sensor_noise={"drive_pressure": 0.0, "telescope_pressure": 2.0}).unwrapped
    env.reset(seed=0)
    readings = [env.step(np.zeros(3))[0] for _ in range(30)]
    drive = np.array([r["drive_pressure"][0] for r in readings])
    telescope = np.array([r["telescope_pressure"][0] for r in readings])
    boom = np.array([r["boom_angle"][0] for r in readings])
    assert np.abs(np.diff(drive)).max() < 0.05  # noiseless and standing still
    assert telescope.std() > 1.0  # 2 MPa noise
    assert 0.0005 < boom.std() < 0.01  # default 0.002 rad noise kept
