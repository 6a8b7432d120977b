"""Every recipe runs end to end on a tiny budget, and fails cleanly on bad input."""

from __future__ import annotations

import io
import json
import os
import runpy
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run_recipe(script: str, *overrides: str) -> subprocess.CompletedProcess:
    """Run ``recipes/<script> <overrides>`` as its command line would, in this process (a
    new interpreter would only import torch, TorchRL and MuJoCo again): its exit status,
    and what it printed to stdout (Hydra's log) and stderr (errors, tracebacks)."""
    argv = [str(ROOT / "recipes" / script), *overrides]
    stdout, stderr = io.StringIO(), io.StringIO()
    old_argv, status = sys.argv, 0
    sys.argv = list(argv)
    try:
        with redirect_stdout(stdout), redirect_stderr(stderr):
            runpy.run_path(argv[0], run_name="__main__")
    except SystemExit as exit_:
        status = exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    finally:
        sys.argv = old_argv
    return subprocess.CompletedProcess(argv, status, stdout.getvalue(), stderr.getvalue())


def test_scoop_recipe_writes_video_plot_trace_and_report(tmp_path):
    result = run_recipe(
        "scoop.py",
        f"hydra.run.dir={tmp_path}",
        "conditions=[summer]",
        "env.start_distance_range_m=[1.0,1.0]",
        "render_width=96",
        "render_height=64",
    )
    assert result.returncode == 0, result.stderr[-2000:]
    for name in ("scoop_summer.mp4", "scoop_signals.png", "trace_summer.csv", "report.md"):
        assert (tmp_path / name).stat().st_size > 0, name
    summary = json.loads((tmp_path / "summary.json").read_text())["summer"]
    assert summary["success"] is True and summary["fill_fraction"] >= 0.5
    header = (tmp_path / "trace_summer.csv").read_text().splitlines()[0]
    assert "drive_pressure" in header and "u_throttle" in header


def test_a_scripted_run_of_an_earlier_expert_is_not_taken_for_this_ones(tmp_path):
    """A scripted evaluation (and a scoop) finished before the simulator's expert changed
    (its run.json without ``expert_revision``: revision 0) is refused, not skipped as done;
    the same run of the current expert is skipped."""
    runs = {
        "evaluate.py": ["evaluation.conditions=[summer]", "evaluation.episodes=1",
                        "evaluation.videos=false"],
        "scoop.py": ["conditions=[summer]", "video=false"],
    }  # fmt: skip
    for script, overrides in runs.items():
        where = tmp_path / script
        args = (f"hydra.run.dir={where}", *overrides, "env.start_distance_range_m=[1.0,1.0]")
        first = run_recipe(script, *args)
        assert first.returncode == 0, first.stderr[-2000:]
        again = run_recipe(script, *args)
        assert again.returncode == 0 and "already finished" in again.stdout, script
        record = json.loads((where / "run.json").read_text())
        assert record["settings"].pop("expert_revision") == 1
        (where / "run.json").write_text(json.dumps(record))
        earlier = run_recipe(script, *args)
        assert earlier.returncode != 0, script
        assert "expert_revision: 0 -> 1" in earlier.stderr, earlier.stderr[-2000:]


def test_scoop_recipe_rejects_an_unknown_condition_before_writing_results(tmp_path):
    result = run_recipe(
        "scoop.py", f"hydra.run.dir={tmp_path}", "conditions=[summer,spring]", "video=false"
    )
    assert result.returncode != 0
    assert "unknown condition 'spring'" in result.stderr
    assert not list(tmp_path.glob("*.csv")) and not (tmp_path / "report.md").exists()


def test_record_then_build_dataset_recipes(tmp_path):
    demos, dataset = tmp_path / "demos", tmp_path / "d_ii"
    result = run_recipe(
        "record.py",
        f"hydra.run.dir={tmp_path / 'run1'}",
        "n_episodes=2",
        "record_hz=100",
        f"out_dir={demos}",
        "workers=1",
    )
    assert result.returncode == 0, result.stderr[-2000:]
    index = json.loads((demos / "index.json").read_text())
    assert len(index["episodes"]) == 2 and index["sensors"]["drive_pressure"] == "MPa"
    result = run_recipe(
        "build_dataset.py",
        f"hydra.run.dir={tmp_path / 'run2'}",
        "dataset=d_i",
        f"source={demos}",
        f"out_dir={dataset}",
    )
    assert result.returncode == 0, result.stderr[-2000:]
    built = json.loads((dataset / "index.json").read_text())
    assert len(built["episodes"]) == 2 and built["stats"]["n_samples"] > 0


def test_record_recipe_rejects_bad_parameters_before_writing(tmp_path):
    result = run_recipe(
        "record.py",
        f"hydra.run.dir={tmp_path / 'run'}",
        "n_episodes=2",
        "env.condition=monsoon",
        f"out_dir={tmp_path / 'demos'}",
    )
    assert result.returncode != 0 and "unknown condition 'monsoon'" in result.stderr
    assert not (tmp_path / "demos").exists()


def test_teleop_recipe_says_it_needs_a_display(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "recipes" / "teleop.py"),
            f"hydra.run.dir={tmp_path}",
            f"out_dir={tmp_path / 'demos'}",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode != 0 and "teleop needs a display" in result.stderr
    assert not (tmp_path / "demos").exists()
