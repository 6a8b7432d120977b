"""The pile loader's expert works one control at a time where people do: it takes its foot
off the gas while curling, backs off before raising, and goes again after a light scoop."""

from __future__ import annotations

import pytest
from pilerl_pile_loader.operator import make_expert
from scoops import REST

DT = 0.05
IMPACT = {**REST, "drive_pressure": 25.0, "boom_pressure": 20.0}  # boom at its relief


def into_the_pile(**options: object):
    """A nominal operator that has felt the impact and curls against a stalled boom."""
    operator = make_expert(dt=DT, **options)
    operator.act(REST)
    commands = [operator.act(IMPACT) for _ in range(8)]
    assert operator.phase == "fill" and commands[-1][1] > 0  # curling
    return operator, commands[-1]


def steady_back_off(operator, reading: dict, steps: int = 30) -> list:
    """Roll back: the pump reverses, the drive pressure surges, then settles."""
    commands = []
    for step in range(steps):
        surge = max(0.0, 6.0 - step)  # the set-off surge dies away
        rolling = {**reading, "pump_angle": -0.05, "drive_pressure": 3.5 + surge}
        commands.append(operator.act(rolling))
    return commands


def test_it_takes_its_foot_off_the_gas_while_curling():
    _, curling = into_the_pile()
    assert curling[0] == 0 and curling[2] == 0  # the bucket alone
    _, curling = into_the_pile(push_while_curling=True)
    assert curling[2] > 0  # this operator keeps crowding while it curls


def test_it_backs_off_until_the_machine_rolls_back_steadily_then_raises():
    operator, _ = into_the_pile()
    curled = {**IMPACT, "bucket_angle": 1.25}  # curled back: the scoop is filled
    assert operator.act(curled).tolist() == pytest.approx([0.0, 0.0, -0.3])  # backs off at once
    assert operator.phase == "finish"
    commands = steady_back_off(operator, {**curled, "boom_pressure": 10.0})
    backing = [c for c in commands if c[2] < 0]
    assert len(backing) >= 11  # through the surge, and 0.5 s of steady rolling
    assert all(c[0] == 0 and c[1] == 0 for c in backing)  # the throttle alone
    assert commands[-1][0] > 0 and commands[-1][2] == 0  # then raises, standing
    raising = make_expert(dt=DT, back_off_throttle=0.0)
    raising.act(REST)
    for _ in range(8):
        raising.act(IMPACT)
    assert raising.act(curled)[0] > 0  # without a back-off: raises in the pile


def test_after_a_light_scoop_it_backs_off_and_goes_again():
    operator, _ = into_the_pile()
    light = {**IMPACT, "boom_angle": REST["boom_angle"] + 0.31, "bucket_angle": 0.6}
    operator.act(light)  # the boom came up out of the pile before the bucket was curled
    assert operator.phase == "finish"
    commands = steady_back_off(operator, {**light, "boom_pressure": 5.0})
    assert commands[0].tolist() == pytest.approx([0.0, 0.0, -0.3])
    assert operator.phase == "approach"  # going again
    lowering = operator.act({**light, "pump_angle": 0.0, "drive_pressure": 3.5})
    assert lowering[0] < 0 and lowering[1] == 0 and lowering[2] == 0  # boom first, standing
    lowered = {**REST, "bucket_angle": 0.6}
    levelling = operator.act(lowered)
    assert levelling[0] == 0 and levelling[1] < 0 and levelling[2] == 0  # then the bucket
    driving = operator.act(REST)
    assert driving[0] == 0 and driving[1] == 0 and driving[2] > 0  # then drives at the pile
    stays = make_expert(dt=DT, go_again=False)
    stays.act(REST)
    for _ in range(8):
        stays.act(IMPACT)
    assert stays.act(light)[1] > 0  # an operator who does not go again curls back
