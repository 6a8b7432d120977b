"""Hardware in the loop: a cloned controller served over UDP against the simulator bridge
gives the in-process evaluator's outcome; injected link faults end in neutral controls;
each run is stored as demonstration episodes; the recipe runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from pilerl.data import EpisodeStore, validate_episode
from pilerl.deploy import BridgeSettings, RuntimeSettings, load_controller
from pilerl.deploy.config import DeployConfig
from pilerl.deploy.faults import REARM_STEP, run_scenario, scenarios
from pilerl.deploy.hil import run_hil
from pilerl.evaluation.evaluator import (
    ActorController,
    EvaluationPlan,
    ScriptedController,
    evaluate,
)
from pilerl.policies import make_actor, save_actor
from pilerl.policies.export import export_onnx
from pilerl.training.bc import BCSettings, train_bc

ROOT = Path(__file__).resolve().parents[2]
S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ENV = {"condition": "summer", "control_hz": 20.0, "start_distance_range_m": (1.0, 2.0)}
SPEEDUP = 25.0
# the equivalence runs wait for every command (lockstep) and tolerate a loaded machine:
# they test the protocol and the control path, the fault runs test the watchdog
LOCKSTEP = RuntimeSettings(control_hz=20.0, max_sensor_age_s=100.0, max_inference_s=25.0)


@pytest.fixture(scope="module")
def cloned(datasets, tmp_path_factory):
    """A small NNetV2 cloned from the shared demonstrations: (best.pt, .onnx)."""
    _, train, validation = datasets
    root = tmp_path_factory.mktemp("deploy")
    torch.manual_seed(0)
    actor, _ = train_bc(
        make_actor("nnetv2", sensors=S, stats=train.stats),
        train.to_tensordict(),
        validation,
        BCSettings(epochs=3, batch_size=64),
        progress=False,
    )
    checkpoint = save_actor(root / "best.pt", actor)
    onnx, _ = export_onnx(actor, root / "nnetv2.onnx")
    return checkpoint, onnx


@pytest.fixture(scope="module")
def in_process(cloned):
    env = {k: v for k, v in ENV.items() if k != "condition"}
    plan = EvaluationPlan("pile_loader", env, ("summer",), episodes=2, seed=3)
    records = evaluate(ActorController(str(cloned[0])), plan, workers=1, progress=False)
    return plan, records


def _hil(controller, plan, run_dir):
    bridge = BridgeSettings(
        env_kwargs={**ENV, "condition": "summer"},
        seeds=tuple(plan.seed * 100_000 + i for i in range(plan.episodes)),
        speedup=SPEEDUP,
        command_wait_s=50.0,
    )
    settings = RuntimeSettings(**{**LOCKSTEP.__dict__, "speedup": SPEEDUP})
    return run_hil(controller, bridge, settings, run_dir=run_dir, max_seconds=60.0)


def test_hil_checkpoint_run_matches_the_in_process_evaluator(cloned, in_process, tmp_path):
    plan, expected = in_process
    records, summary = _hil(cloned[0], plan, tmp_path)
    assert summary["faults"] == {} and summary["neutral_commands"] == 0
    for hil, ref in zip(records, expected, strict=True):
        assert hil["seed"] == ref["seed"]
        assert hil["late_commands"] == 0
        assert hil["success"] == ref["success"]
        assert hil["fill_fraction"] == pytest.approx(ref["fill_fraction"], abs=1e-9)
        assert hil["elapsed_s"] == pytest.approx(ref["elapsed_s"])

    # the run is stored as demonstration episodes, row for row what the machine applied
    store = EpisodeStore.open(tmp_path / "episodes")
    assert len(store) == len(records)
    for i, hil in enumerate(records):
        episode = store.load(i)
        validate_episode(episode, list(store.sensors), action_dim=3)
        np.testing.assert_array_equal(episode["action"].numpy(), np.float32(hil["applied"]))
        assert (episode["faults"] == 0).all()
        assert bool(episode["next", "terminated"][-1]) == hil["scoop_finished"]
        assert torch.isfinite(episode["latency_s"]).all()
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert saved["commands"] == sum(r["steps"] for r in records)
    assert (tmp_path / "cycles.csv").read_text().count("\n") == saved["commands"] + 1


def test_hil_onnx_run_matches_the_in_process_evaluator(cloned, in_process, tmp_path):
    plan, expected = in_process
    records, summary = _hil(cloned[1], plan, tmp_path)
    assert summary["faults"] == {}
    for hil, ref in zip(records, expected, strict=True):
        assert hil["late_commands"] == 0
        # onnxruntime and PyTorch agree to 1e-5 per action: the same scoop
        assert hil["success"] == ref["success"]
        assert hil["fill_fraction"] == pytest.approx(ref["fill_fraction"], abs=0.02)


FAULTS = {s.name: s for s in scenarios(age_s=0.3, period_s=0.05)}
FAULT_RUNTIME = RuntimeSettings(control_hz=20.0, max_sensor_age_s=0.3, speedup=4.0)


@pytest.mark.parametrize("name", list(FAULTS))
def test_injected_faults_end_in_neutral_and_never_crash(cloned, name):
    scenario = FAULTS[name]
    outcome = run_scenario(scenario, str(cloned[1]), env_kwargs=ENV, seed=0, runtime=FAULT_RUNTIME)
    assert not outcome["crashed"], outcome["error"]
    if scenario.expect is None:
        # absorbed: dropped as malformed, or a gap within the stale limit
        assert outcome["reported"] in ("none", "stale")
        if name.startswith(("corrupt", "garbage")):
            assert outcome["malformed"] >= 1
    else:
        assert outcome["neutral"], f"{name}: the machine was never commanded to neutral"
        assert scenario.expect.name.lower() in outcome["reported"].split("+")
    if not name.startswith("kill"):
        assert outcome["resumed"], f"{name}: control did not resume after the re-arm"


def test_fault_scenarios_rearm_after_the_fault_except_a_dead_stream():
    def faulty_steps(scenario):
        return [step for step in range(60) if scenario.fault.covers(step)]

    recoverable = [s for s in FAULTS.values() if s.fault and s.fault.kind != "kill"]
    assert max(max(faulty_steps(s)) for s in recoverable) < REARM_STEP
    assert REARM_STEP in faulty_steps(FAULTS["kill the sensor stream"])


def test_bad_deploy_configs_fail_before_serving():
    with pytest.raises(ValueError, match="give controller="):
        DeployConfig()
    with pytest.raises(ValueError, match="mode must be one of"):
        DeployConfig(controller="x.onnx", mode="fly")
    with pytest.raises(FileNotFoundError, match="missing.onnx"):
        load_controller("missing.onnx")
    with pytest.raises(ValueError, match="unknown controller file type"):
        load_controller("model.h5")


def test_recipe_runs_the_scripted_operator_against_the_simulator(tmp_path):
    run = tmp_path / "hil"
    env = {"start_distance_range_m": (1.0, 1.5)}
    plan = EvaluationPlan("pile_loader", env, ("summer",), episodes=1, seed=2)
    (expected,) = evaluate(ScriptedController(), plan, workers=1, progress=False)
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "recipes" / "deploy.py"),
            f"hydra.run.dir={run}",
            "controller=scripted",
            "mode=hil",
            "hil.episodes=1",
            "hil.seed=2",
            "runtime.speedup=10",
            "hil.command_wait_s=10",
            "runtime.max_sensor_age_s=20",
            "env.start_distance_range_m=[1.0,1.5]",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    (row,) = json.loads((run / "hil_episodes.json").read_text())
    assert row["late_commands"] == 0 and row["seed"] == expected["seed"]
    assert row["success"] == expected["success"]
    assert row["fill_fraction"] == pytest.approx(expected["fill_fraction"], abs=1e-9)
    assert len(EpisodeStore.open(run / "episodes")) == 1
