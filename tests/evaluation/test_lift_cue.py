"""benchmarks/lift_cue.py: where summer demonstrations start lifting, and what a push reaches."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from test_paper_figures import STATS as FIGURE_STATS

from pilerl.data import EpisodeMeta, EpisodeStore, make_episode

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "lift_cue.py"
SENSORS = {
    "boom_angle": "rad",
    "bucket_angle": "rad",
    "drive_pressure": "MPa",
    "telescope_pressure": "MPa",
}
RATE_HZ = 20.0


@pytest.fixture(scope="module")
def lift_cue():
    spec = importlib.util.spec_from_file_location("lift_cue", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def scoop(n: int, lift_at: int | None, *, drive_at_lift: float, telescope_at_lift: float):
    """An episode at 20 Hz: pressures ramp up to the given readings at ``lift_at``, where the
    boom command turns on (never, for ``None``); the boom rests at -0.45 rad until then."""
    rows = torch.arange(n, dtype=torch.float32)
    end = float(lift_at if lift_at is not None else n)
    ramp = torch.clamp(rows / end, max=1.0)
    boom_command = torch.zeros(n) if lift_at is None else (rows >= lift_at).float() * 0.4
    sensors = {
        "boom_angle": torch.full((n,), -0.45) + torch.clamp(rows - end, min=0.0) * 0.01,
        "bucket_angle": torch.full((n,), 0.45),
        "drive_pressure": 4.0 + ramp * (drive_at_lift - 4.0),
        "telescope_pressure": 0.5 + ramp * (telescope_at_lift - 0.5),
    }
    return make_episode(
        sensors=sensors,
        next_sensors=sensors,
        actions=torch.stack([boom_command, torch.zeros(n), torch.full((n,), 0.3)], -1),
        time_s=torch.arange(n, dtype=torch.float64) / RATE_HZ,
        terminated=True,
    )


def store_of(root: Path, episodes) -> Path:
    store = EpisodeStore.create(root, sensors=SENSORS, controls=["boom", "bucket", "throttle"])
    for td in episodes:
        store.append(td, EpisodeMeta(rate_hz=RATE_HZ, condition="summer", success=True))
    return root


def test_the_first_lift_is_found_with_its_readings_and_posture(lift_cue, tmp_path):
    from pilerl.data.export import episodes_to_frame

    root = store_of(
        tmp_path / "demos",
        [
            scoop(80, 40, drive_at_lift=25.0, telescope_at_lift=5.0),
            scoop(80, None, drive_at_lift=25.0, telescope_at_lift=5.0),  # never lifts
            scoop(80, 20, drive_at_lift=12.0, telescope_at_lift=2.0),
        ],
    )
    onsets = lift_cue.lift_onsets(episodes_to_frame(EpisodeStore.open(root)))

    assert list(onsets["episode"]) == [0, 2]
    assert onsets["time_s"].tolist() == pytest.approx([2.0, 1.0])
    assert onsets["drive_mpa"].tolist() == pytest.approx([25.0, 12.0])
    assert onsets["telescope_mpa"].tolist() == pytest.approx([5.0, 2.0])
    # the readings pushed through before the lift: the ramp's last sample before it
    assert onsets["drive_max_before_mpa"].tolist() == pytest.approx(
        [4 + 21 * 39 / 40, 4 + 8 * 19 / 20]
    )
    assert onsets["boom_angle_rad"].tolist() == pytest.approx([-0.45, -0.45])


def test_a_lift_during_the_valves_settling_is_not_the_first_lift(lift_cue):
    frame = pd.DataFrame(
        {
            "episode": [0] * 4,
            "time_s": [0.0, 0.25, 0.5, 0.75],
            "u_boom": [0.5, 0.0, 0.0, 0.3],
            "drive_pressure": [2.0, 4.0, 6.0, 9.0],
            "telescope_pressure": [0.5, 0.5, 0.7, 1.1],
            "boom_angle": [-0.45] * 4,
            "bucket_angle": [0.45] * 4,
        }
    )
    onsets = lift_cue.lift_onsets(frame)
    assert onsets["time_s"].tolist() == [0.75]
    assert onsets["drive_mpa"].tolist() == [9.0]


def test_on_ice_the_steady_push_is_capped_but_the_impact_is_not(lift_cue):
    """The physics the benchmark's verdict rests on: on winter_c's ice the tyres cap the
    push (p_d and p_t) well below summer's, while p_t's impact peak at a brisk approach
    rises well above the capped steady push (the machine's momentum, not its grip)."""
    summer = lift_cue.push("summer", 0.6, starts=1)
    ice = lift_cue.push("winter_c", 0.6, starts=1)

    assert ice["drive_p90"] < 0.6 * summer["drive_p90"]
    assert ice["telescope_p90"] < 0.6 * summer["telescope_p90"]
    assert ice["impact"] > 1.5 * ice["telescope_p90"]


def test_the_script_reports_what_the_pushes_reach(tmp_path):
    root = store_of(
        tmp_path / "demos",
        [scoop(80, 40, drive_at_lift=25.0, telescope_at_lift=5.0) for _ in range(3)],
    )
    out = subprocess.run(
        [
            sys.executable,
            str(SCRIPT),
            "--demos",
            str(root),
            "--conditions",
            "winter_c",
            "--throttles",
            "0.6",
            "--starts",
            "1",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    row = next(line for line in out.stdout.splitlines() if line.strip().startswith("winter_c"))
    # every summer lift came at the drive's relief: no ice push reaches it
    assert row.split()[-2] == "0.00"


def test_a_missing_dataset_is_named(tmp_path):
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--demos", str(tmp_path / "nowhere")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 2
    assert "nowhere" in out.stderr


# the paper figures' controller statistics, and the boom pressure for an actor that reads it
STATS = {
    **FIGURE_STATS,
    "sensors": {**FIGURE_STATS["sensors"], "boom_pressure": {"mean": 8.0, "std": 4.0}},
}


def test_the_boom_response_grid_is_the_actors_own_command(lift_cue, tmp_path):
    from tensordict import TensorDict

    from pilerl.policies import make_actor, save_actor

    with_pt = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
    posture = (-0.45, 0.45)
    torch.manual_seed(0)
    for sensors in (with_pt, with_pt[:3]):
        actor = make_actor("nnetv2", sensors=sensors, stats=STATS)
        path = save_actor(tmp_path / f"{len(sensors)}.pt", actor)
        grid = lift_cue.boom_response(path, posture)

        assert grid.shape == (len(lift_cue.GRID_DRIVE_MPA), len(lift_cue.GRID_TELESCOPE_MPA))
        row, column = 3, 5  # one cell, by hand
        reading = {
            "boom_angle": posture[0],
            "bucket_angle": posture[1],
            "drive_pressure": lift_cue.GRID_DRIVE_MPA[row],
            "telescope_pressure": lift_cue.GRID_TELESCOPE_MPA[column],
        }
        td = TensorDict(
            {k: torch.tensor([[reading[k]]], dtype=torch.float32) for k in sensors},
            batch_size=[1],
        )
        with torch.no_grad():
            expected = actor.eval()(td)["action"][0, 0].item()
        assert grid[row, column] == pytest.approx(expected, abs=1e-6)
        if len(sensors) == 3:  # without p_t every column is the same
            np.testing.assert_allclose(grid, np.repeat(grid[:, :1], grid.shape[1], 1), atol=1e-6)
        else:
            assert np.ptp(grid, axis=1).max() > 1e-3


def test_an_actor_reading_another_sensor_is_refused_naming_it(lift_cue, tmp_path):
    from pilerl.policies import make_actor, save_actor

    sensors = ["boom_angle", "bucket_angle", "drive_pressure", "boom_pressure"]
    path = save_actor(tmp_path / "pl.pt", make_actor("nnetv2", sensors=sensors, stats=STATS))
    with pytest.raises(SystemExit, match="boom_pressure"):
        lift_cue.boom_response(path, (-0.45, 0.45))


def test_the_band_split_separates_pushing_from_lifting_samples(lift_cue):
    frame = pd.DataFrame(
        {
            "drive_pressure": [12.0, 12.0, 13.0, 12.5, 9.0, 15.0, 11.0],
            "telescope_pressure": [1.8, 2.0, 0.7, 0.9, 1.0, 3.0, 5.0],
            "u_boom": [0.0, 0.05, 0.4, 0.3, 0.0, 0.4, 0.0],
            "u_throttle": [0.6, 0.6, 0.2, 0.0, 0.6, 0.0, 0.0],  # the last: standing, not pushing
        }
    )
    split = lift_cue.band_split(frame, (10.0, 14.0))
    assert split["pushing"].tolist() == [1.8, 2.0]
    assert split["lifting"].tolist() == [0.7, 0.9]
