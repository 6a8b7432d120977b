"""Evaluation names the failure right: a boom that creeps up before the pile is an early
boom rise; fill and cycle time are reported beside success; actuation latency delays the
machine's response."""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.failures import (
    LIFT_COMMAND,
    LIFT_RISE_RAD,
    failure_mode,
    first_lift_step,
)
from pilerl_pile_loader.latency import ActuationDelay

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)
from pilerl.evaluation.evaluator import EvaluationPlan, evaluate, summarize
from pilerl.evaluation.metrics import fill_and_cycle_time
from pilerl.operators import OperatorModule
from pilerl.sim.rollout import control_period_s


def test_a_slow_boom_drift_before_contact_is_an_early_boom_rise():
    """The controllers' failure of issue #15: a boom command creeping up from 0.06, never
    above the old 0.3 lift rule, lifts the boom before the pile."""
    commands = np.array([min(0.06 * 1.1**step, 0.29) for step in range(40)])
    angles = -0.45 + np.concatenate([[0.0], np.cumsum(0.05 * commands)])  # boom follows
    penetration_s = 3.0
    lifted = first_lift_step(angles, commands)
    assert lifted is not None and 0.1 * (lifted + 1) < penetration_s
    assert not (commands > LIFT_COMMAND).any()  # the old command rule never saw a lift
    mode = failure_mode(
        success=False,
        tipped=False,
        finished=False,
        first_lift_s=0.1 * (lifted + 1),
        penetration_s=penetration_s,
    )
    assert mode == "early_boom_rise"


def test_a_boom_that_stays_down_is_no_boom_rise_even_with_a_large_command():
    commands = np.full(20, 0.9)  # commanded, but held down (stalled in the pile)
    angles = -0.45 + 0.5 * LIFT_RISE_RAD * np.arange(21) / 20
    assert first_lift_step(angles, commands) is None


def test_without_a_boom_angle_the_boom_command_decides():
    assert first_lift_step(None, np.array([0.2, 0.5, 0.9])) == 1
    assert first_lift_step(None, np.array([0.2, 0.1])) is None
    assert first_lift_step(None, None) is None


def test_fill_distribution_and_cycle_time_beside_success():
    rows = [
        {"fill_fraction": f, "time_to_finish_s": t}
        for f, t in [(0.1, math.nan), (0.4, 9.0), (0.6, 11.0), (0.9, 13.0), (1.1, 15.0)]
    ]
    stats = fill_and_cycle_time(rows)
    assert stats["fill_histogram"] == {
        "<0.25": 1,
        "0.25-0.5": 1,
        "0.5-0.75": 1,
        "0.75-1": 1,
        ">=1": 1,
    }
    assert stats["fill_p25"] == pytest.approx(0.4) and stats["fill_p75"] == pytest.approx(0.9)
    assert stats["finished"] == 4 and stats["cycle_time_s_median"] == pytest.approx(12.0)
    with pytest.raises(ValueError, match="no episode"):
        fill_and_cycle_time([])


def test_actuation_delay_cuts_a_control_step_where_the_command_arrives():
    delay = ActuationDelay(0.2, physics_dt=0.002, frame_skip=167, n_controls=1)  # 3 Hz
    first = delay.segments(np.array([1.0]))
    assert [(n, c.tolist()) for n, c in first] == [(100, [0.0]), (67, [1.0])]
    second = delay.segments(np.array([-1.0]))
    assert [(n, c.tolist()) for n, c in second] == [(100, [1.0]), (67, [-1.0])]
    slow = ActuationDelay(0.5, physics_dt=0.002, frame_skip=100, n_controls=1)  # > 1 step
    assert [n for n, _ in slow.segments(np.array([1.0]))] == [100]
    assert [n for n, _ in slow.segments(np.array([1.0]))] == [100]
    assert [(n, c.tolist()) for n, c in slow.segments(np.array([1.0]))] == [
        (50, [0.0]),
        (50, [1.0]),
    ]
    for bad in (-0.1, math.nan, (0.3, 0.1), (0.1, 0.2, 0.3)):
        with pytest.raises(ValueError, match="actuation_latency_s"):
            ActuationDelay(bad, physics_dt=0.002, frame_skip=10, n_controls=1)


def test_the_machine_answers_a_late_command_later():
    def pump_after_one_step(**kwargs) -> float:
        env = gym.make("pilerl/PileLoading-v0", control_hz=3.0, sensor_noise=0.0, **kwargs)
        env.reset(seed=0)
        obs, *_ = env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))
        env.close()
        return float(obs["pump_angle"][0])

    prompt = pump_after_one_step()
    assert pump_after_one_step(actuation_latency_s=0.0) == prompt  # default: no delay
    assert 0 < pump_after_one_step(actuation_latency_s=0.2) < prompt
    assert 0 < pump_after_one_step(actuation_latency_s=(0.1, 0.3)) < prompt


@dataclass(frozen=True)
class CreepingBoom:
    """A controller whose boom command creeps up from 0.06 but stays below the old 0.3
    lift rule, while it drives at the pile (the runaway issue #15 found in NNetV2)."""

    name: str = "creeping"

    def policy(self, env):
        """One creeping controller per simulator of the rollout env, as a TensorDict module."""
        dt = control_period_s(env)
        return OperatorModule.for_env([_Creeping(dt) for _ in env.simulators], env)


class _Creeping:
    def __init__(self, dt: float) -> None:
        self.dt = dt

    def reset(self) -> None:
        self.time_s = 0.0

    def act(self, observation) -> np.ndarray:
        self.time_s += self.dt
        boom = min(0.06 * math.exp(self.time_s / 0.25), 0.29)
        return np.array([boom, 0.0, 0.5], dtype=np.float32)


def test_evaluation_names_a_creeping_boom_an_early_boom_rise():
    plan = EvaluationPlan("pile_loader", {}, ("summer",), episodes=1, seed=0)
    (row,) = evaluate(CreepingBoom(), plan, workers=1, progress=False)
    assert not row["success"]
    assert row["first_lift_s"] < row["penetration_s"] or math.isnan(row["penetration_s"])
    assert row["failure_mode"] == "early_boom_rise"  # the command rule said no_boom_rise
    summary = summarize([row])["summer"]
    assert summary["failure_modes"]["early_boom_rise"] == 1
    assert sum(summary["fill_histogram"].values()) == 1
