"""Crowd fill (``OperatorStyle.crowd_fill``, off by default): the expert keeps pushing
while the boom rises through the face, so the bucket mouth keeps passing through material;
every change is felt on the sensors."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.operator import make_expert, sample_style
from scoops import REST

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)

DT = 0.05
# in the face: the push heavy, the bucket pushed back (p_t well above its free 0.8 MPa)
IN_FACE = {**REST, "drive_pressure": 18.0, "telescope_pressure": 4.0, "boom_pressure": 12.0}


def crowding(**options: object):
    """A nominal crowding operator that has felt the impact and crowds the face."""
    operator = make_expert(dt=DT, crowd_fill=True, **options)
    operator.act(REST)
    impact = {**IN_FACE, "drive_pressure": 25.0}
    for _ in range(6):
        command = operator.act(impact)
    assert operator.phase == "fill"
    return operator, command


def risen(reading: dict, rad: float) -> dict:
    """``reading`` with the boom ``rad`` above rest and the bucket floor curled as far as
    that rise calls for (``curl_per_lift`` 1.8: no curl is due)."""
    return {**reading, "boom_angle": REST["boom_angle"] + rad, "bucket_angle": 0.45 + 0.8 * rad}


def test_off_by_default_and_drawn_operators_are_the_same_but_for_it():
    assert make_expert(dt=DT).style.crowd_fill is False
    plain = sample_style(np.random.default_rng([0, 5]))
    crowd = sample_style(np.random.default_rng([0, 5]), crowd_fill=True)
    assert crowd == dataclasses.replace(plain, crowd_fill=True)
    drawn = make_expert(dt=DT, rng=np.random.default_rng([0, 5]), crowd_fill="true")
    assert drawn.style == crowd
    with pytest.raises(ValueError, match="crowd_fill"):
        make_expert(dt=DT, rng=np.random.default_rng(0), crowd_fill="sometimes")


def test_it_lifts_and_pushes_together_while_the_boom_rises_through_the_face():
    operator, command = crowding()
    assert command[0] > 0 and command[1] == 0 and command[2] > 0
    # past the nominal operator's push_lift_rad (0.08): still crowding the face
    for rad in (0.1, 0.15, 0.2):
        command = operator.act(risen(IN_FACE, rad))
        assert command[0] > 0 and command[2] == pytest.approx(operator.style.push_throttle)
    nominal = make_expert(dt=DT)
    nominal.act(REST)
    for _ in range(3):
        nominal.act({**IN_FACE, "drive_pressure": 25.0})
    assert nominal.act(risen(IN_FACE, 0.2))[2] == 0  # the nominal one stopped pushing


def test_out_of_the_face_it_holds_the_boom_and_crowds_back_in_unless_it_rolls_freely():
    operator, _ = crowding()
    out = risen({**IN_FACE, "telescope_pressure": 0.8, "boom_pressure": 6.0}, 0.1)
    commands = []
    for step in range(20):  # the push relaxes, then the machine rolls on steadily
        commands.append(operator.act({**out, "drive_pressure": max(5.0, 15.0 - 2.0 * step)}))
    assert commands[0].tolist() == [0.0, 0.0, pytest.approx(operator.style.push_throttle)]
    assert commands[-1][0] > 0 and commands[-1][2] > 0  # nothing to bite: lifts on
    assert operator.act(risen(IN_FACE, 0.1))[0] > 0  # in the face again: lifts and pushes


def pinned_by_the_push(operator, reading: dict, decisions: int = 8) -> np.ndarray:
    """Feed ``reading`` (the boom not rising) for ``decisions`` decisions; the last command."""
    for _ in range(decisions):
        command = operator.act(reading)
    return command


def test_a_boom_that_does_not_rise_while_crowding_is_freed_with_the_foot_off():
    """Felt on the boom angle alone (0.01 rad in 0.3 s), not on the boom pressure."""
    operator, _ = crowding()
    # the boom pressure at its relief does not matter while the boom rises
    for rad in (0.05, 0.07, 0.09, 0.11, 0.13, 0.15, 0.17, 0.19):
        command = operator.act(risen({**IN_FACE, "drive_pressure": 25.0, "boom_pressure": 20}, rad))
    assert command[0] > 0 and command[2] > 0  # still crowding
    # the boom stops rising at a low boom pressure: pinned by the push, felt
    stuck = risen({**IN_FACE, "drive_pressure": 25.0, "boom_pressure": 12.0}, 0.2)
    commands = [operator.act(stuck) for _ in range(8)]
    assert commands[0][2] > 0  # not at once: a person feels it within 0.3 s
    assert commands[-1].tolist() == [pytest.approx(operator.style.lift), 0.0, 0.0]  # foot off
    command = operator.act(risen(stuck, 0.24))  # the boom came up a step
    assert command[0] > 0 and command[2] > 0  # crowding again


def test_it_breaks_out_only_once_the_push_has_relaxed():
    """Foot off and lifting, the boom held down: the operator waits for the machine to stop
    pushing (the drive pressure below half its peak) before it curls a step."""
    operator, _ = crowding()
    stuck = risen({**IN_FACE, "drive_pressure": 25.0}, 0.05)
    pinned_by_the_push(operator, stuck)  # felt pinned: foot off
    command = pinned_by_the_push(operator, stuck, 10)  # the push has not relaxed
    assert command[0] > 0 and command[1] == 0 and command[2] == 0  # lifts on, foot off
    relaxed = {**stuck, "drive_pressure": 11.0, "telescope_pressure": 1.5}  # p_t falls with it
    command = pinned_by_the_push(operator, relaxed, 1)
    assert command[0] == 0 and command[1] > 0  # the boom does not come up: breaks out


def break_out(operator) -> dict:
    """Pin the crowding ``operator``'s boom, relax the push, and let it start a break-out
    curl; the relaxed reading."""
    stuck = risen({**IN_FACE, "drive_pressure": 25.0}, 0.05)
    pinned_by_the_push(operator, stuck)
    pinned_by_the_push(operator, stuck, 10)
    return {**stuck, "drive_pressure": 11.0, "telescope_pressure": 1.5}  # p_t falls with it


def test_breaking_out_it_pushes_only_while_the_boom_holds_its_angle():
    """During a break-out curl the boom valve is shut: a boom pressed down through its
    relief sags, and the foot stays off; once it holds its angle for 0.3 s, it pushes."""
    operator, _ = crowding()
    relaxed = break_out(operator)
    boom, bucket = relaxed["boom_angle"], relaxed["bucket_angle"]
    sag = [  # the bucket turns, the boom sags (0.015 rad in each 0.3 s window), 0.6 s long
        operator.act(
            {**relaxed, "boom_angle": boom - 0.0025 * k, "bucket_angle": bucket + 0.012 * k}
        )
        for k in range(1, 13)
    ]
    assert all(c[1] > 0 and c[2] == 0 for c in sag)  # curling, foot off: the boom sags
    held = {"boom_angle": boom - 0.03, "bucket_angle": bucket + 0.144}
    commands = [  # the bucket turns on, the boom holds its angle
        operator.act({**relaxed, **held, "bucket_angle": held["bucket_angle"] + 0.005 * k})
        for k in range(1, 9)
    ]
    assert commands[0][2] == 0  # not at once: the hold is felt over 0.3 s
    assert commands[-1][1] > 0  # still curling (the floor has not turned a step)
    assert commands[-1][2] == pytest.approx(operator.style.push_throttle)  # pushes


def test_a_boom_that_holds_from_the_start_of_the_break_out_is_pushed_once_felt():
    operator, _ = crowding()
    relaxed = break_out(operator)
    commands = [
        operator.act({**relaxed, "bucket_angle": relaxed["bucket_angle"] + 0.01 * k})
        for k in range(1, 9)
    ]
    assert all(c[1] > 0 for c in commands)  # curling throughout
    assert commands[-1][2] == pytest.approx(operator.style.push_throttle)


def test_a_push_that_never_rose_far_is_relaxed_at_the_charge_pressure():
    """A new crowd whose boom stalls before the drive pressure has risen: its peak is low,
    so half of it lies below the charge pressure the loop never reads under; the push is
    felt relaxed at the charge pressure, and the held-down boom is broken out."""
    operator, _ = crowding()
    stuck = risen({**IN_FACE, "drive_pressure": 25.0}, 0.05)
    pinned_by_the_push(operator, stuck)  # foot off: freeing the boom
    # the boom came up a step, the foot off the push relaxed: crowding again from 3 MPa
    operator.act(risen({**stuck, "drive_pressure": 3.0}, 0.09))
    low = risen({**IN_FACE, "drive_pressure": 3.5}, 0.09)  # the new push barely rose
    pinned_by_the_push(operator, low)  # pinned again: foot off
    command = pinned_by_the_push(operator, {**low, "drive_pressure": 2.5}, 8)
    assert command[0] == 0 and command[1] > 0  # breaks out, not stuck lifting until 30 s


def test_a_curl_step_ends_when_the_bucket_stops_turning_then_the_boom_comes_up_a_step():
    """The bucket stall is felt on the bucket angle (0.01 rad in 0.3 s), not on the
    bucket pressure; after the curl, the boom is lifted a step with the foot off."""
    operator, _ = crowding()
    stuck = risen({**IN_FACE, "drive_pressure": 25.0}, 0.05)
    pinned_by_the_push(operator, stuck)
    pinned_by_the_push(operator, stuck, 10)
    curling = {**stuck, "drive_pressure": 11.0, "telescope_pressure": 1.5, "bucket_pressure": 30.0}
    assert operator.act(curling)[1] > 0  # a bucket pressure over its relief does not stop it
    turning = [
        operator.act({**curling, "bucket_angle": curling["bucket_angle"] + 0.02 * k})
        for k in range(1, 5)
    ]
    assert all(c[1] > 0 for c in turning)
    stalled = {**curling, "bucket_angle": curling["bucket_angle"] + 0.08}
    commands = [operator.act(stalled) for _ in range(8)]
    assert commands[-1].tolist() == [pytest.approx(operator.style.lift), 0.0, 0.0]


def test_when_the_wheels_slip_it_eases_off_and_fills_with_the_wrist():
    operator, _ = crowding()
    operator.act(risen({**IN_FACE, "drive_pressure": 24.0}, 0.05))
    slipping = risen({**IN_FACE, "drive_pressure": 8.0}, 0.06)  # the push collapses ...
    command = operator.act(slipping)  # ... while the pile still holds the bucket
    assert command[0] > 0 and command[1] > 0
    assert command[2] == pytest.approx(operator.style.ease_throttle)
    # on ice the push tops out flat, short of the drive's relief: the same
    capped, _ = crowding()
    for k in range(8):  # the boom rising slowly while the wheels spin
        command = capped.act(risen({**IN_FACE, "drive_pressure": 13.0}, 0.05 + 0.01 * k))
    assert command[1] > 0 and command[2] == pytest.approx(capped.style.ease_throttle)


def test_the_scoop_is_light_only_if_the_bucket_never_bit_into_the_face():
    operator, _ = crowding()
    operator.act(risen(IN_FACE, 0.31))  # came up through the face, floor not curled back
    assert operator.phase == "finish"
    assert operator.act(risen(IN_FACE, 0.31))[1] > 0  # curls back: a loaded scoop
    jumpy = make_expert(dt=DT, crowd_fill=True, jumpy=True, impact_hold_s=0.0)
    jumpy.act(REST)
    surge = {**REST, "drive_pressure": 9.0}  # the set-off surge, far from the pile
    jumpy.act(surge)
    assert jumpy.phase == "fill"
    jumpy.act(risen(surge, 0.31))
    assert jumpy.phase == "finish" and jumpy.act(risen(surge, 0.31))[2] < 0  # backs off ...
    assert jumpy._light  # ... to go again


def test_on_the_mouth_intake_it_fills_a_summer_scoop_the_nominal_expert_does_not():
    env = gym.make("pilerl/PileLoading-v0", sensor_noise=0.0, soil_options={"intake": "mouth"})
    fills = {}
    for crowd in (False, True):
        operator = make_expert(dt=float(env.unwrapped.dt), crowd_fill=crowd)
        obs, _ = env.reset(seed=0)
        while True:
            obs, _, terminated, truncated, info = env.step(operator.act(obs))
            if terminated or truncated:
                break
        fills[crowd] = (info["fill_fraction"], info["success"])
    env.close()
    assert not fills[False][1] and fills[False][0] < 0.5  # 0.48 when written
    assert fills[True][1] and fills[True][0] >= fills[False][0] + 0.03  # 0.54


def test_driving_it_feels_the_machine_stop_with_its_wheels_spinning():
    """On ice the drive pressure tops out at what the tyres hold, short of the impact
    rise: a crowding operator feels the machine stopped (the pressure well up and flat),
    as the default stall cue does; one who waits for the rise (``impact_cue="rise"``) not."""
    spinning = {**REST, "drive_pressure": REST["drive_pressure"] + 5.0}  # nominal rise: 7
    phases = {}
    for crowd in (False, True):
        operator = make_expert(dt=DT, crowd_fill=crowd, impact_cue="rise")
        for _ in range(20):
            operator.act(REST)
        for _ in range(12):  # 0.6 s against the pile
            operator.act(spinning)
        phases[crowd] = operator.phase
    assert phases == {False: "approach", True: "fill"}


@pytest.mark.parametrize("value", ["false", "no", 1])
def test_a_crowd_fill_that_is_not_true_or_false_fails_naming_the_field(value):
    # a string from a command line ("no") would be truthy: the style refuses it
    with pytest.raises(ValueError, match="OperatorStyle.crowd_fill: must be true or false"):
        make_expert(dt=0.05, crowd_fill=value)
