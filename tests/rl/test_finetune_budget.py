"""The fine-tune time budget covers the whole run: training stops early enough to leave
time for the evaluations that follow it (on a fake clock: no timing in tests)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from pilerl.rl import finetuning


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def budgeted_run(
    minutes: float, *, every_frames: int, state: dict | None = None, cross_check: bool = False
):
    run = finetuning._Run.__new__(finetuning._Run)  # only the budget's attributes
    run.config = SimpleNamespace(
        time_budget_minutes=minutes,
        evaluation=SimpleNamespace(
            every_frames=every_frames,
            episodes=5,
            final_episodes=10,
            groups={"winter": ["winter_a", "winter_b"], "summer": ["summer"]},
            cross_check_env={"soil_options": {"intake": "mouth"}} if cross_check else {},
        ),
    )
    run.state = state or {"wall_s": 0.0, "evaluation_s": 0.0, "before": None, "evaluations": []}
    run.deadline, run.final_eval_s, run.periodic_eval_s = None, 0.0, 0.0
    return run


def test_training_stops_when_only_the_final_evaluations_fit_in_the_budget(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(finetuning.time, "perf_counter", clock)
    run = budgeted_run(2.0, every_frames=20_000)
    run.start_clock()
    run.final_eval_s, run.periodic_eval_s = 18.0, 9.0  # measured before training
    assert run.reserve_s() == pytest.approx(2 * 18.0 + 9.0)  # final.pt, best.pt, last periodic
    clock.now += 120.0 - 45.0 - 1.0
    assert not run._out_of_time()
    clock.now += 1.0  # now the evaluations left would end exactly at the budget
    assert run._out_of_time()


def test_the_cross_check_reserves_as_long_as_the_cloned_actors_took():
    run = budgeted_run(2.0, every_frames=20_000, cross_check=True)
    run.final_eval_s, run.periodic_eval_s = 18.0, 9.0
    run.state["cross_check_before"] = {"seconds": 25.0}  # measured before training
    # final.pt, best.pt, last periodic, best.pt on the cross-check
    assert run.reserve_s() == pytest.approx(2 * 18.0 + 9.0 + 25.0)


def test_no_budget_never_stops_training(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(finetuning.time, "perf_counter", clock)
    run = budgeted_run(0.0, every_frames=0)
    run.start_clock()
    clock.now += 1e6
    assert not run._out_of_time()


def test_a_resumed_run_reserves_time_from_its_earlier_evaluations(monkeypatch):
    monkeypatch.setattr(finetuning.time, "perf_counter", FakeClock())
    # before: 10 episodes x 3 conditions; two periodic evaluations: 2 x 5 x 3 -> 60 episodes
    state = {"wall_s": 30.0, "evaluation_s": 60.0, "before": {}, "evaluations": [{}, {}]}
    run = budgeted_run(2.0, every_frames=20_000, state=state)
    run.start_clock()
    assert run.final_eval_s == pytest.approx(30.0) and run.periodic_eval_s == pytest.approx(15.0)
    assert run.deadline == pytest.approx(1000.0 + 120.0 - 30.0)  # earlier training counts
