"""Closed-loop evaluation: interval maths, determinism, a competent operator scores high."""

from __future__ import annotations

import json
import math

import pytest

from pilerl.evaluation.evaluator import (
    EvaluationPlan,
    ScriptedController,
    evaluate,
    summarize,
    write_results,
)
from pilerl.evaluation.metrics import wilson_interval


@pytest.mark.parametrize(
    ("successes", "trials", "low", "high"),
    [
        (8, 10, 0.4902, 0.9433),
        (0, 10, 0.0, 0.2775),
        (10, 10, 0.7225, 1.0),
        (52, 72, 0.6095, 0.8124),  # by hand: centre 0.7110, half-width 0.1014
    ],
)
def test_wilson_interval_matches_reference_values(successes, trials, low, high):
    assert wilson_interval(successes, trials) == pytest.approx((low, high), abs=1e-4)


def test_wilson_interval_rejects_impossible_counts():
    for args in ((1, 0), (5, 3), (-1, 3)):
        with pytest.raises(ValueError, match="wilson_interval"):
            wilson_interval(*args)


def same_records(a, b):
    def equal(x, y):
        return x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))

    return len(a) == len(b) and all(
        equal(ra[k], rb[k]) for ra, rb in zip(a, b, strict=True) for k in ra
    )


def test_evaluation_is_deterministic_and_independent_of_workers():
    plan = EvaluationPlan("pile_loader", {}, ("summer", "winter_c"), episodes=2, seed=3)
    serial = evaluate(ScriptedController(), plan, workers=1, progress=False)
    parallel = evaluate(ScriptedController(), plan, workers=2, progress=False)
    assert same_records(serial, parallel)
    # paired starts: episode i starts from the same pose in every condition
    assert serial[0]["start_distance_m"] == serial[2]["start_distance_m"]


def test_a_sensible_operator_scores_high_in_summer_and_results_are_written(tmp_path):
    plan = EvaluationPlan("pile_loader", {}, ("summer",), episodes=4, seed=0)
    records = evaluate(ScriptedController(), plan, workers=2, progress=False)
    summary = summarize(records)["summer"]
    assert summary["successes"] >= 3 and summary["success_low"] > 0.2
    assert summary["fill_mean"] >= 0.5 and summary["time_to_fill_s_mean"] > 0
    write_results(records, summarize(records), tmp_path)
    assert len((tmp_path / "episodes.csv").read_text().splitlines()) == 5
    assert json.loads((tmp_path / "summary.json").read_text())["summer"]["episodes"] == 4


def test_a_checkpoint_rewritten_in_place_is_evaluated_with_its_new_weights(datasets, tmp_path):
    import torch

    from pilerl.evaluation.evaluator import ActorController
    from pilerl.policies import make_actor, save_actor

    _, train, _ = datasets
    sensors = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
    torch.manual_seed(0)
    actor = make_actor("nnetv2", sensors=sensors, stats=train.stats)
    path = save_actor(tmp_path / "actor.pt", actor)
    plan = EvaluationPlan("pile_loader", {}, ("summer",), episodes=1, seed=0)
    first = evaluate(ActorController(str(path)), plan, workers=1, progress=False)
    with torch.no_grad():
        for parameter in actor.parameters():
            parameter.zero_()  # now every control is tanh(0) = 0: the machine stands still
    save_actor(path, actor)
    second = evaluate(ActorController(str(path)), plan, workers=1, progress=False)
    assert second[0]["first_lift_s"] != second[0]["first_lift_s"]  # NaN: never lifted
    assert not same_records(first, second)


def test_wilson_interval_reaches_zero_and_one_exactly_and_the_plot_accepts_it(tmp_path):
    from pilerl.evaluation.closed_loop import plot_success

    for trials in range(1, 60):  # 0/5, 0/10, 17/17 ... landed 1e-17 off before
        assert wilson_interval(0, trials)[0] == 0.0
        assert wilson_interval(trials, trials)[1] == 1.0
    summary = {
        name: {"success_rate": rate, "success_low": low, "success_high": high}
        | {"successes": s, "episodes": 5}
        for name, s in (("summer", 0), ("winter_c", 5))
        for rate, (low, high) in [(s / 5, wilson_interval(s, 5))]
    }
    assert plot_success(summary, tmp_path / "success.png").stat().st_size > 0
