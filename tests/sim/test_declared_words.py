"""The evaluation words a simulator declares: failure modes and the rule naming them, the
``info`` it reports, its default curriculum and example conditions; a minimal plugin gets
defaults that work, a malformed declaration fails naming the field."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from pilerl.config import register_configs
from pilerl.evaluation.evaluator import EvaluationPlan, evaluate, summarize
from pilerl.evaluation.settings import ScoopConfig
from pilerl.operators import OperatorModule
from pilerl.rl.config import resolve_simulator_words
from pilerl.sim import SimulatorPlugin, get_simulator, registry
from pilerl.sim.settings import EnvConfig

CONF = Path(__file__).resolve().parents[2] / "conf"
MINIMAL = {
    "name": "minimal",
    "gym_id": "test/Minimal-v0",
    "entry_point": "pilerl_toy_cart.env:ToyCartEnv",
    "sensors": {"position": {"unit": "m", "low": -10.0, "high": 10.0}},
    "controls": ["force"],
    "conditions": {"nominal": "", "heavy": ""},
    "options": "pilerl_toy_cart.options:ToyCartOptions",
}


def bogus_columns(*, info, sensors, controls, success) -> dict:
    """An episode rule naming a failure mode its simulator does not declare."""
    return {"failure_mode": "success" if success else "bogus"}


def test_a_minimal_declaration_gets_defaults_that_work():
    plugin = SimulatorPlugin.from_declaration(MINIMAL, where="test")
    assert plugin.failure_modes == ("failed",) and plugin.episode_info == {}
    assert plugin.resolve_mixture(plugin.curriculum, where="test") == {"nominal": 1.0, "heavy": 1.0}
    assert plugin.example_conditions == ("nominal",) and plugin.report_notes == ()
    declared = SimulatorPlugin.from_declaration(
        {**MINIMAL, "episode_info": {"error_m": "m", "stopped": "bool"}}, where="test"
    )
    columns = declared.episode_outcome(
        info={"error_m": np.array([1.0, 0.5, 0.2]), "stopped": np.array([0.0, 0.0, 1.0])},
        sensors={},
        controls={},
        success=False,
    )
    assert columns == {"error_m": 0.2, "stopped": True, "failure_mode": "failed"}
    assert declared.summary_numbers([columns]) == {}


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("failure_modes", ["success"], "failure_modes"),
        ("failure_modes", [], "failure_modes"),
        ("curriculum", {"spring": 1.0}, "unknown condition 'spring'"),
        ("curriculum", {"nominal": 0.0}, "curriculum: weights"),
        ("episode_info", {"success": "bool"}, "episode_info"),
        ("example_conditions", ["spring"], "example_conditions"),
        ("episode_columns", "not a reference", "episode_columns"),
        ("report_notes", "one line", "report_notes"),
        ("expert_revision", -1, "expert_revision: expected an integer >= 0"),
        ("expert_revision", "2", "expert_revision: expected an integer >= 0"),
        ("expert_revision", True, "expert_revision: expected an integer >= 0"),
    ],
)
def test_a_malformed_evaluation_word_fails_naming_the_field(field, value, message):
    with pytest.raises(ValueError, match=message):
        SimulatorPlugin.from_declaration({**MINIMAL, field: value}, where="test")


def test_a_rule_naming_an_undeclared_failure_mode_fails_naming_the_simulator():
    plugin = SimulatorPlugin.from_declaration(
        {**MINIMAL, "episode_columns": f"{__name__}:bogus_columns"}, where="test"
    )
    with pytest.raises(ValueError, match=r"'minimal'.*'bogus'.*\['failed'\]"):
        plugin.episode_outcome(info={}, sensors={}, controls={}, success=False)


@dataclass(frozen=True)
class ConstantPush:
    """Pushes the toy cart with one constant force fraction."""

    force: float
    name: str = "push"

    def policy(self, env):
        return OperatorModule.for_env([_Push(self.force) for _ in env.simulators], env)


class _Push:
    def __init__(self, force: float) -> None:
        self.force = force

    def reset(self) -> None:
        pass

    def act(self, observation) -> np.ndarray:
        return np.array([self.force], np.float32)


def test_the_toy_carts_failure_modes_appear_in_its_evaluation_summary():
    plugin = get_simulator("toy_cart")
    assert plugin.failure_modes == ("overshot", "fell_short")
    plan = EvaluationPlan("toy_cart", {}, ("nominal",), episodes=2, seed=0)
    records = [
        *evaluate(ConstantPush(1.0, "full"), plan, workers=1, progress=False),
        *evaluate(ConstantPush(0.0, "idle"), plan, workers=1, progress=False),
    ]
    assert [r["failure_mode"] for r in records] == ["overshot"] * 2 + ["fell_short"] * 2
    assert all(r["farthest_m"] > 1.05 for r in records[:2])
    assert all(r["error_m"] > 0.05 for r in records)
    summary = summarize(records, simulator="toy_cart")["nominal"]
    assert summary["failure_modes"] == {"overshot": 2, "fell_short": 2}


def compose_finetune(*overrides: str):
    register_configs()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(
            config_name="finetune",
            overrides=["output_dir=/x", "checkpoint=/x/best.pt", *overrides],
        )
    return resolve_simulator_words(OmegaConf.to_object(cfg))


def test_the_default_curriculum_is_the_simulators_declared_mixture():
    toy = compose_finetune("env=toy_cart")
    assert toy.curriculum.name == "default"
    assert [s.conditions for s in toy.curriculum.stages] == [
        {"nominal": 1.0, "heavy": 1.0, "headwind": 1.0}
    ]
    # the pile loader's declared mixture draws as winter_mix did: same conditions, order
    # and weights
    default = compose_finetune().curriculum.stages
    winter_mix = compose_finetune("curriculum=winter_mix").curriculum.stages
    assert [(s.frames, list(s.conditions.items())) for s in default] == [
        (s.frames, list(s.conditions.items())) for s in winter_mix
    ]


def test_scoop_shows_the_simulators_example_conditions_by_default():
    pile_loader = ScoopConfig(env=EnvConfig(), output_dir="/x")
    assert pile_loader.conditions == ["summer", "winter_c"]
    toy = ScoopConfig(env=EnvConfig(simulator="toy_cart"), output_dir="/x")
    assert toy.conditions == ["nominal"]
    with pytest.raises(ValueError, match="conditions"):
        ScoopConfig(env=EnvConfig(), conditions=[], output_dir="/x")


def test_a_simulator_without_episode_rules_is_evaluated_with_the_defaults(monkeypatch):
    """The toy cart declared bare (no rule, no failure modes): its records carry the last
    value of each declared ``info`` entry, and every failure is ``failed``."""
    toy = get_simulator("toy_cart")
    bare = SimulatorPlugin.from_declaration(
        {
            "name": "bare_cart",
            "gym_id": toy.gym_id,  # the toy cart's env, already registered
            "entry_point": toy.entry_point,
            "sensors": {n: vars(s) for n, s in toy.sensors.items()},
            "controls": list(toy.controls),
            "conditions": dict(toy.conditions),
            "options": toy.options,
            "episode_info": {"error_m": "m"},
        },
        where="test",
    )
    monkeypatch.setitem(registry._plugins(), "bare_cart", bare)
    plan = EvaluationPlan("bare_cart", {}, ("nominal",), episodes=2, seed=0)
    records = evaluate(ConstantPush(0.0, "idle"), plan, workers=1, progress=False)
    assert [r["failure_mode"] for r in records] == ["failed", "failed"]
    assert all(r["error_m"] > 0.05 and not r["success"] for r in records)
    assert summarize(records, simulator="bare_cart")["nominal"]["failure_modes"] == {"failed": 2}
