"""Held-out condition presets: documented with their numbers, settable, and they run."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pilerl_pile_loader.conditions import CONDITIONS, HELD_OUT, get_condition

from pilerl.evaluation.evaluator import EvaluationPlan, ScriptedController, evaluate
from pilerl.sim import get_simulator, make_gym_env

ENV_CARD = Path(__file__).parents[2] / "docs" / "env_card.md"


def test_held_out_presets_are_a_group_apart_from_the_papers():
    assert len(HELD_OUT) >= 3 and not set(HELD_OUT) & set(CONDITIONS)
    plugin = get_simulator("pile_loader")
    assert plugin.condition_groups["held_out"] == tuple(HELD_OUT)
    assert plugin.resolve_conditions(["held_out"], where="test") == tuple(HELD_OUT)
    assert not set(HELD_OUT) & set(plugin.resolve_conditions(["all"], where="test"))
    for name in HELD_OUT:
        assert get_condition(name).name == name


@pytest.mark.parametrize("name", sorted(HELD_OUT))
def test_the_env_card_lists_each_held_out_preset_with_its_numbers(name):
    row = next(
        line for line in ENV_CARD.read_text().splitlines() if line.startswith(f"| `{name}` |")
    )
    cells = [c.strip() for c in row.strip("|").split("|")]
    density, phi, cohesion_kpa, delta, mu, rolling = (float(c) for c in cells[2:8])
    c = get_condition(name)
    assert density == c.material.density_kg_m3 and phi == c.material.friction_angle_deg
    assert cohesion_kpa * 1000 == c.material.cohesion_pa
    assert delta == c.material.tool_friction_angle_deg
    assert (mu, rolling) == (c.ground.tyre_friction, c.ground.rolling_resistance)
    lags = re.findall(r"[\d.]+", cells[9])
    assert [float(x) for x in lags] == [c.hydraulics.valve_lag_s, c.hydraulics.pump_lag_s]


def test_condition_overrides_reach_a_held_out_preset():
    env = make_gym_env(
        "pile_loader",
        condition="frozen_crust",
        condition_overrides={"material": {"cohesion_pa": 5000.0}},
    ).unwrapped
    assert env.condition.name == "frozen_crust" and env.condition.material.cohesion_pa == 5000.0
    assert env.condition.ground == get_condition("frozen_crust").ground
    env.close()


def test_the_nominal_expert_runs_in_every_held_out_condition():
    plan = EvaluationPlan("pile_loader", {}, ("summer", *HELD_OUT), episodes=1, seed=1)
    rows = evaluate(ScriptedController(), plan, workers=1, progress=False)
    assert [r["condition"] for r in rows] == ["summer", *HELD_OUT]
    fills = {r["condition"]: r["fill_fraction"] for r in rows}
    assert all(0.0 <= fill < 1.5 for fill in fills.values()), fills
    assert len({r["seed"] for r in rows}) == 1  # the same seeded start everywhere
    # the crust's cohesion stops the bucket where dry gravel fills it
    assert fills["frozen_crust"] < 0.5 <= fills["summer"]
