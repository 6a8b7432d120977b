"""The phenomena the paper rests on happen in the simulator.

Scoops are run by the scripted operator (tests/envs/scoops.py) at fixed seeds.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scoops import EARLY_BOOM, NO_BOOM, SENSIBLE, drive_in, peak, run_scoop
from sklearn.metrics import roc_auc_score

SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def summer_push():
    return [run_scoop(NO_BOOM, condition="summer", seed=s, max_seconds=8.0) for s in SEEDS]


@pytest.fixture(scope="module")
def ice_push():
    return [run_scoop(NO_BOOM, condition="winter_c", seed=s, max_seconds=8.0) for s in SEEDS]


def test_on_ice_drive_pressure_saturates_lower_than_in_summer(summer_push, ice_push):
    summer_peak = np.mean([peak(s.sensors["drive_pressure"]) for s in summer_push])
    ice_peak = np.mean([peak(s.sensors["drive_pressure"]) for s in ice_push])
    assert summer_peak > 22.0  # wheels grip: the HST reaches its relief pressure
    assert ice_peak < 0.65 * summer_peak  # wheels spin: pressure capped by traction


def test_on_ice_wheels_slip_while_pushing(summer_push, ice_push):
    assert ice_push[0].info["wheel_slip_m_s"] > 0.3
    assert abs(summer_push[0].info["wheel_slip_m_s"]) < ice_push[0].info["wheel_slip_m_s"]


def test_on_ice_telescope_pressure_still_rises_as_the_bucket_penetrates(ice_push):
    for scoop in ice_push:
        depth = np.array(scoop.depth_m)
        pt = np.array(scoop.sensors["telescope_pressure"])
        free = pt[depth == 0.0][:10].mean()  # driving, bucket outside the pile
        pushing = pt[depth > 0.1].mean()
        # ice caps the net push (four tyres' grip; drive-in p_t median 1.7 MPa in contact,
        # 0.5 without); the mean rise must stand well clear of the 0.1 MPa sensor noise
        assert pushing > free + 0.3  # MPa
        assert np.corrcoef(depth, pt)[0, 1] > 0.3  # noisy (wheels stick-slip) but rising


def test_sensible_strategy_fills_at_least_half_and_succeeds():
    for seed in SEEDS:
        scoop = run_scoop(SENSIBLE, condition="summer", seed=seed)
        assert scoop.info["scoop_finished"] and scoop.info["success"]
        assert scoop.info["fill_fraction"] >= 0.5


def test_raising_the_boom_too_early_gives_a_low_fill():
    for seed in SEEDS:
        scoop = run_scoop(EARLY_BOOM, condition="summer", seed=seed)
        assert scoop.info["fill_fraction"] < 0.2
        assert not scoop.info["success"]


def test_never_raising_the_boom_gives_a_low_fill(summer_push):
    for scoop in summer_push:
        assert scoop.info["fill_fraction"] < 0.5
        assert not scoop.info["success"]


def test_fill_grows_with_penetration_depth():
    depths, fills = [], []
    for throttle in (0.2, 0.45, 0.8):
        style = {"approach_throttle": throttle, "impact_rise_mpa": 1000.0}
        scoop = run_scoop(
            style, condition="summer", seed=0, max_seconds=6.0, start_distance_range_m=(1.0, 1.0)
        )
        depths.append(peak(scoop.depth_m))
        fills.append(scoop.info["fill_fraction"])
    assert depths == sorted(depths) and depths[-1] > depths[0] + 0.05
    assert fills == sorted(fills) and fills[-1] > fills[0] + 0.05


@pytest.mark.parametrize("condition", ["summer", "winter_c", "winter_d"])
def test_mass_is_conserved(condition):
    scoop = run_scoop(SENSIBLE, condition=condition, seed=4)
    assert max(scoop.fill) > 0.05  # material did move
    initial_kg = (
        scoop.info["pile_mass_kg"] + scoop.info["bucket_load_kg"] + scoop.info["spilled_kg"]
    )
    assert max(scoop.mass_error_kg) < 1e-6 * initial_kg


def test_reward_is_the_sum_of_its_named_parts():
    scoop = run_scoop(SENSIBLE, condition="summer", seed=0)
    np.testing.assert_allclose(scoop.rewards, scoop.reward_part_sums, rtol=1e-6, atol=1e-9)
    assert scoop.info["reward_success"] > 0  # the finishing step pays the success bonus


# ---- issue #15: what the pressures show (the drive-in of benchmarks/sensor_separability.py)
DRIVE_IN_SEEDS = tuple(range(6))
CONTACT_DEPTH_M = 0.05


@pytest.fixture(scope="module")
def drive_ins():
    return {
        condition: [drive_in(condition, seed=s) for s in DRIVE_IN_SEEDS]
        for condition in ("summer", "winter_c")
    }


def _contact_split(runs, sensor):
    depth = np.concatenate([r.depth_m for r in runs])
    reading = np.concatenate([r.sensors[sensor] for r in runs])
    return reading[depth > CONTACT_DEPTH_M], reading[depth == 0.0]


def test_on_ice_telescope_pressure_separates_contact_while_drive_pressure_is_capped(drive_ins):
    contact, free = _contact_split(drive_ins["winter_c"], "telescope_pressure")
    labels = np.r_[np.ones(len(contact)), np.zeros(len(free))]
    assert len(contact) > 100 and len(free) > 100
    assert roc_auc_score(labels, np.r_[contact, free]) >= 0.8
    ice_drive, _ = _contact_split(drive_ins["winter_c"], "drive_pressure")
    summer_drive, _ = _contact_split(drive_ins["summer"], "drive_pressure")
    # the wheels spin on ice: the loop pressure is capped by grip, not by the relief
    assert np.percentile(ice_drive, 90) < 0.65 * np.percentile(summer_drive, 90)


def test_on_ice_drive_pressure_is_not_a_saw_tooth():
    """Noiseless p_d while pushing on ice: its step-to-step (> ~4 Hz) part stays small."""
    for seed in (0, 1):
        run = drive_in("winter_c", seed=seed, sensor_noise=0.0, start_distance_range_m=(1, 1))
        pushing = run.sensors["drive_pressure"][run.depth_m > CONTACT_DEPTH_M]
        assert len(pushing) > 40
        smooth = np.convolve(pushing, np.ones(5) / 5, mode="valid")  # 0.25 s mean
        ripple = pushing[2:-2] - smooth
        # MPa; main's rigid tyre contacts chattered at 1.8 MPa here (2.6 at mu 0.2)
        assert np.std(ripple) < 0.5


def test_lifting_in_the_pile_raises_the_boom_pressure():
    """Breakout: raising the boom with the bucket buried takes more than raising it free,
    on ice too: the pile resists the lift whatever the tyres' grip."""
    lift = (0.7, 0.0, 0.0)
    rise_mpa = {}
    for condition in ("summer", "winter_c"):
        buried = drive_in(
            condition,
            seed=0,
            seconds=4.0,
            then=lift,
            then_after_s=3.0,
            start_distance_range_m=(1.0, 1.0),
        )
        free = drive_in(
            condition,
            seed=0,
            seconds=1.0,
            then=lift,
            then_after_s=0.0,
            start_distance_range_m=(5.0, 5.0),
        )
        assert buried.depth_m[59] > 0.1  # the bucket is in the pile when the lift starts
        lifting_buried = buried.sensors["boom_pressure"][62:70].mean()
        lifting_free = free.sensors["boom_pressure"][2:10].mean()
        assert lifting_buried > lifting_free + 3.0  # MPa
        rise_mpa[condition] = lifting_buried - lifting_free
    # the ice push is shallower (0.30 m against 0.45 m), yet breakout still loads the boom:
    # measured 13.6 of summer's 17.2 MPa (main, with 0.25 x the cutting force: 6 of 17)
    assert rise_mpa["winter_c"] > 0.5 * rise_mpa["summer"]


def test_the_tyres_carry_the_machine_at_rest_and_the_telescope_reads_tank_pressure():
    """Tyre springs hold the machine's weight (less the wheels' own); a lowered, empty
    telescope is pulled by gravity, which its piston-side sensor must not read as a push."""
    env = gym.make("pilerl/PileLoading-v0", sensor_noise=0.0).unwrapped
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(3))
    wheels_kg = 4 * 35.0
    weight_n = (env.machine_mass_kg - wheels_kg) * 9.81
    loads = env.machine.wheel_loads_n()
    assert abs(loads.sum() - weight_n) < 0.02 * weight_n
    assert loads[2] > 1.5 * loads[0]  # engine and counterweight on the rear axle
    tank = env.machine.params.tank_pressure_mpa
    assert obs["telescope_pressure"][0] == pytest.approx(tank, abs=1e-3)
    assert env.data.actuator_force[env.machine.telescope_actuator] < 0  # the rod side holds
    env.close()


def test_on_ice_the_drive_pressure_is_set_by_the_grip_of_all_four_tyres():
    """The front and rear motor of a side are in series (one speed) and the sides in
    parallel: on ice the loop pressure rises until all four tyres slide, so the motors'
    torque balances the grip of the whole machine plus the rolling resistance. (With the
    four motors in parallel the light front tyres spun first and p_d sat 20 % below.)"""
    env = gym.make("pilerl/PileLoading-v0", condition="winter_c", sensor_noise=0.0).unwrapped
    obs, info = env.reset(seed=0)
    params, ground, g = env.machine.params, env.condition.ground, 9.81
    loop_pa, grip_n = [], []
    while info["elapsed_s"] < 8.0 - 1e-9:
        obs, _, _, _, info = env.step(np.array([0.0, 0.0, 0.6], dtype=np.float32))
        if info["cutting_depth_m"] > 0.1 and info["wheel_slip_m_s"] > 0.3:  # spinning
            tyre_loads_n = env.machine.wheel_loads_n() + 35.0 * g  # plus the wheels' own
            loop_pa.append((obs["drive_pressure"][0] - params.drive_charge_pressure_mpa) * 1e6)
            grip_n.append(ground.tyre_friction * tyre_loads_n.sum())
    env.close()
    assert len(loop_pa) > 40
    rolling_n = ground.rolling_resistance * env.machine_mass_kg * g
    drive_m3_rad = 2 * params.motor_displacement_m3_rad  # two sides, one series pair each
    predicted_pa = (np.mean(grip_n) + rolling_n) * params.wheel_radius_m / drive_m3_rad
    assert abs(np.mean(loop_pa) - predicted_pa) < 0.1 * predicted_pa
