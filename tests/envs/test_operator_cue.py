"""The stall impact cue (``OperatorStyle.impact_cue="stall"``, the default since session 33:
"drive in until the machine stops pushing forward, then lift") against the earlier rise cue,
and pushing again once the boom is free (``OperatorStyle.push_again``, on by default); both
felt on the sensors only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pilerl_pile_loader.operator import IMPACT_CUES, OperatorStyle, make_expert, sample_style
from scoops import REST

DT = 0.05
# a granular face's impact (docs/soil_models.md, "Same actions on both soils"): p_d at the
# relief on one 20 Hz reading, then 13-22 MPa while the bucket goes on into the pile [MPa]
IMPACT_BURST = (12.8, 25.0, 16.9, 23.7, 19.2, 20.7, 21.6, 20.5, 22.7, 22.6)


def driving(**style: object):
    """A nominal operator rolling steadily at the pile (1 s at its driving pressure)."""
    operator = make_expert(dt=DT, **style)
    for _ in range(20):
        operator.act(REST)
    assert operator.phase == "approach"
    return operator


def decisions_until_filling(operator, drive_mpa: tuple[float, ...]) -> int | None:
    """Feed the drive pressures ``drive_mpa`` [MPa]; how many it took to feel the impact."""
    for count, drive in enumerate(drive_mpa, start=1):
        operator.act({**REST, "drive_pressure": drive})
        if operator.phase == "fill":
            return count
    return None


def test_the_stall_cue_and_pushing_again_are_the_default_and_a_cue_must_be_known():
    for style in (make_expert(dt=DT).style, OperatorStyle()):
        assert style.impact_cue == "stall" and style.push_again is True
    assert IMPACT_CUES == ("rise", "stall")
    with pytest.raises(ValueError, match="OperatorStyle.impact_cue: must be one of"):
        OperatorStyle(impact_cue="bump")
    with pytest.raises(ValueError, match="OperatorStyle.push_again: must be true or false"):
        make_expert(dt=DT, push_again="yes")
    # drawn operators: the same draws, with the cue and the second push as asked
    plain = sample_style(np.random.default_rng([0, 5]))
    assert (plain.impact_cue, plain.push_again) == ("stall", True)
    drawn = make_expert(
        dt=DT, rng=np.random.default_rng([0, 5]), impact_cue="rise", push_again="false"
    )
    assert drawn.style == dataclasses.replace(plain, impact_cue="rise", push_again=False)
    for rng in (None, np.random.default_rng(0)):
        with pytest.raises(ValueError, match="scripted expert: impact_cue must be one of"):
            make_expert(dt=DT, rng=rng, impact_cue="bump")


def test_the_stall_cue_is_not_a_granular_faces_impact_burst_but_the_push_at_its_relief():
    assert decisions_until_filling(driving(impact_cue="rise"), IMPACT_BURST) == 3
    stall = driving(impact_cue="stall")
    assert decisions_until_filling(stall, IMPACT_BURST) is None  # still driving in
    # the machine stops pushing forward: p_d at the relief, believed after impact_hold_s
    assert decisions_until_filling(stall, (25.0,) * 5) == 3


def test_on_ice_the_stall_cue_feels_the_wheels_spin_where_the_rise_cue_does_not():
    """p_d tops out flat at what the tyres hold (12.5 MPa on winter_c), short of the
    relief and, once the felt level has crept up, of the impact rise."""
    spinning = (REST["drive_pressure"] + 5.0,) * 12  # nominal rise 7 MPa: 0.6 s at +5
    assert decisions_until_filling(driving(impact_cue="rise"), spinning) is None
    count = decisions_until_filling(driving(impact_cue="stall"), spinning)
    assert count == 7  # flat over 0.3 s: seven 20 Hz readings


def test_on_ice_it_feels_the_stop_after_a_long_shaky_push_into_grains():
    """winter_c, particles, seed 1 (docs/soil_models.md, "A stall cue"): p_d shakes at 7-16
    MPa for 1.6 s, through which the felt level creeps up to ~8.4 MPa, then the machine
    stops at 11.5 MPa: flat, well up above what rolling took (4 MPa)."""
    shaky = (8.6, 6.9, 10.0, 6.9, 8.3, 8.9, 15.6, 8.0, 7.8, 8.8, 10.4, 11.6, 10.0, 10.2, 10.5)
    shaky = tuple(p for p in shaky for _ in range(2))  # 1.5 s at 20 Hz
    stopped = (11.2, 11.7, 11.5, 11.5, 11.5, 11.4, 11.3, 11.4, 11.5, 11.5)
    assert decisions_until_filling(driving(impact_cue="rise"), shaky + stopped) is None
    stall = driving(impact_cue="stall")
    assert decisions_until_filling(stall, shaky) is None
    assert decisions_until_filling(stall, stopped) == 7


def test_setting_off_is_not_felt_as_a_stop():
    """From rest (p_d at 2 MPa), the set-off surge (5.5 MPa) settles to the driving 4.6."""
    operator = make_expert(dt=DT, impact_cue="stall")
    set_off = (2.0, 5.0, 5.3, 5.6, 5.6, 5.4, 5.1, 4.8, 4.7) + (4.6,) * 30
    assert decisions_until_filling(operator, set_off) is None


def test_a_steadily_climbing_push_is_not_felt_as_a_stop():
    climbing = tuple(4.0 + 1.75 * k for k in range(12))  # to 23 MPa in 0.55 s
    assert decisions_until_filling(driving(impact_cue="stall"), climbing) is None


def test_with_a_telescope_trigger_the_stall_needs_the_rise_held_and_the_machine_stopped():
    """The bucket pushed back (p_t up by more than the nominal 0.75 MPa rise) while the
    machine still rolls is not the stall, nor is a 50 ms blip of p_t; p_t held up with the
    machine stopped (p_d flat, 5 MPa over what rolling took) is."""

    def until_filling(operator, readings: list[tuple[float, float]]) -> int | None:
        for count, (telescope, drive) in enumerate(readings, start=1):
            operator.act({**REST, "telescope_pressure": telescope, "drive_pressure": drive})
            if operator.phase == "fill":
                return count
        return None

    pushed_back = REST["telescope_pressure"] + 1.0
    rolling, stopped = REST["drive_pressure"], REST["drive_pressure"] + 5.0
    options = {"trigger_sensor": "telescope_pressure"}
    rise = {**options, "impact_cue": "rise"}
    assert until_filling(driving(**rise), [(pushed_back, rolling)] * 20) == 3
    stall = {**options, "impact_cue": "stall"}
    assert until_filling(driving(**stall), [(pushed_back, rolling)] * 20) is None
    free = REST["telescope_pressure"]
    blip = [(free, stopped)] * 6 + [(pushed_back, stopped)] + [(free, stopped)] * 13
    assert until_filling(driving(**stall), blip) is None  # a blip just as the stop is felt
    assert until_filling(driving(**stall), [(pushed_back, stopped)] * 20) == 7  # flat 0.3 s
    # pushed back first, stopped after a second of shaking (the rise has faded by then)
    shaky = [(pushed_back, rolling + (5.0 if k % 2 else 1.0)) for k in range(20)]
    assert until_filling(driving(**stall), shaky + [(free, stopped)] * 10) == 26  # 20th: 9
    # held at the drive's relief with p_t pushed back: after impact_hold_s; a granular
    # face's burst with p_t up is not the relief held
    assert until_filling(driving(**stall), [(pushed_back, 25.0)] * 10) == 3
    burst = [(pushed_back, drive) for drive in IMPACT_BURST]
    assert until_filling(driving(**stall), burst) is None


HELD = {**REST, "drive_pressure": 25.0, "boom_pressure": 20.0, "bucket_pressure": 20.0}
# the curl has turned the floor a step and the boom's pressure has fallen below its stall
FREE = {**HELD, "drive_pressure": 20.0, "boom_pressure": 12.0, "bucket_pressure": 5.0}
FREE["bucket_angle"] = REST["bucket_angle"] + 0.25


def curled_with_both_held(push_again: bool):
    """An operator (the stall cue) whose first curl ended with the boom and the bucket both
    at their reliefs: it has stopped crowding."""
    operator = driving(push_again=push_again)
    while operator.phase == "approach":
        command = operator.act(HELD)
    assert command[1] > 0 and command[2] == 0  # the boom at its relief: curl, foot off
    command = operator.act(HELD)  # the bucket at its relief too: stop crowding
    assert command[1] == 0 and command[2] == 0
    return operator


def throttles_while_lifting(
    operator, boom_from_rad: float, readings: list[dict], rate_rad: float = 0.005
) -> list:
    """The throttle over ``readings``, the boom ``boom_from_rad`` above rest and coming up
    ``rate_rad`` a decision (so it is never felt to stall)."""
    return [
        float(
            operator.act(
                {**reading, "boom_angle": REST["boom_angle"] + boom_from_rad + rate_rad * k}
            )[2]
        )
        for k, reading in enumerate(readings)
    ]


def test_with_push_again_it_crowds_again_once_the_boom_is_free():
    """Once the boom's pressure has stayed below its stall for 0.15 s (four 20 Hz readings,
    both ends) and the boom is still low, one who pushes again crowds the pile; the
    one who does not (``push_again=False``) lifts out without the throttle."""
    push = OperatorStyle().push_throttle
    assert throttles_while_lifting(curled_with_both_held(False), 0.0, [FREE] * 10) == [0.0] * 10
    assert throttles_while_lifting(curled_with_both_held(True), 0.0, [FREE] * 10) == (
        [0.0] * 3 + [pytest.approx(push)] * 7
    )


def test_push_again_waits_for_a_boom_felt_free_and_still_low():
    """A boom freed for single readings (pinned again at once) or risen past
    ``push_lift_rad`` (0.08 rad) is not crowded again: no throttle flicker."""
    flicker = [FREE, HELD] * 10
    assert throttles_while_lifting(curled_with_both_held(True), 0.0, flicker) == [0.0] * 20
    assert throttles_while_lifting(curled_with_both_held(True), 0.1, [FREE] * 10) == [0.0] * 10


def test_push_again_pushes_a_pinned_boom_again_only_once_it_has_come_up_a_step():
    """Every push pins the boom (a curl that ends with the boom and the bucket held, then
    free again): the next push waits until the boom has come up 0.03 rad since the last
    one (here 0.004 rad a decision), not every 0.3 s."""
    pinned = ([FREE] * 4 + [HELD] * 2) * 4  # pushed on the 4th free reading, then pinned
    throttles = throttles_while_lifting(curled_with_both_held(True), 0.0, pinned, 0.004)
    pushes = [k for k, throttle in enumerate(throttles) if throttle > 0]
    # at 0.012 rad; at 0.036 (decision 9) not yet; at 0.060; at 0.084 past push_lift_rad
    assert pushes == [3, 15]
