"""Sweeps: summary aggregation, skipping finished jobs, multirun with the local launcher."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from pilerl.evaluation.metrics import wilson_interval
from pilerl.sweeps import is_done, mark_done, summarize_sweep
from pilerl.sweeps.hydra_record import job_directories, read_choices, read_config, read_overrides
from pilerl.sweeps.summary import main as summary_main

ROOT = Path(__file__).resolve().parents[2]


def fake_job(root: Path, number: int, overrides: list[str], metrics: dict | None) -> None:
    job = root / str(number)
    (job / ".hydra").mkdir(parents=True)
    (job / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
    if metrics is not None:
        mark_done(job, metrics)


def test_summary_groups_by_swept_keys_and_averages_seeds(tmp_path):
    fixed = "env.condition=winter_c"  # the same in every job: not a group key
    fake_job(tmp_path, 0, [fixed, "policy=dannet", "seed=0"], {"success": 1.0, "fill": 0.9})
    fake_job(tmp_path, 1, [fixed, "policy=dannet", "seed=1"], {"success": 0.0, "fill": 0.5})
    fake_job(tmp_path, 2, [fixed, "policy=nnet", "seed=0"], {"success": 0.0, "fill": 0.2})
    fake_job(tmp_path, 3, [fixed, "policy=nnet", "seed=1", "hydra.job.chdir=false"], None)
    rows = summarize_sweep(tmp_path)
    assert [(r["policy"], r["n_jobs"]) for r in rows] == [("dannet", 2), ("nnet", 1)]
    assert rows[0]["fill_mean"] == pytest.approx(0.7)
    assert rows[0]["fill_std"] == pytest.approx(0.28284271, rel=1e-6)
    assert rows[0]["success_mean"] == pytest.approx(0.5)
    assert rows[1]["fill_mean"] == pytest.approx(0.2) and rows[1]["fill_std"] == 0.0
    table = (tmp_path / "sweep_summary.md").read_text()
    assert "3 of 4 jobs finished" in table and "| dannet | 2 |" in table
    assert (tmp_path / "sweep_summary.csv").read_text().startswith("policy,n_jobs,")
    assert (tmp_path / "sweep_summary.png").stat().st_size > 0


def test_success_counts_are_pooled_over_seeds_into_a_wilson_interval(tmp_path):
    for seed, successes in ((0, 3), (1, 5)):
        metrics = {
            "winter_success_rate": successes / 8,
            "winter_successes": successes,
            "winter_episodes": 8,
        }
        fake_job(tmp_path, seed, ["policy=dannet", f"seed={seed}"], metrics)
    fake_job(
        tmp_path,
        2,
        ["policy=nnet", "seed=0"],
        {"winter_success_rate": 0.0, "winter_successes": 0, "winter_episodes": 8},
    )
    rows = summarize_sweep(tmp_path, plot_metric="winter_success_rate")
    dannet = rows[0]
    assert dannet["winter_pooled_success_rate"] == 0.5  # 8 of 16 episodes
    low, high = wilson_interval(8, 16)
    assert (dannet["winter_success_low"], dannet["winter_success_high"]) == (low, high)
    assert rows[1]["winter_success_high"] == pytest.approx(wilson_interval(0, 8)[1])
    assert (tmp_path / "sweep_summary.png").stat().st_size > 0


def test_summary_errors_are_clear(tmp_path, capsys):
    assert summary_main([str(tmp_path / "nowhere")]) == 2
    assert "no such sweep directory" in capsys.readouterr().err
    assert summary_main([str(tmp_path)]) == 2
    assert "no Hydra job directories" in capsys.readouterr().err
    fake_job(tmp_path, 0, ["seed=0"], None)
    assert summary_main([str(tmp_path)]) == 2
    assert "none finished" in capsys.readouterr().err


def test_hydra_record_reads_overrides_choices_and_config(tmp_path):
    job = tmp_path / "sweep" / "nested" / "4"
    (job / ".hydra").mkdir(parents=True)
    overrides = ["+x=1", "~logger", "seed=3", "hydra.job.chdir=false", "+hydra.verbose=true"]
    (job / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
    (job / ".hydra" / "config.yaml").write_text(yaml.safe_dump({"seed": 3, "policy": {}}))
    choices = {"sensors": "s_pt", "policy": "dannet", "hydra/launcher": "basic"}
    (job / ".hydra" / "hydra.yaml").write_text(
        yaml.safe_dump({"hydra": {"runtime": {"choices": choices}}})
    )
    assert job_directories(tmp_path / "sweep") == [job]
    assert read_overrides(job) == {"x": "1", "logger": "", "seed": "3"}
    assert read_choices(job) == choices
    assert read_config(job) == {"seed": 3, "policy": {}}


def test_hydra_record_errors_name_the_file(tmp_path):
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "overrides.yaml").write_text("[seed=1\n")
    (tmp_path / ".hydra" / "hydra.yaml").write_text("hydra: {runtime: {}}\n")
    with pytest.raises(ValueError, match=r"overrides\.yaml: unreadable overrides"):
        read_overrides(tmp_path)
    with pytest.raises(ValueError, match=r"hydra\.yaml: no hydra\.runtime\.choices"):
        read_choices(tmp_path)
    with pytest.raises(ValueError, match=r"config\.yaml: cannot read the config"):
        read_config(tmp_path)
    with pytest.raises(FileNotFoundError, match="no such sweep directory"):
        job_directories(tmp_path / "nowhere")


def test_metrics_must_be_finite_scalars(tmp_path):
    with pytest.raises(ValueError, match="finite scalars"):
        mark_done(tmp_path, {"loss": float("nan")})
    assert not is_done(tmp_path)


def run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, env=env, timeout=600, cwd=ROOT
    )


SCOOP = [
    "recipes/scoop.py",
    "video=false",
    "conditions=[summer]",
    "env.start_distance_range_m=[1.0,1.0]",
]


def test_a_finished_job_is_skipped_when_run_again(tmp_path):
    first = run(*SCOOP, f"hydra.run.dir={tmp_path}")
    assert first.returncode == 0, first.stderr[-2000:]
    report_time = (tmp_path / "report.md").stat().st_mtime_ns
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["summer_success"] == 1.0
    again = run(*SCOOP, f"hydra.run.dir={tmp_path}")
    assert again.returncode == 0 and "already finished: skipping" in again.stdout + again.stderr
    assert (tmp_path / "report.md").stat().st_mtime_ns == report_time
    # another config in the same directory: refused, naming the key; Hydra's record kept
    other = run(*SCOOP, f"hydra.run.dir={tmp_path}", "seed=3")
    assert other.returncode != 0
    assert "seed: 0 -> 3" in other.stderr
    assert "seed: 0" in (tmp_path / ".hydra" / "config.yaml").read_text()
    assert "seed=3" not in (tmp_path / ".hydra" / "overrides.yaml").read_text()
    assert (tmp_path / "report.md").stat().st_mtime_ns == report_time


def test_multirun_with_the_local_parallel_launcher_then_summary(tmp_path):
    result = run(
        SCOOP[0],
        "--multirun",
        *SCOOP[1:],
        "hydra/launcher=local_parallel",
        "seed=0,1",
        "+expert.approach_throttle=0.3,0.5",
        f"hydra.sweep.dir={tmp_path}",
    )
    assert result.returncode == 0, result.stderr[-3000:]
    done = sorted(p.parent.name for p in tmp_path.glob("*/done.json"))
    assert done == ["0", "1", "2", "3"]
    summary = run("-m", "pilerl.sweeps.summary", str(tmp_path), "--metric", "summer_fill_fraction")
    assert summary.returncode == 0, summary.stderr
    rows = (tmp_path / "sweep_summary.csv").read_text().splitlines()
    assert rows[0].startswith("expert.approach_throttle,n_jobs,") and len(rows) == 3


def test_multirun_with_submitit_local_executor(tmp_path):
    result = run(
        SCOOP[0],
        "--multirun",
        *SCOOP[1:],
        "hydra/launcher=submitit_local_2",
        "seed=0,1",
        f"hydra.sweep.dir={tmp_path}",
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert sorted(p.parent.name for p in tmp_path.glob("*/done.json")) == ["0", "1"]
    metrics = json.loads((tmp_path / "0" / "metrics.json").read_text())
    assert metrics["summer_success"] == 1.0


def test_summary_command_limits_the_table_to_one_metric_without_warnings(tmp_path):
    for i, seed in enumerate([0, 1]):
        fake_job(tmp_path, i, ["policy=dannet", f"seed={seed}"], {"fill": 0.5 + i, "loss": 1.0})
    done = subprocess.run(
        [sys.executable, "-W", "error", "-m", "pilerl.sweeps.summary", str(tmp_path)]
        + ["--metric", "fill"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "Warning" not in done.stderr
    header = (tmp_path / "sweep_summary.md").read_text().splitlines()[2]
    assert header == "| n_jobs | fill_mean | fill_std |"
    assert "loss_mean" in (tmp_path / "sweep_summary.csv").read_text()  # the CSV keeps all
    assert header in done.stdout
    wrong = summary_main([str(tmp_path), "--metric", "flil"])
    assert wrong == 2
